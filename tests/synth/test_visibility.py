"""Paint visibility of labelled key-frame points: visible, revealed by history only, hidden everywhere."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from stamlane.synth import SynthConfig, generate_clip, generate_dataset
from stamlane.synth.layout import VISIBILITY_DIR, SplitCounts
from stamlane.synth.statistics import key_frame_visibility
from stamlane.synth.visibility import ABSENT, VISIBLE_CONTRAST, paint_visibility, visibility_class


def _contrast(points: list[tuple[int, int]], value: int = VISIBLE_CONTRAST) -> np.ndarray:
    img = np.zeros((40, 60), np.uint8)
    for x, y in points:
        img[y, x] = value
    return img


def test_masks_follow_the_points_through_the_homographies():
    lanes = [[10, 20, -2], [30, 31, 32]]
    h_samples = [10, 20, 30]
    key = _contrast([(10, 10), (30, 10)])  # key frame: two points show paint
    back1 = _contrast([(25, 20)])  # one frame back the scene sits 5 px further right: (20, 20) -> (25, 20)
    back2 = _contrast([(33, 30)])  # nothing at the shifted (37, 30): 33 is more than WINDOW_PX away
    shift = np.array([[1.0, 0, -5], [0, 1, 0], [0, 0, 1]])  # key_from_hist: hist pixels -> key pixels
    masks = paint_visibility(lanes, h_samples, [key, back1, back2], [np.eye(3), shift, shift])
    assert masks == [[0b001, 0b010, ABSENT], [0b001, 0b000, 0b000]]
    assert [visibility_class(m, 4) for m in masks[0]] == ["visible", "revealed", None]
    assert visibility_class(0b010, 1) == "hidden"  # a one-frame model has no history to reveal it
    assert visibility_class(0b010, 3, stride=2) == "hidden" and visibility_class(0b100, 2, stride=2) == "revealed"
    weak = _contrast([(10, 10)], VISIBLE_CONTRAST - 1)  # one grey level below the threshold
    assert paint_visibility([[10]], [10], [weak], [np.eye(3)]) == [[0]]
    with pytest.raises(ValueError, match="one homography per frame"):
        paint_visibility(lanes, h_samples, [key, back1], [np.eye(3)])


def test_paint_contrast_leaves_the_frames_as_they_were_and_sees_the_paint():
    cfg = SynthConfig.with_factor("glare", width=160, height=96, num_frames=8)
    plain = generate_clip(cfg, np.random.default_rng([2, 3]))
    seen = generate_clip(cfg, np.random.default_rng([2, 3]), paint_contrast=True)
    assert plain.paint_contrast is None and len(seen.paint_contrast) == 8
    assert all(np.array_equal(a, b) for a, b in zip(plain.frames, seen.frames))  # same draws, same frames
    masks = key_frame_visibility(seen, 7)
    classes = [visibility_class(m, 8) for lane in masks for m in lane]
    assert classes.count("visible") > 0 and None not in classes[:1]
    # the paint shows exactly where the painted frame differs from the unpainted one: off the lanes it is dark
    labelled = np.zeros(seen.paint_contrast[7].shape, bool)
    for lane in seen.labels[7]:
        for x, y in zip(lane, seen.h_samples):
            if x >= 0:
                labelled[y, max(x - 6, 0) : x + 7] = True
    rows = sorted(set(seen.h_samples))
    assert seen.paint_contrast[7][rows][~labelled[rows]].mean() < 2


def test_generated_sets_carry_visibility_beside_the_eval_labels(tmp_path: Path):
    cfg = SynthConfig(width=160, height=96, num_frames=10)
    generate_dataset(
        tmp_path,
        SplitCounts(train=1, val=1, test=1, challenging=2, train_factors=1),
        seed=1,
        config=cfg,
        progress=False,
    )
    assert not (tmp_path / VISIBILITY_DIR / "train.json").exists()  # training needs none
    for split in ("val", "test", "challenging"):
        labels = [json.loads(line) for line in (tmp_path / f"{split}.json").read_text().splitlines()]
        seen = [json.loads(line) for line in (tmp_path / VISIBILITY_DIR / f"{split}.json").read_text().splitlines()]
        assert [r["raw_file"] for r in seen] == [r["raw_file"] for r in labels]
        for record, label in zip(seen, labels):
            assert [[m == ABSENT for m in lane] for lane in record["visibility"]] == [
                [x < 0 for x in lane] for lane in label["lanes"]
            ]
    info = json.loads((tmp_path / "dataset.json").read_text())
    assert info["clip_factors"]["train-0001"] == "traffic_standing"  # the factor clip after the clean one
    assert "train-0000" not in info["clip_factors"]
    assert set(info["statistics"]["test"]["paint_visibility_4_frames"]) == {
        "visible_fraction",
        "revealed_fraction",
        "hidden_fraction",
    }
