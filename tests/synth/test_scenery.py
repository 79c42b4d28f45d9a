"""The dashcam2 world (`stamlane.synth.scenery`): the sun and its shadows, curbs and poles, surface repairs, vehicles
with bodies, and that the dashcam world of format 7 draws what it drew before this world existed."""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import cv2
import numpy as np
import pytest

from stamlane.align.camera import Camera, Pose
from stamlane.synth.bodies import BodyStyle, draw_bodies
from stamlane.synth.clip import generate_clip
from stamlane.synth.config import SynthConfig
from stamlane.synth.dashcam import Roadside, Surface
from stamlane.synth.road import render_texture, sample_road
from stamlane.synth.scenery import VERGE_KINDS, RepairedSurface, Scenery, Sun, Verge
from stamlane.synth.vehicles import Vehicle

DASHCAM2 = SynthConfig(width=320, height=180, num_frames=3, world="dashcam2", occluder_prob=1.0)
STRAIGHT = type(
    "Straight",
    (),
    {
        "centre": staticmethod(lambda z: 0.0 * np.asarray(z, float)),
        "slope": staticmethod(lambda z: 0.0 * np.asarray(z, float)),
    },
)()


def test_the_format_7_dashcam_world_draws_what_it_drew_before_dashcam2():
    # labels and per-frame colour means of a format-7 dashcam clip, measured before this world was added
    clip = generate_clip(SynthConfig(width=160, height=90, num_frames=2, world="dashcam"), np.random.default_rng(3))
    labels = hashlib.sha256(json.dumps(clip.labels).encode()).hexdigest()
    assert labels == "d73aaad7df6b97a73643a155acbb5bb99e175cb796bb0a0e9df8c93d25a15a31"
    means = [[float(f[..., k].mean()) for k in range(3)] for f in clip.frames]
    assert np.allclose(means, [[116.9, 101.8, 82.6], [122.0, 106.2, 86.3]], atol=0.3)


def test_the_dashcam2_world_draws_what_it_drew_before_dashcam3():
    # per-frame colour means of a dashcam2 clip, measured before the dashcam3 world was added
    clip = generate_clip(
        SynthConfig(width=160, height=90, num_frames=2, world="dashcam2", occluder_prob=1.0), np.random.default_rng(3)
    )
    means = [[float(f[..., k].mean()) for k in range(3)] for f in clip.frames]
    assert np.allclose(means, [[131.84, 116.09, 95.48], [120.41, 106.25, 87.43]], atol=0.05)


def test_a_verge_lies_beyond_the_shoulders_brighter_than_the_asphalt_and_leaves_the_road_alone():
    rng = np.random.default_rng(1)
    road, _ = sample_road(rng, (-2.0, 60.0), 16.0, curved_prob=0.0, worn_prob=0.0)
    dirt = Verge(("dirt", "gravel"), ((110.0, 135.0, 155.0), (160.0, 165.0, 170.0)), (0.2, 0.0), seed=4)
    plain = render_texture(road, np.random.default_rng(2), shadows=0)
    verged = render_texture(road, np.random.default_rng(2), shadows=0, verge=dirt)
    tex = road.texture_from_ground()
    at = lambda x, z: tuple(np.round(tex @ np.array([x, z, 1.0]))[:2].astype(int))  # noqa: E731
    left, right = min(m.offset for m in road.marks), max(m.offset for m in road.marks)
    for z in (5.0, 20.0, 40.0):
        col, row = at(0.0, z)  # the road: untouched
        assert np.array_equal(verged[row, col], plain[row, col])
        for x, colour in ((left - 3.5, dirt.colours[0]), (right + 3.5, dirt.colours[1])):  # beyond any shoulder
            col, row = at(x, z)
            patch = verged[row - 2 : row + 3, col - 2 : col + 3].reshape(-1, 3).mean(axis=0)
            assert np.abs(patch - np.array(colour)).max() < 25, (x, z, patch)
            assert patch.mean() > plain[row - 2 : row + 3, col - 2 : col + 3].mean() + 20  # brighter than grass
    kinds = {k for s in range(40) for k in Verge.sample(np.random.default_rng(s)).kinds}
    assert kinds == set(VERGE_KINDS)


def test_a_dashcam3_clip_is_the_dashcam2_clip_with_other_verges():
    a = generate_clip(replace(DASHCAM2, world="dashcam3"), np.random.default_rng(2))
    b = generate_clip(DASHCAM2, np.random.default_rng(2))
    assert a.labels == b.labels and a.h_samples == b.h_samples  # the same road, camera and drive
    assert not all(np.array_equal(x, y) for x, y in zip(a.frames, b.frames))


def test_a_dashcam2_clip_is_a_function_of_its_generator_and_not_the_dashcam_clip():
    a = generate_clip(DASHCAM2, np.random.default_rng(2))
    b = generate_clip(DASHCAM2, np.random.default_rng(2))
    assert all(np.array_equal(x, y) for x, y in zip(a.frames, b.frames))
    c = generate_clip(
        SynthConfig(width=320, height=180, num_frames=3, world="dashcam", occluder_prob=1.0), np.random.default_rng(2)
    )
    assert not all(np.array_equal(x, y) for x, y in zip(a.frames, c.frames))
    assert a.h_samples == c.h_samples  # the same camera draws: the labels' rows are the dashcam world's


def test_the_shadow_falls_away_from_the_sun_as_long_as_the_sun_is_low():
    ahead = Sun(azimuth=0.0, elevation=np.radians(45.0), depth=0.5)
    assert ahead.displacement() == pytest.approx([0.0, -1.0])  # the sun ahead: shadows towards the camera
    right_low = Sun(azimuth=np.pi / 2, elevation=np.radians(15.0), depth=0.5)
    assert right_low.displacement() == pytest.approx([-1 / np.tan(np.radians(15.0)), 0.0], abs=1e-9)
    overcast = [Sun.sample(np.random.default_rng(s), clear_sky=False).depth for s in range(20)]
    clear = [Sun.sample(np.random.default_rng(s), clear_sky=True).depth for s in range(20)]
    assert max(overcast) < min(clear)


def test_a_pole_casts_a_sharp_stripe_across_the_lanes_on_the_texture():
    rng = np.random.default_rng(1)
    road, _ = sample_road(rng, (-2.0, 60.0), 16.0, curved_prob=0.0, worn_prob=0.0)
    sun = Sun(azimuth=np.pi / 2, elevation=np.radians(20.0), depth=0.6)  # low, from the right
    right = max(m.offset for m in road.marks)
    shadows = sun.shadows(Roadside(None, None, 0.0, 0.0), [(right + 3.0, 30.0, 8.0)], road.centre, road.z_range)
    assert len(shadows) == 1 and len(sun.shadows(None, [], road.centre, road.z_range)) == 0
    plain = render_texture(road, np.random.default_rng(2), shadows=0)
    shaded = render_texture(road, np.random.default_rng(2), shadows=0, cast=shadows, cast_depth=0.6)
    tex = road.texture_from_ground()
    at = lambda x, z: tuple(np.round(tex @ np.array([x, z, 1.0]))[:2].astype(int))  # noqa: E731
    col, row = at(right + 3.0 - 8.0 / np.tan(np.radians(20.0)) / 2, 30.0)  # half way along the shadow, on the road
    assert shaded[row, col].mean() < 0.6 * plain[row, col].mean()
    col, row = at(0.0, 10.0)  # elsewhere: untouched
    assert np.array_equal(shaded[row, col], plain[row, col])


def test_curbs_stand_beside_the_road_and_poles_rise_above_the_horizon():
    camera = Camera.for_size(320, 180)
    pose = Pose(0.0, 0.0, 1.5, 0.0, 0.0)
    frame = np.zeros((180, 320, 3), np.uint8)
    Scenery([5.0], 0.15, 0.25, 200.0, []).draw(frame, STRAIGHT.centre, camera, pose, 80.0)
    drawn = frame.max(axis=2) > 0
    assert drawn[:, 170:].sum() > 100 and drawn[:, :150].sum() == 0  # right of the image centre only
    horizon = int(camera.horizon_row(pose))
    assert not drawn[: horizon - 2].any()  # a curb is low
    frame[:] = 0
    Scenery([], 0.15, 0.25, 200.0, [(-6.0, 20.0, 9.0)]).draw(frame, STRAIGHT.centre, camera, pose, 80.0)
    drawn = frame.max(axis=2) > 0
    assert drawn[: horizon - 10, :160].any() and not drawn[:, 160:].any()  # a tall pole on the left


def test_repairs_draw_strips_with_sealed_edges_joints_and_cracks():
    ppm = 16.0
    zs = np.linspace(40.0, 0.0, 641, dtype=np.float32)
    rel = np.broadcast_to(np.arange(-100, 101, dtype=np.float32)[None, :], (641, 201)).copy()
    lum = np.full((641, 201), 100.0, np.float32)
    surface = Surface("asphalt", 100.0, 0.0, 0.3, 0.0, [], 0.0)
    repaired = RepairedSurface(
        surface, strips=[(0.0, 1.0, 10.0, 20.0, 20.0)], joints=[(-3.0, 0.0, 40.0)], cracks=[(35.0, -2.0, 2.0, 0.0)]
    )
    out = repaired.draw(lum.copy(), rel, zs, ppm, [-1.8, 1.8], 100.0)
    col = lambda metres: round(metres * ppm) + 100  # noqa: E731
    row = lambda z: round((40.0 - z) * 16)  # noqa: E731
    assert out[row(20.0), col(0.0)] == pytest.approx(120.0)  # inside the strip, 20 lighter
    assert out[row(5.0), col(0.0)] == pytest.approx(100.0)  # before it: as it was
    assert out[row(20.0), col(0.5)] < 80.0  # its sealed edge
    assert out[row(20.0), col(-3.0)] < 60.0  # the joint along the road
    assert out[row(35.0), col(1.0)] < 60.0 and out[row(35.0), col(2.8)] == pytest.approx(100.0)  # the crack, across


def _car(z0: float, offset: float, height: float = 1.5) -> Vehicle:
    return Vehicle(z0, offset, 0.0, 0.0, 0.0, 1.0, 1.8, 4.5, height, (40, 160, 40))


def test_a_car_from_behind_has_wheels_tail_lights_and_glass_and_its_mask_covers_it():
    camera = Camera.for_size(320, 180)
    pose = Pose(0.0, 0.0, 1.5, 0.0, 0.0)
    style = BodyStyle((0.15, 0.65), 0.55, (40.0, 40.0, 40.0), (30.0, 30.0, 220.0))
    frame = np.full((180, 320, 3), 128, np.uint8)
    mask = np.zeros((180, 320), np.uint8)
    draw_bodies(frame, mask, [_car(8.0, 0.0)], [style], STRAIGHT, camera, pose, 0.0)
    changed = np.abs(frame.astype(int) - 128).max(axis=2) > 2
    assert changed.sum() > 500
    rims = cv2.dilate(mask, np.ones((3, 3), np.uint8))  # the mask is filled without anti-aliasing
    assert not (changed & (rims == 0)).any() and (mask > 0).sum() < 1.1 * changed.sum()
    red = (frame[..., 2] > 150) & (frame[..., 1] < 80)
    assert red.sum() > 4  # tail lights
    ys, xs = np.nonzero(mask)
    bottom = frame[ys.max() - 1, xs.min() : xs.max() + 1].max(axis=1)
    assert (bottom < 40).sum() >= 2  # tyres at the bottom corners


def test_a_car_beside_the_camera_shows_its_side_and_wheels_and_a_truck_its_cargo_box():
    camera = Camera.for_size(320, 180)
    pose = Pose(0.0, 0.0, 1.5, 0.0, 0.0)
    style = BodyStyle((0.15, 0.65), 0.55, (40.0, 40.0, 40.0), (30.0, 30.0, 220.0))
    frame = np.full((180, 320, 3), 128, np.uint8)
    mask = np.zeros((180, 320), np.uint8)
    draw_bodies(frame, mask, [_car(3.0, -3.6)], [style], STRAIGHT, camera, pose, 0.0)
    assert mask[:, :160].sum() > 0 and mask[:, 200:].sum() == 0
    dark = (frame.max(axis=2) < 35) & (mask > 0)
    assert dark.sum() > 20  # the near wheels seen from the side
    frame[:] = 128
    mask[:] = 0
    truck = Vehicle(12.0, 0.0, 0.0, 0.0, 0.0, 1.0, 2.5, 10.0, 3.4, (200, 40, 40))
    draw_bodies(frame, mask, [truck], [style], STRAIGHT, camera, pose, 0.0)
    ys, _ = np.nonzero(mask)
    assert ys.min() < camera.horizon_row(pose) < ys.max()  # taller than the camera: it rises above the horizon


def test_stamlane_synth_writes_the_dashcam2_world(tmp_path):
    from stamlane.synth.cli import main as synth_main

    out = tmp_path / "dashcam2"
    small = ["--clips", "1", "--challenging-clips", "0", "--reveal-clips", "0", "--reveal-traffic-clips", "0"]
    args = ["--out", str(out), *small, "--size", "128x72", "--frames", "9", "--quiet", "--world", "dashcam2"]
    assert synth_main([*args, "--randomise"]) == 0
    info = json.loads((out / "dataset.json").read_text())
    assert info["config"]["world"] == "dashcam2" and info["config"]["randomise"] is True
