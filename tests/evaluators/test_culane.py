"""CULane area metric: parity with the official C++ tool and lanedet (fixture numbers), rasterisation, matching."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment
from stamlane_eval import culane
from stamlane_eval.culane import _kuhn_munkres_cpp, _points_official, _rasterise
from stamlane_eval.io import culane_entries, culane_lines_path, read_culane_lines

GOLDEN = Path(__file__).parent / "golden" / "culane"
THRESHOLDS = ("0.3", "0.5")


def _load(root: Path) -> tuple[list[str], list, list]:
    entries = culane_entries(root / "anno", root / "list.txt")
    preds = [read_culane_lines(culane_lines_path(root / "pred", e)) for e in entries]
    gts = [read_culane_lines(culane_lines_path(root / "anno", e)) for e in entries]
    return entries, preds, gts


def _check_per_image(res: culane.CULaneResult, per_image: list[dict], key: str) -> None:
    for r, want in zip(res.per_image, per_image, strict=True):
        for t in THRESHOLDS:
            assert list(r.counts[float(t)]) == want[key][t], (want["entry"], t, key)
        if key == "lanedet":
            assert r.matched_iou.tolist() == want["lanedet_matched_iou"], want["entry"]


@pytest.mark.parametrize(("variant", "key"), [("official", "cpp"), ("lanedet", "lanedet")])
def test_fixture_parity(shared_dir: Path, variant: str, key: str) -> None:
    root = shared_dir / "fixtures" / "evaluators" / "culane"
    exp = json.loads((root / "expected.json").read_text())
    entries, preds, gts = _load(root)
    assert entries == [p["entry"] for p in exp["per_image"]]
    res = culane.evaluate(preds, gts, (0.3, 0.5), 30, (590, 1640), variant)
    _check_per_image(res, exp["per_image"], key)
    for t in THRESHOLDS:
        assert res.totals[float(t)].as_dict() == exp["totals"][key][t]
    assert res.images == 300


@pytest.mark.parametrize(("variant", "key"), [("official", "cpp"), ("lanedet", "lanedet")])
def test_golden_parity(variant: str, key: str) -> None:
    exp = json.loads((GOLDEN / "expected.json").read_text())
    _, preds, gts = _load(GOLDEN)
    res = culane.evaluate(preds, gts, variant=variant)
    _check_per_image(res, exp["per_image"], key)
    tags = {p["tag"] for p in exp["per_image"]}
    assert {"pred_one_point_lane_extra", "pred_blank_line_extra", "gt_one_point_lane"} <= tags


def _full_image(pts: np.ndarray, size: tuple[int, int], width: int) -> np.ndarray:
    img = np.zeros(size, np.uint8)  # size is (H, W)
    for p, q in itertools.pairwise(pts):  # the C++ tool: one cv::line per segment on the whole image
        cv2.line(img, (int(p[0]), int(p[1])), (int(q[0]), int(q[1])), 1, thickness=width)
    return img.astype(bool)


def test_cropped_polyline_equals_full_image_lines() -> None:
    rng = np.random.default_rng(1)
    size = (160, 320)
    for i in range(60):
        n = int(rng.integers(2, 8))
        lane = np.stack([rng.uniform(-80, 400, n), np.sort(rng.uniform(-40, 220, n))], 1)
        if i % 5 == 0:
            lane[1] = lane[0]  # repeated points
        pts = _points_official(lane)
        width = int(rng.choice([1, 2, 15, 30]))
        full = _full_image(pts, size, width)
        m = _rasterise(pts, size, width)
        crop = np.zeros_like(full)
        crop[m.y0 : m.y0 + m.mask.shape[0], m.x0 : m.x0 + m.mask.shape[1]] = m.mask
        assert np.array_equal(crop, full), i
        assert m.area == full.sum()


def test_spline_passes_through_points_and_keeps_two_point_lanes() -> None:
    lane = np.array([[100.0, 500.0], [130.0, 400.0], [170.0, 300.0], [230.0, 200.0]])
    pts = _points_official(lane)
    assert len(pts) == 3 * culane.SPLINE_SAMPLES + 1
    assert np.array_equal(pts[:: culane.SPLINE_SAMPLES], lane.astype(int))
    assert np.array_equal(_points_official(lane[:2]), lane[:2].astype(int))
    assert _points_official(lane[:1]) is None


def test_kuhn_munkres_reaches_the_optimum_on_clear_cases() -> None:
    rng = np.random.default_rng(2)
    for _ in range(200):
        m, n = sorted(rng.integers(1, 7, 2))
        w = np.round(rng.uniform(0, 1, (m, n)), 1)  # weights on a 0.1 grid: far from the 1e-2 tolerance
        match = _kuhn_munkres_cpp(w.tolist())
        rows, cols = linear_sum_assignment(-w)
        assert sorted(match) == sorted(set(match))
        assert sum(w[i, j] for i, j in enumerate(match) if j >= 0) == pytest.approx(w[rows, cols].sum())


def test_edge_rules() -> None:
    lane = np.array([[800.0, 590.0], [820.0, 400.0], [850.0, 250.0]])
    one = np.array([[10.0, 10.0]])
    r = culane.evaluate_image([lane, one], [lane])
    assert r.counts[0.5] == (1, 1, 0) and r.ious[1, 0] == 0.0  # a 1-point lane is an FP with IoU 0
    r = culane.evaluate_image([lane, one], [lane], variant="lanedet")
    assert r.counts[0.5] == (1, 0, 0)  # lanedet drops it
    r = culane.evaluate_image([], [lane, lane])
    assert r.counts[0.3] == (0, 0, 2)
    outside = np.array([[-500.0, -500.0], [-400.0, -400.0]])
    r = culane.evaluate_image([outside], [outside])
    assert np.isnan(r.ious[0, 0]) and r.counts[0.5] == (0, 1, 1)  # 0/0: unmatched, as the C++
    with pytest.raises(ValueError, match="outside the image"):
        culane.evaluate_image([outside], [outside], variant="lanedet")
    # IoU > t is strict: identical lanes have IoU 1, never > 1
    assert culane.evaluate_image([lane], [lane], iou_thresholds=(0.99,)).counts[0.99] == (1, 0, 0)


def test_bad_arguments() -> None:
    lane = np.zeros((2, 2))
    with pytest.raises(ValueError, match="variant"):
        culane.evaluate_image([lane], [lane], variant="cpp")
    with pytest.raises(ValueError, match=r"\(N, 2\)"):
        culane.evaluate_image([np.zeros((3, 3))], [lane])
    with pytest.raises(ValueError, match="non-finite"):
        culane.evaluate_image([np.full((2, 2), np.inf)], [lane])
    with pytest.raises(ValueError, match="size"):
        culane.evaluate_image([lane], [lane], size=(0, 10))


def test_as_dict_layout() -> None:
    lane = np.array([[800.0, 590.0], [820.0, 400.0]])
    d = culane.evaluate([[lane]], [[lane]]).as_dict()
    assert set(d) == {"0.3", "0.5", "images"}
    assert d["0.5"] == {"tp": 1, "fp": 0, "fn": 0, "precision": 1.0, "recall": 1.0, "f1": 1.0}
