"""The generator's settings: `SynthConfig`, and the challenging factors and reveal kinds that override it.

Plain values only (a config is saved with the data in ``dataset.json``); numpy and the standard library, no OpenCV
and no renderer, so ``stamlane.data`` and ``stamlane.experiments`` import the settings and the factor tables
without loading what draws a clip (``tests/synth/test_layout.py``). Which clip of a split has which factor or kind
is `clip_kinds`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from stamlane.synth.layout import REVEAL_FRAMES, SplitCounts
from stamlane.synth.worlds import WORLDS

if TYPE_CHECKING:
    from stamlane.align.camera import Camera

__all__ = [
    "FACTORS",
    "KEY_OCCLUDERS",
    "LABEL_LANES",
    "REVEAL",
    "REVEAL_MOTION",
    "REVEAL_TRAFFIC",
    "TRAIN_MOTION",
    "Factor",
    "SynthConfig",
    "challenging_factor",
    "clip_kinds",
    "counts_of_total",
]

LABEL_LANES = ("all", "adjacent")
"""Which lane marks a frame's labels hold (``SynthConfig.label_lanes``): "all", every mark of the road in view (the
set as every format has made it); "adjacent", TuSimple's convention, the marks of the ego lane and of the lanes beside
it: those within two lane widths of the camera, four on a lane's centre (`ADJACENT_LANE_WIDTHS`)."""
ADJACENT_LANE_WIDTHS = 2.0
"""``label_lanes="adjacent"`` labels a mark when it lies less than this many lane widths beside the camera, level
with it: the ego lane's two marks and the outer marks of the lanes to either side (at ±0.5 and ±1.5 widths from a
lane's centre), never the marks of the lanes beyond them (±2.5)."""
KEY_OCCLUDERS = ("spray", "blobs", "flash")
"""The kinds of transient occluder of the last frames (``SynthConfig.key_occluder``; drawn by
`stamlane.synth.transient.KeyOccluder`)."""


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
    """A transient occluder of the last ``key_occluder_frames`` frames (`KEY_OCCLUDERS`);
    "": none."""
    key_occluder_frames: int = 1
    """How many of the last frames carry ``key_occluder`` (1: the key frame alone)."""
    world: str = "classic"
    """What the clips show, a name of `stamlane.synth.worlds.WORLDS` (each world a choice of scene parts): "classic", the world of formats 1-6 (a camera with its horizon at
    ``horizon``, 2-4 m dashes, box vehicles); "dashcam" (format 7, `stamlane.synth.dashcam`): per clip a camera
    spread over dashcam ranges (its horizon, field of view and height replace ``horizon``, ``hfov_deg`` and
    ``cam_height``), the dash and gap lengths of a marking standard with raised pavement markers, concrete or asphalt
    with joints, seams and a shoulder of another shade, concrete barriers and guard rails, clear or overcast skies,
    sensor effects (blur, noise, exposure, vignetting, JPEG); "dashcam2" (`stamlane.synth.scenery`): the dashcam world
    plus a sun whose direction and height cast every shadow (vehicles, barrier, rail, poles), curbs, poles, long
    repair strips, sealed joints and cracks, and vehicles with wheels, body, cabin, glass and lights; "dashcam3": the
    dashcam2 world with the ground beyond each shoulder drawn as green grass, dirt, dry grass or gravel (most of them
    brighter than the asphalt, with a long ragged edge: `stamlane.synth.scenery.Verge`)."""
    randomise: bool = False
    """Domain randomisation in the dashcam worlds: a random colour cast per clip."""
    label_lanes: str = "all"
    """Which marks the labels hold (`LABEL_LANES`): "all" of them, or the "adjacent" ones of TuSimple's convention
    (the real frames of docs/results/real-roads/ label four marks of a highway with more). The frames do not depend
    on it."""

    @classmethod
    def with_factor(cls, factor: str, **overrides: object) -> SynthConfig:
        """The clean settings (with ``overrides``) plus one challenging factor of `FACTORS`."""
        if factor not in FACTORS:
            raise ValueError(f"factor must be one of {tuple(FACTORS)}, got {factor!r}")
        return cls().overridden(overrides).overridden(FACTORS[factor].overrides)

    def overridden(self, overrides: Mapping[str, object]) -> SynthConfig:
        """These settings with ``overrides`` (field name -> value, as `Factor.overrides`): an unknown name raises
        TypeError, a bad value `__post_init__`'s ValueError."""
        # one mapping holds values of several fields' types, which no static type pairs with their names
        return replace(self, **cast("dict[str, Any]", overrides))

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
        if self.world not in WORLDS:
            raise ValueError(f"world must be one of {tuple(WORLDS)}, got {self.world!r}")
        if self.label_lanes not in LABEL_LANES:
            raise ValueError(f"label_lanes must be one of {LABEL_LANES}, got {self.label_lanes!r}")
        if self.randomise and not WORLDS[self.world].randomisable:
            names = ", ".join(repr(name) for name, world in WORLDS.items() if world.randomisable)
            raise ValueError(
                f"randomise is an option of the worlds with the dashcam sensor: set world to one of {names}"
            )
        if not 1 <= self.key_occluder_frames <= self.num_frames:
            raise ValueError(f"key_occluder_frames must be in [1, num_frames], got {self.key_occluder_frames}")

    @property
    def texture_ppm(self) -> float:
        return self.ppm if self.ppm > 0 else 16.0 * self.width / 640.0

    def camera(self) -> Camera:
        """The pinhole camera of the frames."""
        from stamlane.align.camera import Camera  # here: the package stamlane.align loads OpenCV, the settings do not

        return Camera.for_size(self.width, self.height, self.hfov_deg, self.horizon)

    def h_samples(self) -> list[int]:
        """Label rows (TuSimple ``h_samples``): every ``h_step`` px from just below the labelled range's end."""
        cam = self.camera()
        top = cam.cy + cam.focal * self.cam_height / self.label_range
        start = int(np.ceil(top / self.h_step) * self.h_step)
        return list(range(start, self.height, self.h_step))


def challenging_factor(index: int) -> str:
    """The factor (`FACTORS`) of clip ``index`` of the challenging split (and of the ``index``-th factor clip of the
    train and val splits)."""
    return list(FACTORS)[index % len(FACTORS)]


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


def counts_of_total(
    clips: int,
    *,
    challenging: int | None = None,
    reveal: int | None = None,
    reveal_traffic: int | None = None,
    train_factors: int = 0,
    val_factors: int = 0,
    train_motion: int = 0,
) -> SplitCounts:
    """``stamlane synth --clips N``'s rule: train+val+test = ``clips`` (10 % each for val and test, >= 1 when
    ``clips`` >= 3); by default ``clips // 10`` challenging clips but at least one per factor (`FACTORS`), 3 reveal
    and 2 reveal-traffic clips per 10 (at least 3 and 2).

    >>> counts_of_total(10).as_dict()["train"], counts_of_total(2).val, counts_of_total(10).challenging
    (8, 0, 8)
    """
    val = test = 0 if clips < 3 else max(1, round(clips * 0.1))
    tenths = max(1, clips // 10)
    return SplitCounts(
        train=clips - val - test,
        val=val,
        test=test,
        challenging=max(clips // 10, len(FACTORS)) if challenging is None else challenging,
        reveal=3 * tenths if reveal is None else reveal,
        reveal_traffic=2 * tenths if reveal_traffic is None else reveal_traffic,
        train_factors=train_factors,
        val_factors=val_factors,
        train_motion=train_motion,
    )
