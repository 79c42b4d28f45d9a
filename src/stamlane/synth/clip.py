"""Draw one clip: `generate_clip` renders the frames, every frame's lane labels and its exact ground homography.

A flat road (``road``) is seen by a pinhole camera (`stamlane.align.camera`) that drives along it with speed,
lateral drift or a lane change, the matching yaw, curvature and pitch jitter; box vehicles (``vehicles``) drive on
the road at their own speeds, change lanes, occlude lane marks and cast moving shadows. The ground texture is
rendered once per clip and each frame samples it through the frame's ground homography (``render``: averaged along
the road as far as one image row spans, with ground-anchored asphalt grain near the camera), so the ground-plane
homography of every frame is known exactly; the challenging factors' image effects (``effects``) and the reveal
splits' transient occluders (``transient``) come last. What the world of the settings adds (its camera, markings, sky,
sensor, surface, barriers, light, curbs and poles, verges and vehicles' bodies) its scene parts draw
(`stamlane.synth.parts`, at fixed places in this order: ``generate_clip`` knows no world by name). Defaults follow TuSimple: 20 frames at 20 fps (0.6-1.4 m of
forward motion per frame).

What each effect tests (see docs/data.md):
    * moving vehicles and their shadows hide paint in the key frame that an ALIGNED history frame shows
      (the vehicle moved relative to the road) -> what pre-aligned fusion can recover;
    * lateral drift, lane changes, yaw and curvature move the paint between UNALIGNED frames -> what
      pre-alignment repairs (fusion without alignment sees lanes at the wrong place);
    * dashes, worn paint and static shadows are static on the road -> aligned history frames do NOT fill
      them (the paint is just as missing there); they test the single-frame detector.

A clip is a deterministic function of its settings (`stamlane.synth.config.SynthConfig`) and its random generator's
state; `stamlane.synth.writer.write_clip` stores it.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import cv2
import numpy as np

from stamlane.align.camera import Camera, Pose
from stamlane.synth.config import ADJACENT_LANE_WIDTHS, SynthConfig
from stamlane.synth.effects import NightLight, Windscreen, glare, night
from stamlane.synth.parts import Parts
from stamlane.synth.render import GrainLayer, GroundRenderer
from stamlane.synth.road import Road, render_texture, sample_road
from stamlane.synth.transient import KeyOccluder
from stamlane.synth.vehicles import Vehicle, sample_vehicles, shadow_polygons
from stamlane.synth.worlds import WORLDS

__all__ = ["FAR_M", "HAZE_PX", "SynthClip", "generate_clip"]

FAR_M = 120.0
"""Ground rendered this far ahead of the last camera position; beyond it (a few pixels under the horizon) haze."""
HAZE_PX = 0.04
"""Height of the haze band under the horizon, as a fraction of the image height."""


@dataclass
class SynthClip:
    """One rendered clip, in memory.

    Attributes:
        frames: T BGR uint8 images (H, W, 3), oldest first.
        labels: per frame, TuSimple ``lanes`` (list of x lists, -2 = absent) at ``h_samples``.
        occluded: per frame, per lane, per h_sample: True where a vehicle (or windscreen dirt, the wiper) hides
            the labelled point.
        h_samples: label rows.
        image_from_ground: per frame, (3, 3) homography ground (X, Z, 1) metres -> pixels (w = depth).
        vehicle_masks: per frame, uint8 (H, W), 255 on pixels that hide the road: vehicles, and the windscreen's
            dirt and wiper.
        paint_contrast: per frame, uint8 (H, W): how much the lane paint changes each pixel, the mean over the
            colour channels of |frame - the same frame rendered without paint| (before JPEG), after every effect
            (vehicles, shadows, windscreen, glare, night); None unless ``generate_clip(..., paint_contrast=True)``.
    """

    frames: list[np.ndarray]
    labels: list[list[list[int]]]
    occluded: list[list[list[bool]]]
    h_samples: list[int]
    image_from_ground: list[np.ndarray]
    vehicle_masks: list[np.ndarray]
    paint_contrast: list[np.ndarray] | None = None

    def key_from_hist(self, key: int, hist: int) -> np.ndarray:
        """Exact ground-plane homography from frame ``hist`` pixels to frame ``key`` pixels (0-based), (3, 3)."""
        h = self.image_from_ground[key] @ np.linalg.inv(self.image_from_ground[hist])
        normalised: np.ndarray = h / h[2, 2]
        return normalised


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    smooth: np.ndarray = x * x * (3 - 2 * x)
    return smooth


def _ego_poses(cfg: SynthConfig, rng: np.random.Generator, road: Road, ego_lane: int) -> tuple[list[Pose], np.ndarray]:
    """Camera poses of the T frames and their ``(t, x, z)`` track."""
    n = cfg.num_frames
    t = np.arange(n) / cfg.fps
    duration = t[-1] if n > 1 else 0.0
    v0 = float(rng.uniform(*cfg.speed))
    acc = float(rng.uniform(-1.0, 1.0))
    z = v0 * t + acc * t**2 / 2
    # lateral offset from the ego lane's centre: a lane change (or a weave on a one-lane road) + drift
    lat = np.zeros(n)
    lat_v = np.zeros(n)
    if rng.random() < cfg.lane_change_prob:
        n_lanes = len(road.marks) - 1
        options = [d for d in (-1, 1) if 0 <= ego_lane + d < n_lanes]
        shift = road.lane_width * float(rng.choice(options)) if options else float(rng.choice([-1.0, 1.0]))
        dur = float(rng.uniform(1.2, 3.0))
        t0 = float(rng.uniform(-0.6 * dur, max(duration - 0.3 * dur, -0.5 * dur)))
        s = (t - t0) / dur
        lat += shift * _smoothstep(s)
        inside = (s > 0) & (s < 1)
        lat_v += np.where(inside, shift * 6 * s * (1 - s) / dur, 0.0)
    amp = float(rng.uniform(0.0, cfg.drift_amplitude))
    period = float(rng.uniform(1.5, 4.0))
    phase = float(rng.uniform(0, 2 * np.pi))
    lat += amp * np.sin(2 * np.pi * t / period + phase)
    lat_v += amp * 2 * np.pi / period * np.cos(2 * np.pi * t / period + phase)
    speed = v0 + acc * t
    yaw_j = np.radians(cfg.yaw_jitter_deg) * np.sin(
        2 * np.pi * t / float(rng.uniform(0.8, 2.0)) + float(rng.uniform(0, 6.3))
    )
    yaw = np.arctan(road.slope(z)) + np.arctan2(lat_v, speed) + yaw_j
    pitch0 = np.radians(float(rng.uniform(-0.5, 0.5)))
    pitch = pitch0 + np.radians(cfg.pitch_jitter_deg) * rng.standard_normal(n)
    x = road.centre(z) + lat
    poses = [Pose(float(x[i]), float(z[i]), cfg.cam_height, float(yaw[i]), float(pitch[i])) for i in range(n)]
    return poses, np.stack([t, x, z], axis=1)


def _lane_labels(
    cfg: SynthConfig, camera: Camera, road: Road, pose: Pose, image_from_ground: np.ndarray, h_samples: list[int]
) -> list[list[int]]:
    """TuSimple lanes (x per h_sample, -2 = absent) of every mark visible in a frame, left to right; with
    ``cfg.label_lanes == "adjacent"`` only of the marks within `ADJACENT_LANE_WIDTHS` lane widths beside the camera."""
    rows = np.asarray(h_samples, dtype=np.float64)
    z = pose.z + np.arange(1.0, cfg.label_range, 0.25)
    marks = road.marks
    if cfg.label_lanes == "adjacent":  # beside the camera, level with it (road.centre(pose.z) + offset - pose.x)
        beside = float(road.centre(pose.z)) - pose.x
        marks = [m for m in marks if abs(beside + m.offset) < ADJACENT_LANE_WIDTHS * road.lane_width]
    lanes = []
    for mark in marks:
        g = road.mark_points(mark, z)
        hom = np.c_[g, np.ones(len(g))] @ image_from_ground.T
        front = hom[:, 2] > 1e-6
        if front.sum() < 2:
            continue
        uv = hom[front, :2] / hom[front, 2:3]
        order = np.argsort(uv[:, 1])
        v_sorted, u_sorted = uv[order, 1], uv[order, 0]
        xs = np.interp(rows, v_sorted, u_sorted)
        ok = (rows >= v_sorted[0]) & (rows <= v_sorted[-1]) & (xs >= 0) & (xs <= cfg.width - 1)
        lane = [round(float(x)) if k else -2 for x, k in zip(xs, ok)]
        if sum(ok) >= 2:
            lanes.append(lane)
    return lanes


def _sky(cfg: SynthConfig, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    top = np.array([200, 150, 110], np.float32) * float(rng.uniform(0.8, 1.1))
    bottom = np.array([225, 215, 205], np.float32) * float(rng.uniform(0.85, 1.05))
    a = np.linspace(0, 1, cfg.height, dtype=np.float32)[:, None, None]
    sky = np.broadcast_to(top * (1 - a) + bottom * a, (cfg.height, cfg.width, 3)).copy()
    # a tree line near the horizon
    ridge = cv2.resize(rng.random((1, max(cfg.width // 16, 2))).astype(np.float32), (cfg.width, 1))[0]
    return np.clip(sky, 0, 255).astype(np.uint8), ridge


def generate_clip(
    cfg: SynthConfig, rng: np.random.Generator, *, paint_contrast: bool = False, label_rows: list[int] | None = None
) -> SynthClip:
    """Render one clip.

    Args:
        cfg: generator settings.
        rng: random generator; the clip is a deterministic function of its state.
        paint_contrast: also render every frame without the lane paint (from a copy of ``rng``, so the frames
            are the same with or without it) and keep the difference, ``SynthClip.paint_contrast``: where the
            paint is visible (`stamlane.synth.visibility`). About doubles the rendering time.
        label_rows: the rows the lanes are labelled at (``h_samples``; default ``cfg.h_samples()``, e.g.
            TuSimple's, `stamlane.synth.tusimple_layout.tusimple_rows`); the frames do not depend on them.

    Returns:
        the clip with labels of every frame and the true ``image_from_ground`` of every frame.
    """
    parts = Parts.of(WORLDS[cfg.world])
    look = parts.look(rng, cfg)  # the camera, markings, sky and sensor of the clip's world
    cfg = look.config  # the clip's own camera: its labels' rows and homographies follow from it
    camera = cfg.camera()
    duration = (cfg.num_frames - 1) / cfg.fps
    z_far = cfg.speed[1] * 1.1 * duration + FAR_M
    road, ego_lane = sample_road(
        rng,
        (-2.0, z_far),
        cfg.texture_ppm,
        curved_prob=cfg.curved_prob,
        max_kappa=cfg.max_kappa,
        worn_prob=cfg.worn_prob,
        worn_stretches=cfg.worn_stretches,
        worn_strength=cfg.worn_strength,
        dash_gap=cfg.dash_gap,
        marking=look.marking,
    )
    poses, track = _ego_poses(cfg, rng, road, ego_lane)
    n_shadows = int(rng.integers(cfg.static_shadows[0], cfg.static_shadows[1] + 1))
    scene = parts.scene(rng, road, look)  # the surface, barriers, light, curbs and poles, verges
    # the unpainted texture is a by-product of the same draws: the painted one is what it always was
    textures = render_texture(
        road,
        rng,
        shadows=n_shadows,
        shadow_depth=cfg.shadow_depth,
        unpainted=paint_contrast,
        surface=scene.surface,
        cast=scene.cast(road),
        cast_depth=scene.light.depth,
        verge=scene.verge,
    )
    texture, bare = textures if isinstance(textures, tuple) else (textures, None)  # a pair with paint_contrast
    vehicles: list[Vehicle] = []
    if rng.random() < cfg.occluder_prob:
        count = int(rng.integers(cfg.vehicles[0], cfg.vehicles[1] + 1))
        ego_speed = float((track[-1, 2] - track[0, 2]) / max(duration, 1e-6)) if cfg.num_frames > 1 else cfg.speed[0]
        vehicles = sample_vehicles(
            rng,
            road,
            ego_speed,
            duration,
            count=count,
            ego_track=track,
            lane_change_prob=cfg.vehicle_lane_change_prob,
            truck_prob=cfg.truck_prob,
            oncoming_prob=cfg.oncoming_prob,
            ahead=cfg.vehicle_ahead,
            speed_ratio=cfg.vehicle_speed,
        )
    paint_vehicles = parts.vehicles(rng, vehicles)  # their bodies' draws where the world has them
    classic_sky, ridge = _sky(cfg, rng)  # the tree line's draws for every world
    sky = parts.sky.paint(rng, look.sky, classic_sky)
    # the land beyond the texture's sides: in the dashcam worlds a dull roadside colour, not the sky's
    haze = look.sky.land(tuple(float(c) for c in sky[-1, 0]))
    beside = scene.beside()
    grain = GrainLayer(rng, cfg.grain) if cfg.grain > 0 else None
    levels = 7 if cfg.prefilter else 1
    renderer = GroundRenderer(texture, road.texture_from_ground(), grain, levels=levels)
    h_samples = cfg.h_samples()
    gains = 1.0 + 0.03 * rng.standard_normal(cfg.num_frames)
    # the factors' effects draw from rng only when used: the clean clips stay what they were
    windscreen = Windscreen.sample(rng, cfg.width, cfg.height) if cfg.windscreen else None
    night_light = NightLight.sample(rng) if cfg.night else None
    occluder = None
    if cfg.key_occluder:
        key_pose = poses[-1]
        key_labels = _lane_labels(cfg, camera, road, key_pose, camera.image_from_ground(key_pose), h_samples)
        marks = [np.array([(x, y) for x, y in zip(lane, h_samples) if x >= 0], np.float64) for lane in key_labels]
        size = (cfg.height, cfg.width)
        occluder = KeyOccluder.sample(cfg.key_occluder, rng, size, camera.horizon_row(key_pose), marks)
    first_occluded = cfg.num_frames - cfg.key_occluder_frames
    bare_rng = copy.deepcopy(rng) if paint_contrast else None  # the unpainted frames draw what the painted ones do

    def render_frame(i: int, ground: GroundRenderer, frame_rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Frame ``i`` (BGR uint8) of the ground ``ground`` with everything above it, and its occluder mask."""
        pose, t = poses[i], float(track[i, 0])
        img_from_ground = camera.image_from_ground(pose)
        horizon = camera.horizon_row(pose)
        sky_rows = int(np.clip(np.ceil(horizon + 1), 0, cfg.height))
        frame = ground.render(img_from_ground, (cfg.height, cfg.width), sky_rows, haze)
        frame[:sky_rows] = sky[:sky_rows]
        _haze(frame, sky_rows, haze)
        _draw_ridge(frame, ridge, horizon, pose, camera, look.sky.hills)
        for thing in beside:
            thing.draw(frame, road.centre, camera, pose, FAR_M)
        if vehicles:
            shade: np.ndarray = np.zeros((cfg.height, cfg.width), np.uint8)
            for v in vehicles:
                for poly in shadow_polygons(v, road, t, scene.light.shift):
                    pix = camera.project_polygon(pose, poly)
                    if pix is not None:
                        cv2.fillPoly(shade, [np.round(pix * 16).astype(np.int32)], 255, lineType=cv2.LINE_AA, shift=4)
            shade = cv2.blur(shade, (5, 5))
            factor = 1.0 - scene.light.depth * shade.astype(np.float32) / 255.0
            frame = (frame * factor[..., None]).astype(np.uint8)
        mask = np.zeros((cfg.height, cfg.width), np.uint8)
        paint_vehicles(frame, mask, road, camera, pose, t)
        if night_light is not None:
            frame = night(frame, frame_rng, night_light, horizon)
        if cfg.glare_prob > 0 and frame_rng.random() < cfg.glare_prob:
            frame = glare(frame, frame_rng, horizon)
        if windscreen is not None:
            mask |= windscreen.apply(frame, i)
        if occluder is not None and i >= first_occluded:
            frame = occluder.apply(frame)
            if occluder.mask is not None:
                mask |= occluder.mask
        if look.sensor is not None:
            frame = look.sensor.apply(frame, frame_rng)
        return cv2.convertScaleAbs(frame, alpha=float(gains[i])), mask

    rows = h_samples if label_rows is None else list(label_rows)  # after the occluder's draws: the same frames
    frames, labels, occluded, homs, masks = [], [], [], [], []
    for i, pose in enumerate(poses):
        img_from_ground = camera.image_from_ground(pose)
        frame, mask = render_frame(i, renderer, rng)
        lanes = _lane_labels(cfg, camera, road, pose, img_from_ground, rows)
        occ = [[bool(x >= 0 and mask[y, x] > 0) for x, y in zip(lane, rows)] for lane in lanes]
        frames.append(frame)
        labels.append(lanes)
        occluded.append(occ)
        homs.append(img_from_ground)
        masks.append(mask)
    contrast = None
    if bare is not None and bare_rng is not None:
        bare_renderer = GroundRenderer(bare, road.texture_from_ground(), grain, levels=levels)
        contrast = []
        for i, frame in enumerate(frames):
            unpainted, _ = render_frame(i, bare_renderer, bare_rng)
            diff = np.abs(frame.astype(np.int16) - unpainted.astype(np.int16)).mean(axis=2)
            contrast.append(np.round(diff).astype(np.uint8))
    return SynthClip(frames, labels, occluded, rows, homs, masks, contrast)


def _haze(frame: np.ndarray, first_row: int, colour: tuple[float, ...]) -> None:
    """Fade the ground into ``colour`` over a band under the horizon (hides where the texture ends)."""
    band = max(2, int(HAZE_PX * frame.shape[0]))
    rows = frame[first_row : first_row + band].astype(np.float32)
    a = np.linspace(1.0, 0.0, band, dtype=np.float32)[: len(rows), None, None]
    frame[first_row : first_row + band] = (rows * (1 - a) + np.asarray(colour, np.float32) * a).astype(np.uint8)


def _draw_ridge(
    frame: np.ndarray, ridge: np.ndarray, horizon: float, pose: Pose, camera: Camera, hills: float = 0.04
) -> None:
    """A dark tree line just above the horizon, up to ``hills`` of the frame height, shifting with yaw (not part of
    the ground plane)."""
    height = frame.shape[0]
    shift = round(camera.focal * float(pose.yaw)) % len(ridge)
    tops = horizon - (2 + hills * height * np.roll(ridge, -shift))
    first = int(np.clip(np.floor(tops.min()), 0, height))
    last = int(np.clip(np.floor(horizon) + 1, first, height))
    if last <= first:
        return
    rows = np.arange(first, last, dtype=np.float64)[:, None]
    sel = (rows >= tops[None, :]) & (rows <= horizon)
    band = frame[first:last]
    band[sel] = (band[sel] * 0.35).astype(np.uint8)
