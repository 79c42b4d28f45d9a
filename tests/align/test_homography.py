"""estimate_homography: accuracy on pairs with a known H, every failure mode, input checks."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stamlane.align import AlignConfig, Alignment, check_plausible, estimate_homography
from stamlane.align.egomotion import RoadCamera, image_from_ground, key_from_hist_motion
from stamlane.align.homography import fit_homography
from stamlane.align.synthetic import render_road

from .conftest import SMALL_CAMERA, SMALL_HORIZON, corner_error

SHAPE = (SMALL_CAMERA.height, SMALL_CAMERA.width)


def _assert_identity_failure(alignment: Alignment, reason: str) -> None:
    assert not alignment.ok
    assert reason in alignment.reason
    np.testing.assert_array_equal(alignment.key_from_hist, np.eye(3))
    assert alignment.key_from_hist.dtype == np.float64


def test_egomotion_homography_maps_ground_points():
    camera = RoadCamera()
    truth = key_from_hist_motion(camera, forward=1.5, yaw=0.02, pitch=-0.005)
    ground = np.array([[-3.0, 8.0, 1], [2.0, 15.0, 1], [5.0, 30.0, 1]]).T  # (X, Z, 1) metres, hist ground frame
    hist = image_from_ground(camera) @ ground
    key = image_from_ground(camera, yaw=0.02, pitch=-0.005, forward=1.5) @ ground
    mapped = truth @ hist
    np.testing.assert_allclose(mapped[:2] / mapped[2], key[:2] / key[2], atol=1e-6)


@pytest.mark.parametrize(
    ("forward", "yaw_deg", "pitch_deg", "tolerance"),
    # the largest motion (2 m, 2 degrees) measured 1.64 px since the camera's principal point is the pixel
    # centre (W - 1) / 2 (it was W / 2): the renderer's aliasing moved by half a pixel
    [(0.5, 0.0, 0.0, 1.5), (1.2, 1.5, -0.3, 1.5), (2.0, -2.0, 0.5, 2.0), (1.0, -0.8, 0.2, 1.5)],
)
def test_known_ego_motion_is_recovered_within_a_pixel(texture, forward, yaw_deg, pitch_deg, tolerance):
    yaw, pitch = np.radians(yaw_deg), np.radians(pitch_deg)
    hist = render_road(texture, SMALL_CAMERA)
    key = render_road(texture, SMALL_CAMERA, yaw=yaw, pitch=pitch, forward=forward)
    truth = key_from_hist_motion(SMALL_CAMERA, forward, yaw, pitch)
    alignment = estimate_homography(hist, key, horizon_row=SMALL_HORIZON)
    assert alignment.ok, alignment.reason
    assert alignment.reason == ""
    assert alignment.num_matches >= alignment.num_inliers >= 12
    assert alignment.key_from_hist.shape == (3, 3) and alignment.key_from_hist.dtype == np.float64
    # 1.5 px at 640x360: the rendered texture aliases differently in the two views near the horizon
    assert corner_error(alignment.key_from_hist, truth, SHAPE, SMALL_HORIZON) < tolerance


def test_refinement_improves_on_the_match_stage(texture):
    hist = render_road(texture, SMALL_CAMERA)
    key = render_road(texture, SMALL_CAMERA, yaw=0.02, forward=1.6)
    truth = key_from_hist_motion(SMALL_CAMERA, 1.6, 0.02)
    coarse = estimate_homography(hist, key, horizon_row=SMALL_HORIZON, config=AlignConfig(refine=False))
    fine = estimate_homography(hist, key, horizon_row=SMALL_HORIZON)
    assert corner_error(fine.key_from_hist, truth, SHAPE, SMALL_HORIZON) < corner_error(
        coarse.key_from_hist, truth, SHAPE, SMALL_HORIZON
    )


def test_grayscale_and_default_horizon(texture):
    hist = render_road(texture, SMALL_CAMERA, color=False)
    key = render_road(texture, SMALL_CAMERA, forward=1.0, color=False)
    alignment = estimate_homography(hist, key[..., None])  # (H, W) and (H, W, 1); horizon 0.45 * H = 162
    assert alignment.ok
    assert corner_error(alignment.key_from_hist, key_from_hist_motion(SMALL_CAMERA, 1.0), SHAPE, SMALL_HORIZON) < 1.5


def test_real_frame_pair(shared_dir):
    paths = sorted((shared_dir / "data" / "frames").glob("*.jpg"))
    if not paths:
        pytest.skip("no real frames in ../shared/data/frames")
    hist = cv2.imread(str(paths[0]))
    camera = RoadCamera()  # 1280x720, vanishing line at row 280 like these frames
    truth = key_from_hist_motion(camera, 1.5, np.radians(1.0), np.radians(-0.3))
    key = cv2.warpPerspective(hist, truth, (hist.shape[1], hist.shape[0]))
    key = np.clip(key.astype(np.float32) * 1.1 + 10 + np.random.default_rng(0).normal(0, 2, key.shape), 0, 255)
    key = cv2.imdecode(cv2.imencode(".jpg", key.astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 75])[1], 1)
    alignment = estimate_homography(hist, key)
    assert alignment.ok, alignment.reason
    assert corner_error(alignment.key_from_hist, truth, hist.shape[:2], 324) < 1.0


def test_identical_frames_give_the_identity(texture):
    frame = render_road(texture, SMALL_CAMERA)
    alignment = estimate_homography(frame, frame.copy(), horizon_row=SMALL_HORIZON)
    assert alignment.ok
    np.testing.assert_allclose(alignment.key_from_hist, np.eye(3), atol=1e-3)


@pytest.mark.parametrize(
    ("make", "reason"),
    [
        (lambda f: np.zeros_like(f), "too few features"),  # black
        (lambda f: np.full_like(f, 128), "too few features"),  # textureless
        (lambda f: cv2.GaussianBlur(f, (0, 0), 25), "too few"),  # blurred beyond recognition
    ],
)
def test_unusable_history_frame_fails_softly(texture, make, reason):
    key = render_road(texture, SMALL_CAMERA)
    _assert_identity_failure(estimate_homography(make(key), key, horizon_row=SMALL_HORIZON), reason)


def test_identical_black_frames_fail_softly():
    black = np.zeros((120, 160, 3), np.uint8)
    _assert_identity_failure(estimate_homography(black, black), "too few features")


def test_unrelated_frames_fail_softly(texture):
    rng = np.random.default_rng(0)
    noise = cv2.GaussianBlur(rng.integers(0, 256, (SHAPE[0], SHAPE[1], 3)).astype(np.uint8), (0, 0), 1.5)
    key = render_road(texture, SMALL_CAMERA)
    alignment = estimate_homography(noise, key, horizon_row=SMALL_HORIZON)
    assert not alignment.ok and alignment.reason  # too few matches / inliers, or an implausible fit
    np.testing.assert_array_equal(alignment.key_from_hist, np.eye(3))


def test_too_few_matches_and_degenerate_matches():
    cfg = AlignConfig()
    few = np.zeros((5, 2), np.float32)
    _assert_identity_failure(fit_homography(few, few, SHAPE, SMALL_HORIZON, cfg), "too few matches")
    line = np.stack([np.linspace(0, 600, 40), np.full(40, 300.0)], axis=1).astype(np.float32)  # collinear
    alignment = fit_homography(line, line + 1, SHAPE, SMALL_HORIZON, cfg)
    assert not alignment.ok and alignment.reason


FLIP = np.array([[-1.0, 0, 639], [0, 1, 0], [0, 0, 1]])
SCALE = np.diag([5.0, 5.0, 1.0])
SHEAR = np.array([[1.0, 4.0, 0], [0, 1, 0], [0, 0, 1]])
PERSPECTIVE = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0.01, 1]])
SHIFT = np.array([[1.0, 0, 500], [0, 1, 0], [0, 0, 1]])


@pytest.mark.parametrize(
    ("matrix", "reason"),
    [
        (FLIP, "mirror"),
        (SCALE, "scale"),
        (SHEAR, "shear"),
        (PERSPECTIVE, "infinity"),
        (SHIFT, "motion"),
        (np.zeros((3, 3)), "singular"),
        (np.full((3, 3), np.nan), "non-finite"),
    ],
)
def test_implausible_homographies_are_rejected(matrix, reason):
    assert reason in check_plausible(matrix, SHAPE, SMALL_HORIZON)


def test_plausible_ego_motions_are_accepted():
    for forward in (0.0, 1.0, 2.0, 4.0):
        truth = key_from_hist_motion(SMALL_CAMERA, forward, np.radians(2.0), np.radians(0.5))
        assert check_plausible(truth, SHAPE, SMALL_HORIZON) == ""


def test_implausible_fit_is_reported_not_returned(texture):
    """A mirrored history frame matches, but its homography is a flip: identity, ok=False."""
    key = render_road(texture, SMALL_CAMERA)
    alignment = estimate_homography(np.ascontiguousarray(key[:, ::-1]), key, horizon_row=SMALL_HORIZON)
    assert not alignment.ok and alignment.reason
    np.testing.assert_array_equal(alignment.key_from_hist, np.eye(3))


GOOD = np.zeros((100, 120, 3), np.uint8)


@pytest.mark.parametrize(
    ("hist", "key", "kwargs", "message"),
    [
        (GOOD.astype(np.float32), GOOD, {}, "float32"),
        (GOOD, GOOD[..., :2], {}, r"\(100, 120, 2\)"),
        (GOOD[None], GOOD, {}, r"\(1, 100, 120, 3\)"),
        ([[0]], GOOD, {}, "list"),
        (GOOD, np.zeros((100, 121, 3), np.uint8), {}, r"\(100, 121, 3\)"),
        (np.zeros((20, 20), np.uint8), np.zeros((20, 20), np.uint8), {}, r"\(20, 20\)"),
        (GOOD, GOOD, {"horizon_row": 99}, "99"),
        (GOOD, GOOD, {"horizon_row": -1}, "-1"),
        (GOOD, GOOD, {"horizon_row": 0.5}, "0.5"),
    ],
)
def test_invalid_input_raises_with_the_value(hist, key, kwargs, message):
    with pytest.raises(ValueError, match=message):
        estimate_homography(hist, key, **kwargs)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"working_scale": 2.0}, "2.0"),
        ({"key_scales": (0.5,)}, "0.5"),
        ({"ratio": 1.5}, "1.5"),
        ({"min_inliers": 3}, "3"),
        ({"max_models": 0}, "max_models must be >= 1, got 0"),
    ],
)
def test_align_config_rejects_bad_values(kwargs, message):
    with pytest.raises(ValueError, match=message):
        AlignConfig(**kwargs)


def test_never_raises_on_odd_valid_images():
    """Random sizes (down to 64x64), horizons and contents: always an Alignment, identity when not ok."""
    rng = np.random.default_rng(0)
    for trial in range(30):
        h, w = int(rng.integers(64, 300)), int(rng.integers(64, 400))
        contents = [
            lambda: rng.integers(0, 256, (h, w, 3)).astype(np.uint8),  # noqa: B023
            lambda: (rng.random((h, w)) > 0.995).astype(np.uint8) * 255,  # noqa: B023
            lambda: np.full((h, w, 1), 77, np.uint8),  # noqa: B023
        ]
        frame = contents[trial % 3]()
        other = np.ascontiguousarray(np.roll(frame, 3, axis=1)) if trial % 2 else frame
        row = None if trial % 4 == 0 else int(rng.integers(0, h - 32))
        alignment = estimate_homography(frame, other, horizon_row=row)
        assert alignment.key_from_hist.shape == (3, 3)
        assert alignment.ok or (alignment.reason and np.array_equal(alignment.key_from_hist, np.eye(3)))
