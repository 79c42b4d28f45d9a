"""Evenly spread features: grid FAST with retry, quadtree, orientation, descriptors."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stamlane.align.features import (
    EDGE,
    FeatureConfig,
    _fast,
    _grid_fast,
    _orientation,
    _quadtree,
    detect_plain_orb,
    detect_pyramid_features,
    detect_spread_features,
    ground_box,
)
from stamlane.align.synthetic import render_road

from .conftest import SMALL_CAMERA, SMALL_HORIZON


def _occupied(points: np.ndarray, horizon: int, cell: int = 30) -> int:
    return len({(int((y - horizon) // cell), int(x // cell)) for x, y in points})


def test_spread_features_shapes_and_region(texture):
    gray = render_road(texture, SMALL_CAMERA, color=False)
    feats = detect_spread_features(gray, SMALL_HORIZON, FeatureConfig(max_features=200))
    assert 100 <= len(feats) <= 200
    assert feats.points.shape == (len(feats), 2) and feats.points.dtype == np.float32
    assert feats.descriptors.shape == (len(feats), 32) and feats.descriptors.dtype == np.uint8
    _x0, y0, _x1, y1 = ground_box(gray.shape, SMALL_HORIZON)
    assert feats.points[:, 1].min() >= y0 and feats.points[:, 1].max() < y1
    assert feats.points[:, 0].min() >= EDGE and feats.points[:, 0].max() < gray.shape[1] - EDGE


def test_spread_covers_more_cells_than_plain_orb(texture):
    """The paper's Figure 2: plain ORB top-N clusters, the grid + quadtree spreads over the road."""
    gray = render_road(texture, SMALL_CAMERA, color=False)
    spread = detect_spread_features(gray, SMALL_HORIZON, FeatureConfig(max_features=150))
    plain = detect_plain_orb(gray, SMALL_HORIZON, 150)
    assert _occupied(spread.points, SMALL_HORIZON) > 1.5 * _occupied(plain.points, SMALL_HORIZON)


def test_low_threshold_pass_reproduces_high_threshold_pass():
    """The vectorised retry rests on this: FAST at 7 restricted to scores >= 20 equals FAST at 20."""
    rng = np.random.default_rng(0)
    gray = cv2.GaussianBlur(rng.integers(0, 256, (200, 300)).astype(np.uint8), (0, 0), 1.0)
    box = (10, 10, 290, 190)
    high, _ = _fast(gray, box, 20)
    low, low_scores = _fast(gray, box, 7)
    assert {tuple(p) for p in high} == {tuple(p) for p in low[low_scores >= 20]}


def test_grid_fast_retries_only_empty_cells():
    gray = np.full((120, 240), 100, np.uint8)
    cv2.rectangle(gray, (40, 40), (70, 70), 200, -1)  # strong corners in the left cell
    cv2.rectangle(gray, (160, 40), (190, 70), 113, -1)  # weak corners (contrast 13) in the right cell
    # +-1 of noise breaks the ties between neighbouring corner pixels that FAST's strict NMS would drop
    gray = (gray + np.random.default_rng(0).integers(0, 2, gray.shape)).astype(np.uint8)
    points, scores = _grid_fast(gray, (0, 0, 240, 120), FeatureConfig(cell_size=120))
    left = points[:, 0] < 120
    assert left.any() and (~left).any()
    assert scores[left].min() >= 20  # the left cell had strong corners: weak ones are not added there
    assert scores[~left].max() < 20  # the right cell had none: the retry found its weak ones


def test_quadtree_keeps_budget_and_isolated_corners():
    rng = np.random.default_rng(1)
    cluster = rng.uniform([0, 0], [20, 20], (500, 2))  # a crowded corner of the window
    isolated = np.array([[300, 50], [500, 80], [150, 90]], float)
    points = np.vstack([cluster, isolated]).astype(np.float32)
    scores = np.r_[rng.uniform(50, 100, 500), [1.0, 1.0, 1.0]].astype(np.float32)
    keep = _quadtree(points, scores, (0, 0, 600, 100), 40)
    assert len(keep) <= 40
    assert {500, 501, 502} <= set(keep.tolist())  # weak but alone in their nodes: kept, unlike a top-N
    assert len(set(keep.tolist())) == len(keep)


def test_quadtree_keeps_everything_under_budget():
    points = np.array([[1, 1], [5, 5]], np.float32)
    assert _quadtree(points, np.ones(2, np.float32), (0, 0, 10, 10), 10).tolist() == [0, 1]


def test_orientation_matches_brute_force_intensity_centroid():
    rng = np.random.default_rng(2)
    gray = rng.integers(0, 256, (100, 100)).astype(np.uint8)
    points = np.array([[30, 30], [50, 60], [70, 40]], np.float32)
    v, u = np.mgrid[-15:16, -15:16]
    circle = u**2 + v**2 <= 15**2
    expected = []
    for x, y in points.astype(int):
        patch = gray[y - 15 : y + 16, x - 15 : x + 16].astype(float) * circle
        expected.append(np.degrees(np.arctan2((patch * v).sum(), (patch * u).sum())) % 360)
    np.testing.assert_allclose(_orientation(gray, points), expected, atol=1e-6)


def test_pyramid_points_are_in_input_pixels(texture):
    gray = render_road(texture, SMALL_CAMERA, color=False)
    feats = detect_pyramid_features(gray, SMALL_HORIZON, (1.0, 1.5), FeatureConfig(max_features=100))
    assert len(feats) > 100  # two levels
    assert feats.points[:, 0].max() < gray.shape[1] and feats.points[:, 1].max() < gray.shape[0]
    assert feats.points[:, 1].min() >= SMALL_HORIZON - 2
    with pytest.raises(ValueError, match=r"0\.5"):
        detect_pyramid_features(gray, SMALL_HORIZON, (0.5,))


def test_textureless_image_has_no_features():
    assert len(detect_spread_features(np.full((200, 300), 90, np.uint8), 80)) == 0
    assert len(detect_plain_orb(np.zeros((200, 300), np.uint8), 80)) == 0


@pytest.mark.parametrize(
    "kwargs", [{"cell_size": 2}, {"fast_threshold": 5, "min_fast_threshold": 7}, {"max_features": 3}]
)
def test_feature_config_rejects_bad_values(kwargs):
    with pytest.raises(ValueError, match=str(next(iter(kwargs.values())))):
        FeatureConfig(**kwargs)
