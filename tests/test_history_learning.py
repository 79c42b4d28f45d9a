"""A multi-frame model that must read its history does, and the probe that measures it sees it.

Two synthetic clips whose labelled key frames have their lower 60 % (every lane mark) painted over with the
road's mean colour: the key frame alone cannot be solved, the history frames still show the lanes. A tiny 2-frame
network overfits them in seconds; `HistoryUseMonitor` then scores it with its real history and with the key frame
copied into the history slot. (A single-frame network is no control here: on two clips it memorises their lanes
from the sky and the verge.) These fail when the history stops reaching the output (a fusion that drops it, a
data pipeline that feeds the key frame twice, a probe that changes nothing).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from stamlane_eval.integrations.lightning import LaneEvalCallback

from stamlane.predict.postprocess import PostprocessConfig
from stamlane.training.history_use_monitor import HistoryUseMonitor
from tests.overfit import overfit, tiny_data, tiny_module

torch.set_num_threads(1)
STEPS = 150
"""The 2-frame network reaches val F1 0.83 with its history and 0.0 with the key frame copied (6.5 s on one core)."""


@pytest.fixture(scope="module")
def blanked(tiny_synthetic) -> Path:
    root = tiny_synthetic(256, 144, 4, train=2, val=0, test=0, challenging=0, seed=5)
    for line in (root / "train.json").read_text().splitlines():
        path = root / json.loads(line)["raw_file"]
        image = cv2.imread(str(path))
        cut = int(0.4 * image.shape[0])
        image[cut:] = image[cut:].reshape(-1, 3).mean(axis=0).astype(np.uint8)
        cv2.imwrite(str(path), image)
    return root


def _fit(root: Path, num_frames: int, tmp_path: Path) -> dict[str, float]:
    module = tiny_module(num_frames, PostprocessConfig(min_cluster_pixels=10, min_samples=10, extend=True, degree=1))
    callbacks = [LaneEvalCallback(tusimple=True, culane=False), HistoryUseMonitor()]
    return overfit(module, tiny_data(root, num_frames), STEPS, tmp_path, callbacks)


def test_a_model_that_must_read_its_history_does(blanked: Path, tmp_path: Path) -> None:
    found = _fit(blanked, 2, tmp_path)
    assert found["val/tusimple_f1"] >= 0.7, found  # it solved the clips from the history
    assert found["val/keycopy_tusimple_f1"] <= 0.3, found  # the same weights without the history cannot
    assert found["val/history_use_f1"] >= 0.5, found
    assert found["val/history_use_seg_loss"] > 0 and found["val/history_prob_change"] > 0.02, found
