"""Overlay pictures: the ground truth visible on any background, the legend, the per-image score."""

from __future__ import annotations

import numpy as np
import pytest

from stamlane.predict.image_score import image_score, iou_width
from stamlane.predict.overlay import (
    GT_CORE,
    GT_EDGE,
    LANE_COLOURS,
    OKABE_ITO,
    draw_lanes,
    draw_legend,
    gt_width,
    label_strip,
    line_width,
)

H, W = 360, 640
GT = [np.array([[100.0, 350.0], [300.0, 180.0]]), np.array([[540.0, 350.0], [340.0, 180.0]])]


def _has(picture: np.ndarray, colour: tuple[int, int, int], tolerance: int = 2) -> int:
    """Pixels of ``picture`` within ``tolerance`` of ``colour`` (BGR) in every channel."""
    return int((np.abs(picture.astype(int) - np.array(colour)) <= tolerance).all(axis=2).sum())


@pytest.mark.parametrize("background", [255, 0, 128], ids=["white-saturated", "black", "grey"])
def test_the_ground_truth_shows_on_any_background(background: int) -> None:
    """Glare and white paint (255), night asphalt (0): the yellow core and the black outline, one of which differs
    from the background in every case, both cover a lane's length."""
    frame = np.full((H, W, 3), background, np.uint8)
    picture = draw_lanes(frame, [], GT)
    length = sum(float(np.linalg.norm(lane[1] - lane[0])) for lane in GT)
    assert _has(picture, GT_CORE) > length * (gt_width(line_width(frame)) - 2)  # the core, all along the lanes
    if background > 0:  # the outline on both sides (on black it is the background)
        assert _has(picture, GT_EDGE, 30) > 2 * length
    differs = (np.abs(picture.astype(int) - background).max(axis=2) > 100).sum()
    assert differs > length * gt_width(line_width(frame))  # whatever the background, the band stands out


def test_a_prediction_on_the_ground_truth_leaves_the_band_visible_around_it() -> None:
    frame = np.full((H, W, 3), 255, np.uint8)
    picture = draw_lanes(frame, GT, GT)
    assert _has(picture, LANE_COLOURS[0]) > 100 and _has(picture, LANE_COLOURS[1]) > 100
    assert _has(picture, GT_CORE) > 2 * 200  # yellow on both sides of each predicted lane


def test_prediction_colours_are_okabe_ito_and_never_the_ground_truths() -> None:
    bgr = {(b, g, r) for r, g, b in OKABE_ITO.values()}
    assert set(LANE_COLOURS) <= bgr and len(set(LANE_COLOURS)) == len(LANE_COLOURS)
    assert GT_CORE not in LANE_COLOURS and GT_EDGE not in LANE_COLOURS


def test_the_legend_names_the_model_and_marks_both_kinds_of_line() -> None:
    frame = np.full((H, W, 3), 255, np.uint8)
    alone = draw_legend(frame.copy(), model="stam4-s0")
    both = draw_legend(frame.copy(), model="stam4-s0", score="TuSimple acc 93.8 %, 3/4 lanes", ground_truth=True)
    assert (alone != 255).any() and _has(alone, LANE_COLOURS[0]) > 0 and _has(alone, GT_CORE) == 0
    assert _has(both, GT_CORE) > 0 and (both != 255).sum() > (alone != 255).sum()  # two more lines
    assert (both[H // 2 :] == 255).all()  # in its corner only
    bottom = draw_legend(frame.copy(), score="IoU F1@0.5 0.86", predictions=False, corner="bottom")
    assert (bottom[: H // 2] == 255).all() and (bottom[H // 2 :] != 255).any()
    assert (draw_legend(frame.copy(), predictions=False) == 255).all()  # nothing to say: nothing drawn
    with pytest.raises(ValueError, match="corner"):
        draw_legend(frame, corner="left")


def test_a_label_strip_fits_a_long_text_into_its_column() -> None:
    strip = label_strip(200, ["a model with a very long name indeed, longer than its column"], 24, 0.6)
    assert strip.shape == (24, 200, 3) and (strip[:, 195:] == 32).all() and (strip > 32).any()


def test_the_score_is_the_official_per_image_one() -> None:
    rows = list(range(180, 351, 10))
    assert image_score(GT, GT, rows, (H, W)) == "TuSimple acc 100.0 %, 2/2 lanes"
    assert image_score(GT[:1], GT, rows, (H, W)) == "TuSimple acc 50.0 %, 1/2 lanes"
    shifted = [lane + np.array([200.0, 0.0]) for lane in GT]
    assert image_score(shifted, GT, rows, (H, W)).endswith(", 0/2 lanes")  # a few crossing points still count
    assert image_score(GT, GT, None, (H, W)) == "IoU F1@0.5 1.00 (2 of 2 lanes, 0 false)"
    assert image_score(shifted[:1] + GT[1:], GT, None, (H, W)) == "IoU F1@0.5 0.50 (1 of 2 lanes, 1 false)"
    assert image_score([], [], None, (H, W)) == "IoU F1@0.5 0.00 (0 of 0 lanes, 0 false)"  # prf's 0, as stamlane-eval
    assert iou_width((590, 1640)) == 30 and iou_width((360, 640)) == 12
