"""(H, W) end to end: a WIDE image through data -> module -> postprocess -> evaluator callback.

Sizes are ``(H, W)`` in code (like torch) and ``WxH`` only where people type them. A swap anywhere on the way
(the transform's crop, the batch meta ``orig_size``, the lanes clipped to the image, the callback drawing at
``orig_size``) moves or drops the lane at x > H, and the score below drops from a perfect 1.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from lightning.pytorch import Trainer
from stamlane_eval.cli_tools import format_wxh, parse_wxh
from stamlane_eval.integrations.lightning import LaneEvalCallback

from stamlane.data.datamodule import ClipDataModule
from stamlane.data.options import AugmentOptions, ClipOptions, LoaderOptions
from stamlane.models import LaneDecoder, VGGEncoder
from stamlane.models.aggregators import KeyFrameOnly
from stamlane.predict.postprocess import PostprocessConfig
from stamlane.training.module import StamLaneModule

H, W = 90, 240
"""Original frames: wide, and the right lane lies at x > H, where a swapped size would cut it off."""
NET = (48, 128)
LANES = ([[40.0, 88.0], [70.0, 10.0]], [[190.0, 88.0], [215.0, 10.0]])


def _culane_root(root: Path) -> Path:
    video = root / "driver_00_30frame" / "clip.MP4"
    video.mkdir(parents=True)
    for n in (0, 30):
        image = np.full((H, W, 3), 90, np.uint8)
        for lane in LANES:
            cv2.polylines(image, [np.int32(lane)], False, (255, 255, 255), 2)
        cv2.imwrite(str(video / f"{n:05d}.jpg"), image)
        (video / f"{n:05d}.lines.txt").write_text(
            "".join(" ".join(f"{x:g} {y:g}" for x, y in lane) + "\n" for lane in LANES)
        )
    (root / "list.txt").write_text("/driver_00_30frame/clip.MP4/00030.jpg\n")
    return root


class _Oracle(StamLaneModule):
    """The module with its network replaced by the batch's own targets: perfect logits and embeddings."""

    def _run(self, batch: dict) -> tuple[torch.Tensor, torch.Tensor]:
        binary, instance = batch["binary"], batch["instance"]
        logits = torch.stack([-10.0 * binary, 10.0 * binary], dim=1).float()
        embedding = 10.0 * torch.nn.functional.one_hot(instance, 4).permute(0, 3, 1, 2).float()
        return logits, embedding


def test_a_wide_image_scores_perfectly_end_to_end(tmp_path: Path) -> None:
    root = _culane_root(tmp_path / "data")
    data = ClipDataModule(
        root=str(root),
        format="culane",
        clip=ClipOptions(num_frames=1, image_size=NET, align="none"),
        augment=AugmentOptions(crop_scale=(1.0, 1.0), flip_prob=0.0, brightness=0.0, contrast=0.0, saturation=0.0),
        loader=LoaderOptions(batch_size=1),
        val_labels=["list.txt"],
    )
    data.setup("validate")
    sample = data.make_dataset("val")[0]
    assert tuple(sample["meta"]["orig_size"]) == (H, W)  # (H, W), as the image's shape
    module = _Oracle(
        VGGEncoder(width=0.125),
        KeyFrameOnly,
        LaneDecoder,
        num_frames=1,
        image_size=NET,
        postprocess=PostprocessConfig(min_cluster_pixels=5, min_samples=3),
    )
    callback = LaneEvalCallback(tusimple=False, culane_size=None, iou_thresholds=(0.5,))
    trainer = Trainer(
        accelerator="cpu",
        callbacks=[callback],
        logger=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        enable_checkpointing=False,
    )
    metrics = trainer.validate(module, datamodule=data, verbose=False)[0]
    assert metrics["val/culane_f1@0.5"] == pytest.approx(1.0)


@pytest.mark.parametrize(("text", "size"), [("1640x590", (590, 1640)), ("640x360", (360, 640)), ("7x7", (7, 7))])
def test_sizes_are_typed_wxh_and_held_hw(text: str, size: tuple[int, int]) -> None:
    assert parse_wxh(text) == size and format_wxh(size) == text


@pytest.mark.parametrize("text", ["1640", "0x10", "10x-2", "axb", "20x20x20"])
def test_bad_sizes_are_refused(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match="WxH"):
        parse_wxh(text, max_side=10_000)
