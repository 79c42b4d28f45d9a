"""The dashcam world (generator format 7): its camera spread, marking standards, road surface, roadside, sensor,
and that it leaves the classic world alone (the frozen splits: test_splits_frozen.py)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from stamlane.align.camera import Camera, Pose
from stamlane.synth.clip import generate_clip
from stamlane.synth.config import SynthConfig
from stamlane.synth.dashcam import HORIZON, MARKINGS, Marking, Roadside, Sensor, Surface
from stamlane.synth.road import render_texture, sample_road

DASHCAM = SynthConfig(width=320, height=180, num_frames=3, world="dashcam")


def test_the_settings_refuse_an_unknown_world_and_randomise_without_the_dashcam():
    with pytest.raises(ValueError, match="world must be one of"):
        SynthConfig(world="moon")
    with pytest.raises(ValueError, match="randomise"):
        SynthConfig(randomise=True)
    assert SynthConfig(world="dashcam", randomise=True).randomise


def test_a_dashcam_clip_is_a_function_of_its_generator():
    a = generate_clip(DASHCAM, np.random.default_rng(4))
    b = generate_clip(DASHCAM, np.random.default_rng(4))
    assert all(np.array_equal(x, y) for x, y in zip(a.frames, b.frames))
    assert json.dumps(a.labels) == json.dumps(b.labels)


def test_the_camera_spreads_the_horizon_over_dashcam_ranges_and_the_labels_follow():
    horizons, starts = [], []
    for seed in range(12):
        clip = generate_clip(DASHCAM, np.random.default_rng(seed))
        h = clip.image_from_ground[-1]
        far = h @ np.array([0.0, 1e6, 1.0])  # a ground point very far ahead: the horizon's row
        horizons.append(far[1] / far[2] / DASHCAM.height)
        starts.append(clip.h_samples[0])
        assert clip.h_samples[0] > far[1] / far[2]  # labels begin below the horizon
    assert HORIZON[0] - 0.02 <= min(horizons) and max(horizons) <= HORIZON[1] + 0.02
    assert max(horizons) - min(horizons) > 0.12  # spread, not the classic world's fixed 0.42
    assert len(set(starts)) > 3


def test_the_dashcam_road_takes_its_standards_dash_gap_and_width():
    rng = np.random.default_rng(0)
    marking = Marking(MARKINGS[0], dash=3.05, gap=9.15)
    road, _ = sample_road(rng, (-2.0, 150.0), 16.0, marking=marking)
    dashed = [m for m in road.marks if m.dashed]
    for mark in road.marks:
        assert (mark.dash, mark.gap) == (3.05, 9.15)
        assert MARKINGS[0].width[0] <= mark.width <= MARKINGS[0].width[1]
    assert all(m.dots == "" for m in road.marks if not m.dashed)
    found = set()
    for seed in range(30):  # the US standard puts raised markers on some dashed marks, in the gaps or alone
        road, _ = sample_road(np.random.default_rng(seed), (-2.0, 150.0), 16.0, marking=marking)
        found |= {m.dots for m in road.marks if m.dashed}
    assert {"gaps", "only"} <= found and dashed is not None


def test_dots_replace_the_paint_of_a_dots_only_mark():
    rng = np.random.default_rng(1)
    road, _ = sample_road(rng, (-2.0, 60.0), 16.0, curved_prob=0.0, worn_prob=0.0)
    for mark in road.marks:
        mark.dashed, mark.worn = False, []
    plain = render_texture(road, np.random.default_rng(2), shadows=0, unpainted=True)
    for mark in road.marks:
        mark.dashed, mark.dots = True, "only"
    dotted = render_texture(road, np.random.default_rng(2), shadows=0, unpainted=True)
    paint = [np.abs(t.astype(int) - b.astype(int)).mean(axis=2) > 40 for t, b in (plain, dotted)]
    assert 0 < paint[1].sum() < 0.25 * paint[0].sum()  # dots: a fraction of a solid line's paint


def test_the_surface_draws_joints_beside_the_marks_and_a_shoulder_of_another_shade():
    ppm, offsets = 16.0, [-1.8, 1.8]
    zs = np.linspace(40.0, 0.0, 641, dtype=np.float32)
    rel = np.broadcast_to(np.arange(-100, 101, dtype=np.float32)[None, :], (641, 201)).copy()
    lum = np.full((641, 201), 100.0, np.float32)
    surface = Surface("concrete", 160.0, 5.0, 0.3, 20.0, [], 0.0)
    out = surface.draw(lum, rel, zs, ppm, offsets, 100.0)
    col = lambda metres: round(metres * ppm) + 100  # noqa: E731
    assert out[5, col(0.0)] == pytest.approx(160.0)  # the lane, between two transverse joints
    assert out[5, col(3.0)] == pytest.approx(180.0)  # the right shoulder, 20 lighter
    assert out[5, col(1.8 + 0.5)] < 160.0  # the paving seam 0.2 + 0.3 m beyond the right mark
    joints = out[:, col(0.5)] < 150.0  # transverse joints every 5 m: 8 in 40 m
    assert 7 <= np.count_nonzero(np.diff(joints.astype(int)) == 1) <= 9


def test_a_barrier_and_a_rail_stand_beside_the_road_and_not_on_it():
    camera = Camera.for_size(320, 180)
    pose = Pose(0.0, 0.0, 1.5, 0.0, 0.0)
    frame = np.zeros((180, 320, 3), np.uint8)
    Roadside(barrier=-6.0, rail=None, barrier_grey=200.0, rail_grey=180.0).draw(
        frame, lambda z: 0.0 * np.asarray(z), camera, pose, 80.0
    )
    drawn = frame.max(axis=2) > 0
    assert drawn[:, :150].sum() > 500 and drawn[:, 170:].sum() == 0  # left of the image centre only
    horizon = int(camera.horizon_row(pose))
    assert drawn[horizon - 3 : horizon + 3].any()  # it runs to the far end
    frame[:] = 0
    Roadside(barrier=None, rail=5.0, barrier_grey=200.0, rail_grey=180.0).draw(
        frame, lambda z: 0.0 * np.asarray(z), camera, pose, 80.0
    )
    drawn = frame.max(axis=2) > 0
    assert drawn[:, 170:].sum() > 200 and drawn[:, :150].sum() == 0


def test_the_sensor_is_the_identity_when_it_does_nothing_and_compresses_when_asked():
    frame = np.random.default_rng(0).integers(0, 256, (90, 640, 3), dtype=np.uint8)  # blur in px at 640 wide
    plain = Sensor(0.0, 0.0, 1.0, 1.0, 0.0, 0)
    assert np.abs(plain.apply(frame, np.random.default_rng(1)).astype(int) - frame).max() <= 1
    blurred = Sensor(1.2, 0.0, 1.0, 1.0, 0.0, 0).apply(frame, np.random.default_rng(1))
    assert blurred.std() < 0.8 * frame.std()
    dark = Sensor(0.0, 0.0, 0.8, 1.0, 0.3, 0).apply(frame, np.random.default_rng(1))
    assert dark.mean() < 0.85 * frame.mean() and dark[:10, :10].mean() < dark[40:50, 315:325].mean()
    squeezed = Sensor(0.0, 0.0, 1.0, 1.0, 0.0, 30).apply(frame, np.random.default_rng(1))
    assert squeezed.shape == frame.shape and not np.array_equal(squeezed, frame)


def test_randomise_casts_a_colour_only_when_asked():
    assert Sensor.sample(np.random.default_rng(0), False).cast == (1.0, 1.0, 1.0)
    assert Sensor.sample(np.random.default_rng(0), True).cast != (1.0, 1.0, 1.0)


def test_the_classic_world_draws_what_it_drew_before_the_dashcam_existed():
    classic = SynthConfig(width=320, height=180, num_frames=3)
    assert classic.world == "classic"
    a = generate_clip(classic, np.random.default_rng(7))
    b = generate_clip(replace(classic, world="dashcam"), np.random.default_rng(7))
    assert not all(np.array_equal(x, y) for x, y in zip(a.frames, b.frames))
    assert a.h_samples == classic.h_samples()


def test_stamlane_synth_writes_the_dashcam_world_and_records_it(tmp_path, capsys):
    from stamlane.synth.cli import main as synth_main
    from stamlane.synth.layout import FORMAT_VERSION

    out = tmp_path / "dashcam"
    small = ["--clips", "1", "--challenging-clips", "0", "--reveal-clips", "0", "--reveal-traffic-clips", "0"]
    assert (
        synth_main(["--out", str(out), *small, "--size", "128x72", "--frames", "9", "--quiet", "--world", "dashcam"])
        == 0
    )
    info = json.loads((out / "dataset.json").read_text())
    assert info["format_version"] == FORMAT_VERSION == 7
    assert info["config"]["world"] == "dashcam" and info["config"]["randomise"] is False
    bad = tmp_path / "bad"
    assert synth_main(["--out", str(bad), *small, "--randomise"]) == 2
    assert (
        capsys.readouterr()
        .err.strip()
        .endswith("--randomise is an option of the dashcam worlds (--world dashcam, dashcam2, dashcam3)")
    )
    assert not bad.exists()
