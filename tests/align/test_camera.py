"""The one camera model (``stamlane.align.camera``): its pixel convention, and the same model behind the synthetic
generator and the ego-motion homographies of the alignment tests."""

from __future__ import annotations

import numpy as np
import pytest

from stamlane.align.camera import Camera, Pose
from stamlane.align.egomotion import RoadCamera, image_from_ground, key_from_hist_motion
from stamlane.synth import SynthConfig, generate_clip


def test_pixel_centres_are_integers_and_the_principal_point_is_the_image_centre() -> None:
    camera = Camera.centred(640, 360, 500.0)
    assert (camera.cx, camera.cy) == (319.5, 179.5)
    uv, depth = camera.project(Pose(0.0, 0.0, 1.5, 0.0, 0.0), np.array([[0.0, 1.5, 40.0]]))  # on the axis
    np.testing.assert_allclose(uv[0], [319.5, 179.5])
    assert depth[0] == pytest.approx(40.0)
    pitch = camera.pitch_for_horizon(140.0)
    assert camera.horizon_row(Pose(0.0, 0.0, 1.5, 0.0, pitch)) == pytest.approx(140.0)


def test_the_generator_and_the_ego_motion_homographies_share_the_camera() -> None:
    road = RoadCamera(width=640, height=360, focal=500.0, horizon_row=140.0, camera_height=1.5)
    assert road.camera == Camera.centred(640, 360, 500.0)
    level = SynthConfig(width=640, height=360, horizon=0.5).camera()  # level horizon at the centre row
    assert (level.cx, level.cy) == (road.camera.cx, road.camera.cy)
    # the ego-motion homography is the camera model's image_from_ground at the moved pose
    moved = road.camera.image_from_ground(Pose(0.0, 2.0, 1.5, 0.01, road.pitch))
    np.testing.assert_allclose(image_from_ground(road, yaw=0.01, forward=2.0), moved)
    # a ground point seen from both poses lands where key_from_hist sends it
    ground = np.array([1.2, 15.0, 1.0])
    hist = image_from_ground(road) @ ground
    key = image_from_ground(road, yaw=0.01, forward=2.0) @ ground
    mapped = key_from_hist_motion(road, 2.0, yaw=0.01) @ (hist / hist[2])
    np.testing.assert_allclose(mapped[:2] / mapped[2], key[:2] / key[2], atol=1e-9)


def test_the_generator_homographies_follow_the_camera_model() -> None:
    cfg = SynthConfig(width=160, height=96, num_frames=3)
    clip = generate_clip(cfg, np.random.default_rng(0))
    camera = cfg.camera()
    for h in clip.image_from_ground:  # every frame's homography maps the ground in front of the camera below
        top = camera.cy - camera.focal * 0.05  # the horizon, give or take the pitch jitter
        far = h @ np.array([0.0, 1e6, 1.0])
        assert far[2] > 0 and far[1] / far[2] > top
