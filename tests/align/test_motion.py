"""The ``motion`` preset (`stamlane.align.motion`): large forward motion with a moving blob, the prior's geometry, and
the presets made before it unchanged."""

from __future__ import annotations

from dataclasses import fields

import cv2
import numpy as np
import pytest

import stamlane.align.motion as motion
from stamlane.align import ALIGN_PRESETS, AlignConfig, align_preset, check_plausible, estimate_homography
from stamlane.align.egomotion import key_from_hist_motion
from stamlane.align.motion import forward_motion
from stamlane.align.synthetic import render_road

from .conftest import SMALL_CAMERA, SMALL_HORIZON, corner_error

SHAPE = (SMALL_CAMERA.height, SMALL_CAMERA.width)

# repr(AlignConfig()) before motion_scales existed: the pair cache names its entries by it (align/cache.pair_key)
STANDARD_REPR = (
    "AlignConfig(features=FeatureConfig(cell_size=15, fast_threshold=20, min_fast_threshold=7, max_features=300, "
    "spread=True), working_scale=0.5, min_working_width=640, key_scales=(1.0, 1.3, 1.69), max_hamming=64, "
    "ratio=None, ransac_threshold=3.0, min_matches=15, min_inliers=10, refine=True, refine_scale=1.0, lk_window=21, "
    "max_track_points=300, min_track_ratio=0.5, refine_threshold=1.0, max_scale=3.0, max_displacement=0.5, "
    "max_models=3)"
)


def _pair_with_blob(texture: np.ndarray, forward: float, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """Two road frames ``forward`` metres apart and a textured box that moves 10 px right, 5 down between them
    (a vehicle driving with the camera: it does not follow the road's motion)."""
    hist = render_road(texture, SMALL_CAMERA)
    key = render_road(texture, SMALL_CAMERA, yaw=yaw, forward=forward)
    blocks = np.random.default_rng(0).integers(0, 255, (22, 30, 3), np.uint8)
    box = cv2.resize(blocks, (120, 90), interpolation=cv2.INTER_NEAREST)
    hist[200:290, 300:420] = box
    key[205:295, 310:430] = box
    return hist, key


@pytest.mark.parametrize(("forward", "yaw"), [(3.0, 0.0), (4.0, 0.01)])
def test_motion_preset_aligns_low_frame_rate_motion_where_standard_fails(texture, forward, yaw):
    # 3-4 m a frame (5 fps at 15-20 m/s): the near road grows beyond the key pyramid's 1.69x
    hist, key = _pair_with_blob(texture, forward, yaw)
    truth = key_from_hist_motion(SMALL_CAMERA, forward, yaw)
    plain = estimate_homography(hist, key, horizon_row=SMALL_HORIZON, config=align_preset("standard"))
    assert not plain.ok or corner_error(plain.key_from_hist, truth, SHAPE, SMALL_HORIZON) > 20
    found = estimate_homography(hist, key, horizon_row=SMALL_HORIZON, config=align_preset("motion"))
    assert found.ok, found.reason
    assert corner_error(found.key_from_hist, truth, SHAPE, SMALL_HORIZON) < 2.0
    assert found.num_inliers >= AlignConfig().min_inliers


def test_motion_preset_keeps_a_confirmed_plain_estimate(texture, monkeypatch):
    # 1 m a frame (20 fps): the plain estimate is confirmed and kept; no pre-warped search runs
    hist = render_road(texture, SMALL_CAMERA)
    key = render_road(texture, SMALL_CAMERA, forward=1.0)
    truth = key_from_hist_motion(SMALL_CAMERA, 1.0)

    def no_search(*args: object, **kwargs: object) -> None:
        raise AssertionError("the pre-warped search ran on a confirmed plain estimate")

    monkeypatch.setattr(motion, "_warped_prep", no_search)
    found = estimate_homography(hist, key, horizon_row=SMALL_HORIZON, config=align_preset("motion"))
    assert found.ok and corner_error(found.key_from_hist, truth, SHAPE, SMALL_HORIZON) < 1.0


def test_forward_motion_is_the_ground_homography_of_driving_ahead():
    # the camera's vanishing row is its horizon_row (140) and its principal point the image centre
    truth = key_from_hist_motion(SMALL_CAMERA, 3.5)
    height, width = SHAPE
    bottom = np.linalg.inv(truth) @ np.array([(width - 1) / 2, height - 1, 1.0])
    scale = (height - 1 - SMALL_CAMERA.horizon_row) / (bottom[1] / bottom[2] - SMALL_CAMERA.horizon_row)
    np.testing.assert_allclose(forward_motion(scale, SHAPE, SMALL_CAMERA.horizon_row), truth, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(forward_motion(1.0, SHAPE, 150.0), np.eye(3), atol=1e-12)
    with pytest.raises(ValueError, match="scale >= 1"):
        forward_motion(0.9, SHAPE, 150.0)
    with pytest.raises(ValueError, match="vanishing_row"):
        forward_motion(1.5, SHAPE, float(height))


@pytest.mark.parametrize("scales", [(0.5,), (1.4, float("nan")), (9.0,)])
def test_motion_scales_are_checked(scales):
    with pytest.raises(ValueError, match="motion_scales"):
        AlignConfig(motion_scales=scales)


def test_presets_made_before_it_are_unchanged(texture, monkeypatch):
    assert repr(AlignConfig()) == STANDARD_REPR  # the pair cache keeps its entries
    assert ALIGN_PRESETS["standard"] == AlignConfig()
    assert ALIGN_PRESETS["fast"] == AlignConfig(key_scales=(1.0,), max_track_points=150)
    assert "motion_scales" not in repr(ALIGN_PRESETS["fast"])
    assert "motion_scales=(1.4, 1.8, 2.4)" in repr(ALIGN_PRESETS["motion"])
    assert "ground_sign=True" in repr(ALIGN_PRESETS["motion"])
    changed = {"motion_scales", "ground_sign", "max_scale", "max_displacement"}  # what the motion preset sets
    others = [f.name for f in fields(AlignConfig) if f.name not in changed]
    assert all(getattr(ALIGN_PRESETS["motion"], n) == getattr(AlignConfig(), n) for n in others)

    # standard and fast never take the motion path
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the motion prior ran for a preset without motion_scales")

    monkeypatch.setattr(motion, "estimate_with_motion", refuse)
    hist = render_road(texture, SMALL_CAMERA)
    key = render_road(texture, SMALL_CAMERA, forward=1.0)
    for name in ("standard", "fast"):
        assert estimate_homography(hist, key, horizon_row=SMALL_HORIZON, config=align_preset(name)).ok


@pytest.mark.parametrize("forward", [6.0, 8.0, 12.0])
def test_ground_sign_lets_the_true_homography_of_a_long_drive_through(forward):
    # 6-12 m (two to three frames at 5 fps): hist_from_key's h[2, 2], the image origin's w, turns negative while
    # the ground region lies before the line at infinity; the default test reads the origin's sign and refuses
    truth = key_from_hist_motion(SMALL_CAMERA, forward)
    assert np.linalg.inv(truth)[2, 2] < 0
    assert "perspective too strong" in check_plausible(truth, SHAPE, SMALL_HORIZON, AlignConfig())
    assert check_plausible(truth, SHAPE, SMALL_HORIZON, align_preset("motion")) == ""
    # and what is implausible stays so: a mirror image, a ground region cut by the line at infinity (w = 1 - y / 250
    # of hist_from_key: positive at row 162, negative at row 359)
    mirror = np.diag([-1.0, 1.0, 1.0]) @ truth
    assert "mirror" in check_plausible(mirror, SHAPE, SMALL_HORIZON, align_preset("motion"))
    crossing = np.linalg.inv(np.array([[1.0, 0, 0], [0, 1, 0], [0, -1 / 250, 1]]))
    assert "perspective too strong" in check_plausible(crossing, SHAPE, SMALL_HORIZON, align_preset("motion"))
