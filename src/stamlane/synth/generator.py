"""Synthetic road clips in the TuSimple layout, with the true inter-frame homographies.

A flat road (``road``) is seen by a pinhole camera (``camera``) that drives along it with
speed, lateral drift or a lane change, the matching yaw, curvature and pitch jitter; box vehicles
(``vehicles``) drive on the road at their own speeds, change lanes, occlude lane marks and cast
moving shadows. The ground texture is rendered once per clip and each frame samples it through the
frame's ground homography (``render``: averaged along the road as far as one image row spans, with
ground-anchored asphalt grain near the camera), so the ground-plane homography of every frame is known
exactly. Defaults follow TuSimple: 20 frames at 20 fps (0.6-1.4 m of forward motion per frame).

What each effect tests (see the README):
    * moving vehicles and their shadows hide paint in the key frame that an ALIGNED history frame shows
      (the vehicle moved relative to the road) -> what pre-aligned fusion can recover;
    * lateral drift, lane changes, yaw and curvature move the paint between UNALIGNED frames -> what
      pre-alignment repairs (fusion without alignment sees lanes at the wrong place);
    * dashes, worn paint and static shadows are static on the road -> aligned history frames do NOT fill
      them (the paint is just as missing there); they test the single-frame detector.

Layout written by ``generate_dataset`` (``<id>`` like ``train-0007``)::

    <root>/clips/<id>/1.jpg .. <T>.jpg          frames, oldest first; the key frame is <T>.jpg
    <root>/{train,val,test,challenging}.json    TuSimple label json-lines of each clip's KEY frames: the last
                                                frame and every ``key_step``-th frame before it, down to frame
                                                ``FIRST_KEY + 1`` (so every key frame has >= 7 history frames)
    <root>/{reveal,reveal-traffic}.json         the key frame (the last of 12) of each clip of the two splits
                                                where the history reveals lanes (`REVEAL`, `REVEAL_TRAFFIC`)
    <root>/<split>-<kind>.json                  the key frames of each factor or kind of the challenging,
                                                reveal and reveal-traffic splits
    <root>/frame_labels/<id>.json               TuSimple-style labels of EVERY frame (+ "occluded" flags)
    <root>/homographies/<id>.json               true geometry: image_from_ground per frame, and
                                                last_from_frame / next_from_frame (= key_from_hist)
    <root>/visibility/<split>.json              per key frame of the split's labels, per labelled point: where
                                                its paint is visible (key frame / history only / nowhere;
                                                ``stamlane.synth.visibility``)
    <root>/dataset.json                         generator settings and statistics (written last)
"""

from __future__ import annotations

import copy
import json
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from stamlane.align.camera import Camera, Pose
from stamlane.synth.effects import NightLight, Windscreen, glare, night
from stamlane.synth.render import GrainLayer, GroundRenderer
from stamlane.synth.road import Road, render_texture, sample_road
from stamlane.synth.transient import KEY_OCCLUDERS, KeyOccluder
from stamlane.synth.vehicles import Vehicle, draw_vehicles, sample_vehicles, shadow_polygons
from stamlane.synth.visibility import VISIBILITY_CLASSES, paint_visibility, visibility_class

__all__ = [
    "DEMO_SPLITS",
    "FACTORS",
    "REVEAL",
    "REVEAL_TRAFFIC",
    "SPLITS",
    "TRAIN_MOTION",
    "Factor",
    "SynthClip",
    "SynthConfig",
    "generate_clip",
    "generate_dataset",
    "key_frames",
    "write_clip",
]

SPLITS = ("train", "val", "test", "challenging", "reveal", "reveal-traffic")
"""Every split of a set, in the order of their seeds' codes (clip ``i`` of split ``SPLITS[c]`` draws from
``(seed, c, i)``: a split added at the end leaves every clip before it as it was)."""
KIND_SPLITS = ("challenging", "reveal", "reveal-traffic")
"""Splits whose every clip has a named factor or kind, with a label file per kind (``<split>-<kind>.json``)."""
FORMAT_VERSION = 6
"""6: the ``reveal`` and ``reveal-traffic`` splits (`REVEAL`, `REVEAL_TRAFFIC`: 12-frame clips where the history
shows what the key frame hides) with their visibility over every history frame, and ``train_motion`` clips (the
reveal splits' ego motion, no occluder) in the train split after its factor clips; every clip of format 5 is as it
was, byte for byte; 5: factor clips added to the train and val splits (``train_factors``, ``val_factors``; the clean clips and the
test and challenging splits are format 4's, byte for byte) and the paint visibility of every labelled key-frame
point of the val, test and challenging splits (``visibility/<split>.json``); 4: the challenging split is made of labelled factors (`FACTORS`, one per clip; train, val and test are format
3's, byte for byte); 3: several labelled key frames per clip (``key_step``), light traffic in the clean splits; 2: 20 fps, asphalt grain near the camera, along-road
prefiltering, vehicles 4-35 m ahead; 1: 10 fps, 3-30 m."""
DEFAULT_SYNTHETIC_ROOT = f"data/synthetic-v{FORMAT_VERSION}"
"""Where ``ClipDataModule(root=None)`` and ``stamlane demo`` read the synthetic set (relative to the working
directory; generated there when missing). Named by the format version, so a newer generator never reuses (or
overwrites) an older set."""
DEMO_SPLITS = {
    "train": 120,
    "val": 20,
    "test": 100,
    "challenging": 128,
    "reveal": 90,
    "reveal_traffic": 60,
    "train_factors": 120,
    "val_factors": 32,
    "train_motion": 96,
}
"""Clips per split of the default set (``stamlane demo``, ``root: null``, ``stamlane synth --demo``): 120 clean and
120 factor clips (15 per factor) and 96 ``train_motion`` clips in train (what makes the fusion read its history,
docs/training.md); 20 clean and 32 factor val clips; 100 test and 128 challenging clips (16 per factor); 90 reveal
(30 per kind) and 60 reveal-traffic clips (30 per kind). The arguments of `generate_dataset`."""
TRAIN_KEY_STEP = 1
"""Default key frames of the train split: every frame from ``FIRST_KEY`` on (13 of a 20-frame clip)."""
EVAL_KEY_STEP = 3
"""Default key frames of the val, test and challenging splits: frames 8, 11, 14, 17, 20 of a 20-frame clip."""
FIRST_KEY = 7
"""0-based index of the earliest frame that may be a key frame: every key frame has >= 7 history frames, enough
for the paper's longest clips (5 frames) and the 8-frame ones some video detectors use."""
FAR_M = 120.0
"""Ground rendered this far ahead of the last camera position; beyond it (a few pixels under the horizon) haze."""
TEMPORAL_LABELS = "challenging-frames.json"
"""Label file of every frame from the ``FIRST_KEY + 1``-th of the first `TEMPORAL_CLIPS_PER_FACTOR` challenging clips
of each factor, oldest first: what the temporal stability metrics (Rs / Rj / Rm) score, frame after frame."""
TEMPORAL_CLIPS_PER_FACTOR = 4
VISIBILITY_DIR = "visibility"
"""Folder of a set's visibility files: ``visibility/<split>.json``, one line per key frame of ``<split>.json``
(``raw_file``, ``visibility``: per lane, per h_sample, the mask of `stamlane.synth.visibility.paint_visibility`)."""
HAZE_PX = 0.04
"""Height of the haze band under the horizon, as a fraction of the image height."""


@dataclass(frozen=True)
class Factor:
    """One challenging factor: what it does to the clean settings and what history frames can do about it."""

    description: str
    overrides: dict[str, object]
    geometry: str
    """What an aligned history frame shows where the key frame cannot see the paint, and an unaligned one."""


_TRAFFIC = {
    "occluder_prob": 1.0,
    "vehicles": (4, 8),
    "vehicle_ahead": (3.0, 30.0),
    "truck_prob": 0.35,
    "oncoming_prob": 0.0,
    "vehicle_lane_change_prob": 0.0,
}
FACTORS: dict[str, Factor] = {
    "traffic_standing": Factor(
        "4-8 vehicles standing on the road (relative speed -1x the camera's)",
        _TRAFFIC | {"vehicle_speed": (0.0, 0.05)},
        "a standing vehicle hides the same road in every frame: aligned history cannot reveal it",
    ),
    "traffic_same_speed": Factor(
        "4-8 vehicles at the camera's speed (relative speed ~0)",
        _TRAFFIC | {"vehicle_speed": (0.9, 1.1)},
        "the vehicle moves with the camera, so the road it hides now lay in front of it earlier: aligned "
        "history reveals up to the camera's travel (~3 m in 3 frames)",
    ),
    "traffic_oncoming": Factor(
        "4-8 vehicles driving towards the camera (relative speed ~2x the camera's)",
        _TRAFFIC | {"vehicle_speed": (-1.1, -0.9)},
        "the vehicle moves fast over the road: aligned history shows the road it hides now unoccluded",
    ),
    "windscreen": Factor(
        "dirt and drops on the windscreen and a sweeping wiper (camera-fixed)",
        {"windscreen": True},
        "aligned history shows the road behind the dirt at other pixels; unaligned history shows the dirt again",
    ),
    "glare": Factor(
        "frames spoilt one at a time by overexposure, a sun flare or motion blur (60 % of the frames)",
        {"glare_prob": 0.6},
        "a clean history frame shows the same paint: aligned it lands on the key frame's paint",
    ),
    "shadow": Factor(
        "8-14 deep static shadows on the road",
        {"static_shadows": (8, 14), "shadow_depth": 0.8},
        "a static shadow lies on the road: aligned history shows it at the same place, no better lit",
    ),
    "worn_dashed": Factor(
        "worn paint (3-7 stretches of 5-30 m per mark, 70-100 % gone) and dashes with 10-16 m gaps",
        {"worn_prob": 1.0, "worn_stretches": (3, 7), "worn_strength": (0.7, 1.0), "dash_gap": (10.0, 16.0)},
        "missing paint is missing on the road: aligned history cannot fill a gap (unaligned history slides "
        "dashes into it, at the wrong place when the camera turns)",
    ),
    "night": Factor(
        "night: headlights light the near road, the far road is dark and noisy",
        {"night": True},
        "every frame is as dark; aligned frames average the sensor noise away on the static paint",
    ),
}
"""The factors of the challenging split: its clip ``i`` has factor ``i % len(FACTORS)`` (in this order) on top of
the clean settings, one factor per clip; ``challenging-<factor>.json`` holds each factor's key frames."""

REVEAL_FRAMES = 12
"""Frames of a clip of the reveal splits (the key frame last): room for spans up to 8 frames, or 4 at stride 3."""
REVEAL_MOTION: dict[str, object] = {
    "num_frames": REVEAL_FRAMES,
    "lane_change_prob": 1.0,
    "drift_amplitude": 0.8,
    "yaw_jitter_deg": 1.5,
    "occluder_prob": 0.0,
}
"""The ego motion of the reveal clips and the train split's ``train_motion`` clips: a lane change in every clip,
strong drift and yaw jitter, so that an UNALIGNED history frame shows the paint tens of pixels from where the key
frame has it (beyond the metrics' tolerances); no vehicles, so the history frames are clean."""
_REVEAL_GEOMETRY = (
    "hidden in the key frame alone: every aligned history frame shows the paint under it; unaligned history "
    "shows it displaced by the lane change, drift and yaw"
)
REVEAL: dict[str, Factor] = {
    "key_spray": Factor(
        "an opaque textured band over the near road, full width, in the key frame alone (never in training)",
        REVEAL_MOTION | {"key_occluder": "spray"},
        _REVEAL_GEOMETRY,
    ),
    "key_blobs": Factor(
        "3-6 opaque textured ellipses on the lane marks, in the key frame alone (never in training)",
        REVEAL_MOTION | {"key_occluder": "blobs"},
        _REVEAL_GEOMETRY,
    ),
    "key_flash": Factor(
        "the key frame alone overexposed under a bright veil, as the training glare corruption (positive control)",
        REVEAL_MOTION | {"key_occluder": "flash"},
        _REVEAL_GEOMETRY,
    ),
}
"""The kinds of the ``reveal`` split (clip ``i`` has kind ``i % 3``): 12 frames at 20 fps, the key frame last, a
transient occluder in the key frame alone (`stamlane.synth.transient`), the history frames clean."""
REVEAL_TRAFFIC: dict[str, Factor] = {
    "oncoming_close": Factor(
        "4-8 vehicles (half of them trucks) 3-20 m ahead driving towards the camera, frames at 5 fps",
        _TRAFFIC
        | {"vehicle_speed": (-1.1, -0.9), "vehicle_ahead": (3.0, 20.0), "truck_prob": 0.5}
        | {"fps": 5.0, "num_frames": REVEAL_FRAMES},
        "a close oncoming vehicle sweeps over the road: 0.2-0.6 s earlier the road it hides now was open",
    ),
    "same_speed": Factor(
        "4-8 vehicles at the camera's speed, frames at 5 fps",
        _TRAFFIC | {"vehicle_speed": (0.9, 1.1)} | {"fps": 5.0, "num_frames": REVEAL_FRAMES},
        "the vehicle moves with the camera: the road it hides now lay in front of it 3-17 m (0.2-0.6 s) earlier",
    ),
}
"""The kinds of the ``reveal-traffic`` split (clip ``i`` has kind ``i % 2``): natural occluders only, at 5 fps so
that four frames span 0.6 s, where the labels give the history room to help (docs/results.md)."""
TRAIN_MOTION = Factor(
    "the reveal clips' ego motion (a lane change, drift, yaw jitter), 12 frames, no occluder",
    REVEAL_MOTION,
    "unaligned history misplaces the lanes: training for the reveal splits' motion (the recipe corrupts the key "
    "frames)",
)
"""The ``train_motion`` clips of the train split (after its factor clips, named ``motion`` in ``clip_factors``)."""


@dataclass(frozen=True)
class SynthConfig:
    """Settings of the generator; every field is a plain value so the config is saved with the data.

    Distances in metres, angles in degrees, speeds in m/s. The defaults make the CLEAN splits (train, val,
    test): light traffic (half the clips have 1-3 vehicles, 8-60 m ahead), so that a detector of the visible
    paint can score: on 150 such key frames, lanes fitted to the visible labelled points (and continued to the
    image's common far end) reach TuSimple F1 0.991, against 0.815 with the format-2 defaults (85 % of clips
    with 2-5 vehicles 4-35 m ahead; 43 % of the lanes more than 15 % hidden). Heavy traffic is the
    challenging split's (`challenging`).
    """

    width: int = 640
    height: int = 360
    num_frames: int = 20
    fps: float = 20.0
    hfov_deg: float = 60.0
    horizon: float = 0.42
    cam_height: float = 1.8
    speed: tuple[float, float] = (12.0, 28.0)
    lane_change_prob: float = 0.5
    drift_amplitude: float = 0.4
    yaw_jitter_deg: float = 0.5
    pitch_jitter_deg: float = 0.25
    curved_prob: float = 0.5
    max_kappa: float = 1 / 350
    occluder_prob: float = 0.5
    vehicles: tuple[int, int] = (1, 3)
    oncoming_prob: float = 0.6
    truck_prob: float = 0.2
    vehicle_lane_change_prob: float = 0.35
    vehicle_ahead: tuple[float, float] = (8.0, 60.0)
    """Distance (metres) of a vehicle's rear ahead of the camera at the key frame."""
    vehicle_speed: tuple[float, float] = (0.35, 1.25)
    """A vehicle's speed on the road as a multiple of the camera's (negative: towards it; 0: standing)."""
    static_shadows: tuple[int, int] = (0, 5)
    shadow_depth: float = 0.5
    moving_shadow_depth: float = 0.6
    worn_prob: float = 0.4
    worn_stretches: tuple[int, int] = (1, 3)
    """Worn stretches (5-30 m each) of a mark that is worn."""
    worn_strength: tuple[float, float] = (0.4, 0.9)
    """How much of the paint a worn stretch has lost (1: all)."""
    dash_gap: tuple[float, float] = (4.0, 8.0)
    """Metres between two dashes of a dashed mark (the dashes are 2-4 m)."""
    windscreen: bool = False
    """Dirt and drops on the windscreen and a sweeping wiper (camera-fixed occluders, ``effects``)."""
    glare_prob: float = 0.0
    """Chance of each frame to be spoilt by overexposure, a sun flare or motion blur (``effects.glare``)."""
    night: bool = False
    """Night: headlights light the near road, the rest is dark and noisy (``effects.night``)."""
    label_range: float = 80.0
    h_step: int = 10
    jpeg_quality: int = 92
    ppm: float = 0.0
    """Texture pixels per metre; 0 = ``16 * width / 640``."""
    grain: float = 0.12
    """Relative brightness amplitude of the fine asphalt grain near the camera (``render``); 0: none."""
    prefilter: bool = True
    """Average the texture along the road as far as one image row spans (no far-field aliasing)."""
    key_occluder: str = ""
    """A transient occluder of the last ``key_occluder_frames`` frames (`stamlane.synth.transient.KEY_OCCLUDERS`);
    "": none."""
    key_occluder_frames: int = 1
    """How many of the last frames carry ``key_occluder`` (1: the key frame alone)."""

    @classmethod
    def with_factor(cls, factor: str, **overrides: object) -> SynthConfig:
        """The clean settings (with ``overrides``) plus one challenging factor of `FACTORS`."""
        if factor not in FACTORS:
            raise ValueError(f"factor must be one of {tuple(FACTORS)}, got {factor!r}")
        return replace(cls(**overrides), **FACTORS[factor].overrides)

    def __post_init__(self) -> None:
        if self.width < 64 or self.height < 48:
            raise ValueError(f"frame size must be at least 64x48, got {self.width}x{self.height}")
        from stamlane.safety.budget import MAX_SYNTH_FRAMES, check_clip, check_rate

        # one clip is rendered in memory: its frames x height x width within the size budget
        check_clip(self.num_frames, (self.height, self.width), "synthetic", frames_limit=MAX_SYNTH_FRAMES)
        check_rate(self.fps, "synthetic fps")
        if not 0.0 <= self.glare_prob <= 1.0:
            raise ValueError(f"glare_prob must be in [0, 1], got {self.glare_prob}")
        if self.key_occluder and self.key_occluder not in KEY_OCCLUDERS:
            raise ValueError(f"key_occluder must be one of {KEY_OCCLUDERS} or empty, got {self.key_occluder!r}")
        if not 1 <= self.key_occluder_frames <= self.num_frames:
            raise ValueError(f"key_occluder_frames must be in [1, num_frames], got {self.key_occluder_frames}")

    @property
    def texture_ppm(self) -> float:
        return self.ppm if self.ppm > 0 else 16.0 * self.width / 640.0

    def camera(self) -> Camera:
        return Camera.for_size(self.width, self.height, self.hfov_deg, self.horizon)

    def h_samples(self) -> list[int]:
        """Label rows (TuSimple ``h_samples``): every ``h_step`` px from just below the labelled range's end."""
        cam = self.camera()
        top = cam.cy + cam.focal * self.cam_height / self.label_range
        start = int(np.ceil(top / self.h_step) * self.h_step)
        return list(range(start, self.height, self.h_step))


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
        return h / h[2, 2]


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


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
    """TuSimple lanes (x per h_sample, -2 = absent) of every mark visible in a frame, left to right."""
    rows = np.asarray(h_samples, dtype=np.float64)
    z = pose.z + np.arange(1.0, cfg.label_range, 0.25)
    lanes = []
    for mark in road.marks:
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


def generate_clip(cfg: SynthConfig, rng: np.random.Generator, *, paint_contrast: bool = False) -> SynthClip:
    """Render one clip.

    Args:
        cfg: generator settings.
        rng: random generator; the clip is a deterministic function of its state.
        paint_contrast: also render every frame without the lane paint (from a copy of ``rng``, so the frames
            are the same with or without it) and keep the difference, ``SynthClip.paint_contrast``: where the
            paint is visible (`stamlane.synth.visibility`). About doubles the rendering time.

    Returns:
        the clip with labels of every frame and the true ``image_from_ground`` of every frame.
    """
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
    )
    poses, track = _ego_poses(cfg, rng, road, ego_lane)
    n_shadows = int(rng.integers(cfg.static_shadows[0], cfg.static_shadows[1] + 1))
    # the unpainted texture is a by-product of the same draws: the painted one is what it always was
    textures = render_texture(road, rng, shadows=n_shadows, shadow_depth=cfg.shadow_depth, unpainted=paint_contrast)
    texture, bare = textures if paint_contrast else (textures, None)
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
    sky, ridge = _sky(cfg, rng)
    haze = tuple(float(c) for c in sky[-1, 0])
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
        _draw_ridge(frame, ridge, horizon, pose, camera)
        if vehicles:
            shade = np.zeros((cfg.height, cfg.width), np.uint8)
            for v in vehicles:
                for poly in shadow_polygons(v, road, t):
                    pix = camera.project_polygon(pose, poly)
                    if pix is not None:
                        cv2.fillPoly(shade, [np.round(pix * 16).astype(np.int32)], 255, lineType=cv2.LINE_AA, shift=4)
            shade = cv2.blur(shade, (5, 5))
            factor = 1.0 - cfg.moving_shadow_depth * shade.astype(np.float32) / 255.0
            frame = (frame * factor[..., None]).astype(np.uint8)
        mask = np.zeros((cfg.height, cfg.width), np.uint8)
        draw_vehicles(frame, mask, vehicles, road, camera, pose, t)
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
        return cv2.convertScaleAbs(frame, alpha=float(gains[i])), mask

    frames, labels, occluded, homs, masks = [], [], [], [], []
    for i, pose in enumerate(poses):
        img_from_ground = camera.image_from_ground(pose)
        frame, mask = render_frame(i, renderer, rng)
        lanes = _lane_labels(cfg, camera, road, pose, img_from_ground, h_samples)
        occ = [[bool(x >= 0 and mask[y, x] > 0) for x, y in zip(lane, h_samples)] for lane in lanes]
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
    return SynthClip(frames, labels, occluded, h_samples, homs, masks, contrast)


def _haze(frame: np.ndarray, first_row: int, colour: tuple[float, ...]) -> None:
    """Fade the ground into ``colour`` over a band under the horizon (hides where the texture ends)."""
    band = max(2, int(HAZE_PX * frame.shape[0]))
    rows = frame[first_row : first_row + band].astype(np.float32)
    a = np.linspace(1.0, 0.0, band, dtype=np.float32)[: len(rows), None, None]
    frame[first_row : first_row + band] = (rows * (1 - a) + np.asarray(colour, np.float32) * a).astype(np.uint8)


def _draw_ridge(frame: np.ndarray, ridge: np.ndarray, horizon: float, pose: Pose, camera: Camera) -> None:
    """A dark tree line just above the horizon, shifting with yaw (not part of the ground plane)."""
    height = frame.shape[0]
    shift = round(camera.focal * float(pose.yaw)) % len(ridge)
    tops = horizon - (2 + 0.04 * height * np.roll(ridge, -shift))
    first = int(np.clip(np.floor(tops.min()), 0, height))
    last = int(np.clip(np.floor(horizon) + 1, first, height))
    if last <= first:
        return
    rows = np.arange(first, last, dtype=np.float64)[:, None]
    sel = (rows >= tops[None, :]) & (rows <= horizon)
    band = frame[first:last]
    band[sel] = (band[sel] * 0.35).astype(np.uint8)


def key_frames(num_frames: int, key_step: int = 0) -> list[int]:
    """0-based indices of a clip's labelled key frames, oldest first.

    Args:
        num_frames: frames in the clip.
        key_step: 0: the last frame only; k >= 1: the last frame and every k-th frame before it, not before
            ``FIRST_KEY`` (a clip of at most ``FIRST_KEY + 1`` frames has only its last frame as key).
    """
    if key_step < 0:
        raise ValueError(f"key_step must be >= 0, got {key_step}")
    last = num_frames - 1
    if key_step == 0:
        return [last]
    return list(range(last, min(FIRST_KEY, last) - 1, -key_step))[::-1]


def write_clip(clip: SynthClip, root: Path, clip_id: str, jpeg_quality: int = 92, key_step: int = 0) -> list[dict]:
    """Write a clip's frames, per-frame labels and homographies under ``root``.

    Returns:
        the TuSimple label records (``raw_file``, ``lanes``, ``h_samples``) of the clip's key frames
        (`key_frames` with ``key_step``), oldest first.
    """
    folder = root / "clips" / clip_id
    folder.mkdir(parents=True, exist_ok=True)
    names = [f"{i + 1}.jpg" for i in range(len(clip.frames))]
    for name, frame in zip(names, clip.frames):
        ok, buf = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
        if not ok:
            raise OSError(f"could not encode {folder / name}")
        (folder / name).write_bytes(buf.tobytes())
    raw = [f"clips/{clip_id}/{name}" for name in names]
    per_frame = [
        {"raw_file": r, "lanes": lanes, "h_samples": clip.h_samples, "occluded": occ}
        for r, lanes, occ in zip(raw, clip.labels, clip.occluded)
    ]
    (root / "frame_labels").mkdir(exist_ok=True)
    (root / "frame_labels" / f"{clip_id}.json").write_text(json.dumps(per_frame))
    last = len(clip.frames) - 1
    geometry = {
        "frames": names,
        "image_from_ground": [h.tolist() for h in clip.image_from_ground],
        "last_from_frame": [clip.key_from_hist(last, j).tolist() for j in range(len(names))],
        "next_from_frame": [clip.key_from_hist(j + 1, j).tolist() for j in range(len(names) - 1)],
    }
    (root / "homographies").mkdir(exist_ok=True)
    (root / "homographies" / f"{clip_id}.json").write_text(json.dumps(geometry))
    return [
        {"raw_file": raw[k], "lanes": clip.labels[k], "h_samples": clip.h_samples}
        for k in key_frames(len(names), key_step)
    ]


def clip_statistics(clip: SynthClip, num_frames: int = 4, stride: int = 1) -> dict[str, float]:
    """What a clip offers the fusion of its last ``num_frames`` frames.

    Returns:
        ``key_points``: labelled key-frame points; ``hidden``: of those hidden by a vehicle;
        ``revealed``: hidden ones visible in at least one ground-aligned history frame;
        ``unaligned_shift``: mean |x| difference (px) of a lane point between the oldest history frame
        and the key frame without alignment (what pre-alignment repairs).
    """
    key = len(clip.frames) - 1
    hist = [key - stride * k for k in range(1, num_frames) if key - stride * k >= 0]
    h, w = clip.vehicle_masks[key].shape
    hidden = revealed = points = 0
    for lane, occ in zip(clip.labels[key], clip.occluded[key]):
        for x, y, o in zip(lane, clip.h_samples, occ):
            if x < 0:
                continue
            points += 1
            if not o:
                continue
            hidden += 1
            for j in hist:
                p = np.linalg.inv(clip.key_from_hist(key, j)) @ np.array([x, y, 1.0])
                u, v = p[:2] / p[2]
                if 0 <= u < w and 0 <= v < h and clip.vehicle_masks[j][int(v), int(u)] == 0:
                    revealed += 1
                    break
    shift, count = 0.0, 0
    if hist:
        old = hist[-1]
        for lk in clip.labels[key]:
            best = None
            for lo in clip.labels[old]:
                both = [(a, b) for a, b in zip(lk, lo) if a >= 0 and b >= 0]
                if both:
                    d = float(np.mean([abs(a - b) for a, b in both]))
                    best = d if best is None else min(best, d)
            if best is not None:
                shift += best
                count += 1
    return {"key_points": points, "hidden": hidden, "revealed": revealed, "unaligned_shift": shift / max(count, 1)}


def challenging_factor(index: int) -> str:
    """The factor (`FACTORS`) of clip ``index`` of the challenging split (and of the ``index``-th factor clip of the
    train and val splits)."""
    return list(FACTORS)[index % len(FACTORS)]


def key_frame_visibility(clip: SynthClip, key: int, reach: int = FIRST_KEY) -> list[list[int]]:
    """`stamlane.synth.visibility.paint_visibility` of key frame ``key`` (0-based) of a clip rendered with
    ``paint_contrast``, over the key frame and up to ``reach`` frames before it."""
    if clip.paint_contrast is None:
        raise ValueError("the clip was rendered without paint_contrast")
    back = range(min(reach, key) + 1)
    return paint_visibility(
        clip.labels[key],
        clip.h_samples,
        [clip.paint_contrast[key - j] for j in back],
        [clip.key_from_hist(key, key - j) for j in back],
    )


def write_temporal_labels(root: Path, challenging: int) -> Path | None:
    """Write `TEMPORAL_LABELS`: every frame from the ``FIRST_KEY + 1``-th of the challenging clips ``0 ..
    TEMPORAL_CLIPS_PER_FACTOR * len(FACTORS) - 1`` (as many of each factor), from their ``frame_labels``; None (and
    no file) for a set without challenging clips or with clips of fewer than ``FIRST_KEY + 2`` frames."""
    clips = min(challenging, TEMPORAL_CLIPS_PER_FACTOR * len(FACTORS))
    if clips == 0:
        return None
    records = []
    for i in range(clips):
        frames = json.loads((Path(root) / "frame_labels" / f"challenging-{i:04d}.json").read_text())
        records += [{k: f[k] for k in ("raw_file", "lanes", "h_samples")} for f in frames[FIRST_KEY:]]
    if len(records) < 2 * clips:  # clips too short for two frames with a full history each: nothing to follow
        return None
    path = Path(root) / TEMPORAL_LABELS
    path.write_text(_json_lines(records))
    return path


def _json_lines(records: list[dict]) -> str:
    return "".join(json.dumps(r) + "\n" for r in records)


@dataclass(frozen=True)
class _ClipJob:
    """What a worker of `generate_dataset` renders: clip ``index`` of ``split`` with ``config``."""

    root: Path
    split: str
    config: SynthConfig
    seed: int
    code: int
    index: int
    key_step: int
    visibility: bool
    reach: int = FIRST_KEY
    """History frames the visibility masks look back over (`key_frame_visibility`)."""


def _make_clip(job: _ClipJob) -> tuple[list[dict], dict[str, float], list[dict]]:
    """Render and write one clip (a worker of `generate_dataset`): its key-frame records, `clip_statistics` and,
    when asked, the visibility records of its key frames (`key_frame_visibility`)."""
    cv2.setNumThreads(1)  # the pool already runs one clip per core
    clip = generate_clip(
        job.config, np.random.default_rng([job.seed, job.code, job.index]), paint_contrast=job.visibility
    )
    records = write_clip(clip, job.root, f"{job.split}-{job.index:04d}", job.config.jpeg_quality, job.key_step)
    visibility = []
    if job.visibility:
        keys = key_frames(len(clip.frames), job.key_step)
        visibility = [
            {"raw_file": r["raw_file"], "visibility": key_frame_visibility(clip, k, job.reach)}
            for r, k in zip(records, keys)
        ]
    return records, clip_statistics(clip), visibility


def _visibility_shares(records: list[dict], num_frames: int = 4) -> dict[str, float]:
    """The share of labelled key-frame points in each visibility class for ``num_frames`` frames at stride 1."""
    counts = dict.fromkeys(VISIBILITY_CLASSES, 0)
    for record in records:
        for lane in record["visibility"]:
            for mask in lane:
                cls = visibility_class(mask, num_frames)
                if cls is not None:
                    counts[cls] += 1
    total = max(sum(counts.values()), 1)
    return {f"{cls}_fraction": n / total for cls, n in counts.items()}


def clip_kinds(split: str, index: int, clean: int) -> tuple[str, Factor] | None:
    """The named factor or kind of clip ``index`` of ``split`` (None for a clean clip), given the split's ``clean``
    clips before its factor clips: the challenging split's `FACTORS`; the train and val splits' factor clips after
    their clean ones, and the train split's `TRAIN_MOTION` clips after its ``len(FACTORS)``-cycled factor clips
    (``index - clean`` beyond ``factors``: see `generate_dataset`); the reveal splits' kinds, cycled."""
    cycles = {"challenging": FACTORS, "reveal": REVEAL, "reveal-traffic": REVEAL_TRAFFIC}
    if split in cycles:
        kinds = cycles[split]
        name = list(kinds)[index % len(kinds)]
        return name, kinds[name]
    if index < clean:
        return None
    name = challenging_factor(index - clean)
    return name, FACTORS[name]


def generate_dataset(
    root: str | Path,
    *,
    train: int = 80,
    val: int = 10,
    test: int = 10,
    challenging: int = 10,
    train_factors: int = 0,
    val_factors: int = 0,
    reveal: int = 0,
    reveal_traffic: int = 0,
    train_motion: int = 0,
    seed: int = 0,
    config: SynthConfig | None = None,
    progress: bool = True,
    train_key_step: int = TRAIN_KEY_STEP,
    eval_key_step: int = EVAL_KEY_STEP,
    workers: int = 1,
    visibility: bool = True,
) -> dict:
    """Write a synthetic clip set (layout in the module docstring).

    Args:
        root: output folder (created; existing clips of the same ids are overwritten).
        train, val, test: clips per split with the normal settings.
        challenging: clips of the challenging split: clip ``i`` has the factor ``challenging_factor(i)`` on top
            of ``config`` (`FACTORS`); each factor's key frames also go to ``challenging-<factor>.json``.
        train_factors, val_factors: clips with a challenging factor added to the train and val splits after
            their clean clips (ids ``train-<train + i>``: factor ``challenging_factor(i)``), so that training has
            a reason to read the history; they come from their own seeds (their split and index), never the
            test or challenging clips', and leave the clean clips as they were. With them, ``train-clean.json``
            / ``val-clean.json`` list the clean clips' key frames alone.
        reveal, reveal_traffic: clips of the ``reveal`` and ``reveal-traffic`` splits (`REVEAL`,
            `REVEAL_TRAFFIC`, kinds cycled; the key frame alone labelled; visibility over every history frame).
        train_motion: `TRAIN_MOTION` clips added to the train split after its factor clips (the reveal splits'
            ego motion, key frames as ``train_key_step``), named ``motion`` in ``clip_factors``.
        seed: master seed; clip ``i`` of a split depends only on ``(seed, split, i)``.
        config: settings of the normal splits (default ``SynthConfig()``); every factor and kind overrides it.
        progress: show a tqdm progress bar.
        train_key_step: key frames of the train clips (`key_frames`: 0 = the last frame only, 1 = every frame
            from ``FIRST_KEY`` on).
        eval_key_step: key frames of the val, test and challenging clips (e.g. 3: frames 8, 11, 14, 17, 20 of
            20-frame clips, five fairly different views of each clip).
        workers: processes rendering clips in parallel (the files do not depend on it).
        visibility: write ``visibility/<split>.json`` for every split but train: for every labelled key-frame
            point, where its paint is visible (`key_frame_visibility`).

    Returns:
        the content of ``dataset.json``: settings, counts, key frames and statistics per split.
    """
    root = Path(root)
    cfg = config or SynthConfig()
    counts = {
        "train": train,
        "val": val,
        "test": test,
        "challenging": challenging,
        "reveal": reveal,
        "reveal-traffic": reveal_traffic,
    }
    extra = {"train": train_factors + train_motion, "val": val_factors}
    named = {"train_factors": train_factors, "val_factors": val_factors, "train_motion": train_motion}
    for name, n in (counts | named).items():
        if n < 0:
            raise ValueError(f"clip count of split {name!r} must be >= 0, got {n}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    steps = {split: train_key_step if split == "train" else eval_key_step for split in SPLITS}
    steps |= {"reveal": 0, "reveal-traffic": 0}
    keys = {split: key_frames(cfg.num_frames, steps[split]) for split in SPLITS}  # checks the steps
    reach_of = {split: REVEAL_FRAMES - 1 if split in ("reveal", "reveal-traffic") else FIRST_KEY for split in SPLITS}
    root.mkdir(parents=True, exist_ok=True)
    stats: dict[str, dict[str, float]] = {}
    clip_factors: dict[str, str] = {}
    by_kind: dict[tuple[str, str], list[dict]] = {}
    total = sum(counts.values()) + sum(extra.values())
    bar = tqdm(total=total, desc=f"synthetic clips -> {root}", unit="clip", disable=not progress)
    pool = ProcessPoolExecutor(workers) if workers > 1 else None
    try:
        for code, split in enumerate(SPLITS):
            jobs, kinds = [], []
            for i in range(counts[split] + extra.get(split, 0)):
                kind = clip_kinds(split, i, counts[split])
                if split == "train" and i >= train + train_factors:
                    kind = ("motion", TRAIN_MOTION)
                split_cfg = cfg if kind is None else replace(cfg, **kind[1].overrides)
                if kind is not None:
                    clip_factors[f"{split}-{i:04d}"] = kind[0]
                kinds.append(None if kind is None else kind[0])
                see = visibility and split != "train"
                jobs.append(_ClipJob(root, split, split_cfg, seed, code, i, steps[split], see, reach_of[split]))
            records: list[dict] = []
            seen: list[dict] = []
            totals = {"key_points": 0, "hidden": 0, "revealed": 0, "unaligned_shift": 0.0}
            for kind, (clip_records, clip_stats, clip_seen) in zip(
                kinds, pool.map(_make_clip, jobs) if pool else map(_make_clip, jobs)
            ):
                records += clip_records
                seen += clip_seen
                if split in KIND_SPLITS and kind is not None:
                    by_kind.setdefault((split, kind), []).extend(clip_records)
                for k, v in clip_stats.items():
                    totals[k] += v
                bar.update(1)
            if records or split not in ("reveal", "reveal-traffic"):  # a set without them: no empty label files
                (root / f"{split}.json").write_text(_json_lines(records))
            if extra.get(split):  # the clean clips alone too: the set as it was before factor clips
                clean = [r for r in records if r["raw_file"].split("/")[1] not in clip_factors]
                (root / f"{split}-clean.json").write_text(_json_lines(clean))
            n = max(len(jobs), 1)
            stats[split] = {
                "clips": len(jobs),
                "key_frames": len(records),
                "hidden_fraction": totals["hidden"] / max(totals["key_points"], 1),
                "revealed_fraction_of_hidden": totals["revealed"] / max(totals["hidden"], 1),
                "unaligned_shift_px": totals["unaligned_shift"] / n,
            }
            if seen:
                (root / VISIBILITY_DIR).mkdir(exist_ok=True)
                (root / VISIBILITY_DIR / f"{split}.json").write_text(_json_lines(seen))
                stats[split]["paint_visibility_4_frames"] = _visibility_shares(seen)
        for split in KIND_SPLITS:  # every factor of the challenging split has its file, even an empty one
            for name in {"challenging": FACTORS, "reveal": REVEAL, "reveal-traffic": REVEAL_TRAFFIC}[split]:
                if split == "challenging" or counts[split]:
                    (root / f"{split}-{name}.json").write_text(_json_lines(by_kind.get((split, name), [])))
        write_temporal_labels(root, challenging)
    finally:
        if pool:
            pool.shutdown()
        bar.close()
    info = {
        "generator": "stamlane.synth.generator",
        "format_version": FORMAT_VERSION,
        "seed": seed,
        "config": asdict(cfg),
        "factors": {name: asdict(factor) for name, factor in FACTORS.items()},
        "reveal_kinds": {name: asdict(kind) for name, kind in (REVEAL | REVEAL_TRAFFIC).items()},
        "clip_factors": clip_factors,
        "visibility_reach": {split: reach_of[split] for split in SPLITS if split != "train" and visibility},
        "splits": {name.replace("-", "_"): n for name, n in counts.items()} | named,
        "key_frames": {split: [k + 1 for k in keys[split]] for split in SPLITS[:4]}
        | {split: [REVEAL_FRAMES] for split in ("reveal", "reveal-traffic") if counts[split]},
        "statistics": stats,
    }
    (root / "dataset.json").write_text(json.dumps(info, indent=2))
    return info
