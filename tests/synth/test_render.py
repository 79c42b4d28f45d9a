"""Rendering the ground of a synthetic frame: prefiltering, grain, and on-the-fly alignment of default clips."""

from __future__ import annotations

import cv2
import numpy as np

from stamlane.align import estimate_clip
from stamlane.align.camera import Camera, Pose
from stamlane.align.homography import default_horizon_row, ground_corners
from stamlane.synth.clip import generate_clip
from stamlane.synth.config import SynthConfig
from stamlane.synth.render import GrainLayer, GroundRenderer

CAMERA = Camera.for_size(320, 180)
POSE = Pose(0.0, 0.0, 1.8, 0.0, 0.0)
PPM = 16.0
# texture covering X in [-10, 10] m, Z in [0, 100] m; row 0 is the far end
TEX_FROM_GROUND = np.array([[PPM, 0, 10 * PPM], [0, -PPM, 100 * PPM], [0, 0, 1.0]])


def stripes() -> np.ndarray:
    """Alternating black and white texture rows: the worst case for point sampling far away."""
    tex = np.zeros((int(100 * PPM) + 1, int(20 * PPM) + 1, 3), np.uint8)
    tex[::2] = 255
    return tex


def test_without_prefilter_and_grain_it_is_one_perspective_warp():
    rng = np.random.default_rng(0)
    tex = rng.integers(0, 256, (int(100 * PPM) + 1, int(20 * PPM) + 1, 3), dtype=np.uint8)
    h = CAMERA.image_from_ground(POSE)
    first = int(np.ceil(CAMERA.horizon_row(POSE) + 1))
    got = GroundRenderer(tex, TEX_FROM_GROUND, None, levels=1).render(h, (180, 320), first, (9, 9, 9))
    want = cv2.warpPerspective(tex, h @ np.linalg.inv(TEX_FROM_GROUND), (320, 180), borderValue=(9, 9, 9))
    assert np.abs(got[first:].astype(int) - want[first:].astype(int)).max() <= 1
    assert (got[:first] == 9).all()


def test_prefiltering_averages_far_rows_and_keeps_near_rows():
    h = CAMERA.image_from_ground(POSE)
    first = int(np.ceil(CAMERA.horizon_row(POSE) + 1))
    plain = GroundRenderer(stripes(), TEX_FROM_GROUND, None, levels=1).render(h, (180, 320), first, (128,) * 3)
    filtered = GroundRenderer(stripes(), TEX_FROM_GROUND, None).render(h, (180, 320), first, (128,) * 3)
    far = slice(first + 5, first + 25)  # 20-60 m: one image row spans many texture rows
    # point sampling aliases the stripes into rows of black and white; prefiltering gives their mean grey
    assert plain[far, 160, 0].astype(float).std() > 60
    assert filtered[far, 160, 0].astype(float).std() < 20
    assert abs(filtered[far, 160, 0].astype(float).mean() - 127.5) < 15
    # the nearest rows span less than a texture row: both sample the texture itself
    assert filtered[-10:, 160, 0].astype(float).std() > 60


def test_grain_is_anchored_to_the_ground_and_fades_out_far_away():
    rng = np.random.default_rng(1)
    grey = np.full((int(100 * PPM) + 1, int(20 * PPM) + 1, 3), 100, np.uint8)
    renderer = GroundRenderer(grey, TEX_FROM_GROUND, GrainLayer(rng))
    big = Camera.for_size(640, 360)
    first = int(np.ceil(big.horizon_row(POSE) + 1))
    a = renderer.render(big.image_from_ground(POSE), (360, 640), first, (100,) * 3)
    moved = Pose(0.3, 1.0, 1.8, 0.01, 0.0)
    b = renderer.render(big.image_from_ground(moved), (360, 640), first, (100,) * 3)
    near = slice(300, 360)
    assert a[near].astype(float).std() > 5  # grain near the camera
    assert a[first : first + 30].astype(float).std() < 1  # none far away (it would alias)
    key_from_hist = big.image_from_ground(moved) @ np.linalg.inv(big.image_from_ground(POSE))
    warped = cv2.warpPerspective(a, key_from_hist, (640, 360)).astype(float)
    diff = np.abs(warped[near] - b[near].astype(float))
    assert np.median(diff) < 0.5 * np.median(np.abs(a[near].astype(float) - b[near].astype(float)))


def test_default_clips_are_aligned_on_the_fly():
    """The paper's ORB pre-alignment recovers the generator's true homographies on default clips (640x360)."""
    cfg = SynthConfig(num_frames=4)
    row = default_horizon_row(cfg.height)
    corners = ground_corners((cfg.height, cfg.width), row).reshape(-1, 1, 2)
    good = total = 0
    for i in range(4):
        clip = generate_clip(cfg, np.random.default_rng([0, 0, i]))
        frames = [cv2.imdecode(cv2.imencode(".jpg", f)[1], cv2.IMREAD_COLOR) for f in clip.frames]
        alignments = estimate_clip(frames, strategy="chain")
        for j, al in enumerate(alignments[:-1]):
            truth = clip.key_from_hist(3, j)
            back = cv2.perspectiveTransform(cv2.perspectiveTransform(corners, np.linalg.inv(truth)), al.key_from_hist)
            error = float(np.linalg.norm((back - corners).reshape(-1, 2), axis=1).mean())
            good += int(al.ok and error < 2.0)
            total += 1
    assert good >= total - 2, f"{good} of {total} history frames aligned within 2 px"
