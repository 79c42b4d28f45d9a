"""The parts of the dashcam world (``SynthConfig(world="dashcam")``, generator format 7): what the real-road check asked for.

`benchmarks/real_roads.py` ran the models trained on the classic world on a real highway video and six labelled real
frames (docs/results/real-roads/). What went wrong, and what this world draws for it, per clip:

- **the lanes ran on above the vanishing point** (the classic camera always has its horizon at 42 % of the frame, a
  real dashcam's sat at 38 % and 56 %): the ``dashcam`` camera spreads it over dashcam ranges (`HORIZON`,
  `HFOV_DEG`, `CAM_HEIGHT_M`), so the network sees sky, roadside and far road at every height;
- **lanes came and went with the dashes** (one US dash cycle, a 3 m line and a 9 m gap, lost the dashed line while
  no dash was near): `MARKINGS`, the dash and gap lengths and widths of common standards, and raised pavement
  markers (Botts' dots) in the gaps or instead of the paint (`Marking`);
- **lines followed the foot of a concrete barrier and ran across the left lanes**: `Roadside` stands concrete
  barriers and guard rails beside the road (3-D, drawn per frame), and `Surface` paints what a detector mistakes for
  paint on the ground: concrete slabs with transverse and longitudinal joints, tar-sealed cracks, a shoulder of
  another shade with its seam, darker wheel paths;
- **sunny and overcast skies** (`Sky`), **sensor effects** (`Sensor`: defocus blur, noise, exposure and gamma, vignetting, the
  camera's own JPEG compression) and, with ``SynthConfig.randomise``, random colour casts (domain randomisation).

Each is a variant of a scene part (`stamlane.synth.worlds`; `stamlane.synth.parts` draws them): it draws from the
clip's generator only in a world that picks it, so the classic world's clips stay as they were, byte for byte
(``tests/synth/test_splits_frozen.py``).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import cv2
import numpy as np

from stamlane.align.camera import Camera, Pose

__all__ = [
    "CAM_HEIGHT_M",
    "HFOV_DEG",
    "HORIZON",
    "MARKINGS",
    "Marking",
    "MarkingStandard",
    "Roadside",
    "Sensor",
    "Sky",
    "Surface",
    "fill_world_polygon",
    "fill_world_quad",
]

HORIZON = (0.34, 0.62)
"""Range of the horizon row as a fraction of the frame height: the labelled real frames ~0.38 (TuSimple's camera),
the real video ~0.56; dashcams pitched up or down a few degrees fill the range."""
HFOV_DEG = (45.0, 75.0)
"""Range of the horizontal field of view (degrees): TuSimple-like 1280x720 highway cameras ~50-60, wide dashcams more
(before the lens distortion this world does not draw)."""
CAM_HEIGHT_M = (1.2, 1.9)
"""Range of the camera height above the road (metres): a dashcam behind a car's windscreen to an SUV's or a van's."""


@dataclass(frozen=True)
class MarkingStandard:
    """Dash and gap lengths (metres) and line widths of a marking standard; ``dots_prob``: chance that a dashed mark
    has raised pavement markers (Botts' dots) in its gaps, ``dots_only_prob``: instead of its paint."""

    name: str
    dash: float
    gap: float
    width: tuple[float, float]
    dots_prob: float = 0.0
    dots_only_prob: float = 0.0


MARKINGS = (
    MarkingStandard("us", 3.05, 9.15, (0.10, 0.15), dots_prob=0.4, dots_only_prob=0.15),  # MUTCD: 10 ft / 30 ft, 4-6 in
    MarkingStandard("de_autobahn", 6.0, 12.0, (0.15, 0.30)),  # RMS Leitlinie on motorways: 6 m / 12 m
    MarkingStandard("de_road", 3.0, 6.0, (0.12, 0.15)),  # RMS Leitlinie on other roads: 3 m / 6 m
    MarkingStandard("uk_motorway", 2.0, 7.0, (0.10, 0.15)),  # TSRGD lane line: 2 m mark, 7 m gap
)
"""The marking standards a dashcam clip draws from (one per clip, every dashed mark of it; ±10 % on the lengths)."""
DOT_SPACING_M = 1.22
"""Metres between two raised pavement markers (California: 4 ft)."""
DOT_RADIUS_M = 0.06
"""Radius of a raised pavement marker (a 10-cm Botts' dot, a little larger for its bright rim)."""


@dataclass(frozen=True)
class Surface:
    """What the road surface adds to the classic asphalt, drawn into the top-down texture before the paint.

    Attributes:
        kind: ``"asphalt"`` or ``"concrete"`` (light slabs with joints).
        grey: the surface's mean grey level (concrete lighter than asphalt).
        slab: metres between transverse joints of concrete (0 for asphalt).
        joint_offset: metres from each lane mark to the longitudinal joint beside it (concrete), or of the paving seam
            beside the outer marks (asphalt).
        shoulder_shade: grey-level change of the shoulders beyond the outer marks (their seam is a straight edge).
        seams: tar-sealed cracks, ``(lateral metres from the centre, z0, length, wobble)`` each.
        wheel_paths: how much darker the wheel paths of each lane are (grey levels).
    """

    kind: str
    grey: float
    slab: float
    joint_offset: float
    shoulder_shade: float
    seams: list[tuple[float, float, float, float]] = field(default_factory=list)
    wheel_paths: float = 0.0

    @classmethod
    def sample(cls, rng: np.random.Generator, z_range: tuple[float, float], half_width: float) -> Surface:
        concrete = rng.random() < 0.4
        length = z_range[1] - z_range[0]
        seams = [
            (
                float(rng.uniform(-half_width, half_width)),
                float(rng.uniform(*z_range)),
                float(rng.uniform(10, 60)),
                float(rng.uniform(0.05, 0.4)),
            )
            for _ in range(int(rng.poisson(length / 40.0)))
        ]
        return cls(
            "concrete" if concrete else "asphalt",
            float(rng.uniform(135, 185) if concrete else rng.uniform(55, 115)),
            float(rng.uniform(4.5, 6.0)) if concrete else 0.0,
            float(rng.uniform(0.0, 0.5)),
            float(rng.choice([-1, 1]) * rng.uniform(8, 30)),
            seams,
            float(rng.uniform(0, 15)),
        )

    def draw(
        self, lum: np.ndarray, rel: np.ndarray, zs: np.ndarray, ppm: float, offsets: list[float], base: float
    ) -> np.ndarray:
        """The texture's grey plane with this surface.

        Args:
            lum: ``(h, w)`` float32 grey levels of the classic asphalt (texture rows along the road, far end first).
            rel: ``(h, w)`` texels from the road centre across the road (positive right).
            zs: ``(h,)`` metres along the road of each texture row.
            ppm: texels per metre.
            offsets: lateral metres of the lane marks from the road centre, left to right.
            base: the classic asphalt's mean grey level in ``lum``.
        """
        lum = lum + (self.grey - base)
        metres = rel / ppm
        left, right = min(offsets), max(offsets)
        shoulder = (metres < left - 0.2) | (metres > right + 0.2)
        lum = np.where(shoulder, lum + self.shoulder_shade, lum)
        line = max(1.0, 0.03 * ppm)  # half width of a joint or seam in texels
        for mark in (left, right):  # the paving seam beside the outer marks: a straight edge of contrast
            side = -1.0 if mark == left else 1.0
            lum = np.where(np.abs(metres - (mark + side * (0.2 + self.joint_offset))) * ppm < line, lum - 25, lum)
        if self.kind == "concrete":
            for mark in offsets[1:-1]:  # longitudinal joints beside the inner marks
                lum = np.where(np.abs(metres - (mark + self.joint_offset)) * ppm < line, lum - 30, lum)
            transverse = (np.mod(zs, self.slab) * ppm < 2 * line)[:, None]
            lum = np.where(transverse & ~shoulder, lum - 22, lum)
        for a, b in itertools.pairwise(offsets):  # wheel paths: two darker bands per lane
            centre = (a + b) / 2
            for path in (centre - 0.85, centre + 0.85):
                lum -= self.wheel_paths * np.exp(-(((metres - path) / 0.35) ** 2)).astype(np.float32)
        for x, z0, length, wobble in self.seams:  # tar-sealed cracks: dark, winding, along the road
            rows = (zs >= z0) & (zs <= z0 + length)
            if not rows.any():
                continue
            wave = x + wobble * np.sin(zs[rows] / max(length, 1.0) * 2 * np.pi * 2 + x)
            near = np.abs(metres[rows] - wave[:, None]) * ppm < 1.5 * line
            lum[rows] = np.where(near, lum[rows] * 0.45, lum[rows])
        return lum.astype(np.float32)


@dataclass(frozen=True)
class Roadside:
    """3-D things beside the road: a concrete barrier (``barrier``: lateral metres of its face from the road centre,
    None for none) and a guard rail (``rail``), with their colours."""

    barrier: float | None
    rail: float | None
    barrier_grey: float
    rail_grey: float

    @classmethod
    def sample(cls, rng: np.random.Generator, left: float, right: float) -> Roadside:
        """Draw a barrier and a rail (each 60 %) 0.8-3 m beyond the outer marks (``left``, ``right``: their lateral
        metres), the barrier on the left and the rail on the right, or (30 %) the other way round."""
        on_left, on_right = left - float(rng.uniform(0.8, 3.0)), right + float(rng.uniform(0.8, 3.0))
        swap = rng.random() < 0.3
        barrier = (on_right if swap else on_left) if rng.random() < 0.6 else None
        rail = (on_left if swap else on_right) if rng.random() < 0.6 else None
        return cls(barrier, rail, float(rng.uniform(140, 210)), float(rng.uniform(150, 215)))

    def draw(
        self,
        frame: np.ndarray,
        centre: object,
        camera: Camera,
        pose: Pose,
        far: float,
    ) -> None:
        """Draw the barrier and the rail into ``frame`` (BGR uint8, in place), far to near.

        Args:
            centre: the road centre's lateral position at distances ``z`` (``Road.centre``).
            far: metres ahead of the camera to draw to.
        """
        zs = pose.z + np.concatenate([np.arange(0.5, 20.0, 1.0), np.arange(20.0, far, 4.0)])[::-1]
        for z1, z0 in itertools.pairwise(zs):
            c0, c1 = float(centre(z0)), float(centre(z1))  # type: ignore[operator]
            if self.barrier is not None:
                x0, x1 = c0 + self.barrier, c1 + self.barrier
                side = 1.0 if self.barrier < 0 else -1.0  # the foot slopes towards the road
                foot = [(x0 + side * 0.25, 0.0), (x1 + side * 0.25, 0.0), (x1, 0.3), (x0, 0.3)]
                wall = [(x0, 0.3), (x1, 0.3), (x1, 0.85), (x0, 0.85)]
                g = self.barrier_grey
                fill_world_quad(frame, camera, pose, foot, (z0, z1, z1, z0), (g * 0.8, g * 0.82, g * 0.85))
                fill_world_quad(frame, camera, pose, wall, (z0, z1, z1, z0), (g * 0.92, g * 0.94, g * 0.95))
            if self.rail is not None:
                x0, x1 = c0 + self.rail, c1 + self.rail
                g = self.rail_grey
                fill_world_quad(
                    frame, camera, pose, [(x0, 0.45), (x1, 0.45), (x1, 0.78), (x0, 0.78)], (z0, z1, z1, z0), (g,) * 3
                )
                fill_world_quad(
                    frame,
                    camera,
                    pose,
                    [(x0, 0.58), (x1, 0.58), (x1, 0.64), (x0, 0.64)],
                    (z0, z1, z1, z0),
                    (g * 0.6,) * 3,
                )
                if int(z0 / 2.0) != int(z1 / 2.0):  # a post every 2 m
                    xp = x0 + (0.15 if self.rail > 0 else -0.15)
                    post = [(xp, 0.0), (xp, 0.0), (xp, 0.7), (xp, 0.7)]
                    fill_world_quad(frame, camera, pose, post, (z0, z0 + 0.15, z0 + 0.15, z0), (60, 60, 65))


def fill_world_polygon(
    frame: np.ndarray,
    camera: Camera,
    pose: Pose,
    world: np.ndarray,
    colour: tuple[float, ...],
    mask: np.ndarray | None = None,
) -> None:
    """Fill the world polygon ``world`` (N, 3) as the camera at ``pose`` sees it into ``frame`` (anti-aliased, 1/16 px),
    and 255 into ``mask`` when given; nothing when it does not project (behind the camera, or far off the image)."""
    poly = camera.project_polygon(pose, world)
    if poly is None or not np.isfinite(poly).all() or np.abs(poly).max() >= 1e5:
        return
    pts = np.round(poly * 16).astype(np.int32)
    cv2.fillPoly(frame, [pts], tuple(float(c) for c in colour), lineType=cv2.LINE_AA, shift=4)
    if mask is not None:
        cv2.fillPoly(mask, [pts], 255, shift=4)


@dataclass(frozen=True)
class Sensor:
    """What the camera does to every frame of a clip: defocus ``blur`` (Gaussian sigma, px at 640 wide), ``noise``
    (grey levels), ``gain`` and ``gamma`` (exposure), ``vignette`` (darkening of the corners), ``jpeg`` (the camera's
    own compression quality; 0: none) and ``cast`` (per-channel gains, BGR: a colour cast; ones without
    ``SynthConfig.randomise``)."""

    blur: float
    noise: float
    gain: float
    gamma: float
    vignette: float
    jpeg: int
    cast: tuple[float, float, float] = (1.0, 1.0, 1.0)

    @classmethod
    def sample(cls, rng: np.random.Generator, randomise: bool) -> Sensor:
        cast = (1.0, 1.0, 1.0)
        if randomise:
            blue, green, red = (float(c) for c in rng.uniform(0.8, 1.2, 3))
            cast = (blue, green, red)
        return cls(
            float(rng.uniform(0.0, 1.2)),
            float(rng.uniform(0.0, 5.0)),
            float(rng.uniform(0.8, 1.2)),
            float(rng.uniform(0.8, 1.25)),
            float(rng.uniform(0.0, 0.35)),
            int(rng.integers(30, 90)) if rng.random() < 0.7 else 0,
            cast,
        )

    def apply(self, frame: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The frame (BGR uint8 ``(H, W, 3)``) as this camera records it; draws the frame's noise from ``rng``."""
        h, w = frame.shape[:2]
        out: np.ndarray = frame.astype(np.float32)
        sigma = self.blur * w / 640.0
        if sigma > 0.3:
            out = cv2.GaussianBlur(out, (0, 0), sigma)
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        r2 = ((xx - w / 2) / (w / 2)) ** 2 + ((yy - h / 2) / (h / 2)) ** 2
        shade = (1.0 - self.vignette * np.clip(r2 / 2.0, 0, 1))[..., None] * np.asarray(self.cast, np.float32)
        out = 255.0 * np.clip(out * shade * self.gain / 255.0, 0, 1) ** (1.0 / self.gamma)
        out += rng.normal(0.0, self.noise, (h, w, 1)).astype(np.float32)
        out = np.clip(out, 0, 255).astype(np.uint8)
        if self.jpeg:
            _, data = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg])
            decoded = cv2.imdecode(data, cv2.IMREAD_COLOR)
            assert decoded is not None, "a JPEG cv2.imencode just wrote decodes"
            out = decoded
        return out


@dataclass(frozen=True)
class Marking:
    """The clip's marking standard (the ``standards`` markings, `stamlane.synth.parts`) with its dash and gap lengths
    drawn (±10 %): every dashed mark of the clip's road has them (`stamlane.synth.road.sample_road`)."""

    standard: MarkingStandard
    dash: float
    gap: float

    @classmethod
    def sample(cls, rng: np.random.Generator, standard: MarkingStandard) -> Marking:
        return cls(standard, standard.dash * float(rng.uniform(0.9, 1.1)), standard.gap * float(rng.uniform(0.9, 1.1)))

    def restyle(self, rng: np.random.Generator, dashed: bool) -> tuple[float, str]:
        """One mark's width (metres) and raised pavement markers (`stamlane.synth.road.LaneMark.dots`), drawn after
        the classic mark's draws."""
        width = float(rng.uniform(*self.standard.width))
        r = rng.random()
        if dashed and r < self.standard.dots_only_prob:
            return width, "only"
        if dashed and r < self.standard.dots_only_prob + self.standard.dots_prob:
            return width, "gaps"
        return width, ""


@dataclass(frozen=True)
class Sky:
    """The clip's sky and what lies at the horizon.

    Attributes:
        clear: a clear sky (the sun's shadows are deep, `stamlane.synth.scenery.Sun`), else overcast.
        hills: height of the tree line / hills above the horizon, as a fraction of the frame height.
        land_colour: BGR of the land beside the road beyond the texture's sides (dry grass to green); None: the
            classic world's, the sky's own colour at the horizon.
    """

    clear: bool = True
    hills: float = 0.04
    land_colour: tuple[float, float, float] | None = None

    @classmethod
    def sample(cls, rng: np.random.Generator) -> Sky:
        """A clear (50 %) or overcast sky and the hills' height; the land's colour comes later (`with_land`)."""
        return cls(bool(rng.random() < 0.5), float(rng.uniform(0.02, 0.12)))

    def with_land(self, rng: np.random.Generator) -> Sky:
        """This sky with the land's colour drawn (after the sensor's draws: the order of format 7)."""
        land = (float(rng.uniform(40, 90)), float(rng.uniform(80, 130)), float(rng.uniform(80, 150)))
        return Sky(self.clear, self.hills, land)

    def land(self, sky: tuple[float, ...]) -> tuple[float, ...]:
        """The colour of the land beyond the road texture's sides (BGR), given the sky's colour at the horizon: the
        clip's `land_colour` seen through a little haze (the sky's colour where it has none)."""
        if self.land_colour is None:
            return sky
        return tuple(0.75 * c + 0.25 * s for c, s in zip(self.land_colour, sky))

    def paint(self, rng: np.random.Generator, height: int, width: int) -> np.ndarray:
        """The clip's sky, BGR uint8 ``(height, width, 3)``: clear blue to a pale horizon, or overcast with clouds."""
        a = np.linspace(0, 1, height, dtype=np.float32)[:, None, None]
        if self.clear:
            top = np.array([210, 140, 70], np.float32) * float(rng.uniform(0.8, 1.1))
            bottom = np.array([235, 215, 195], np.float32) * float(rng.uniform(0.85, 1.05))
            sky = np.broadcast_to(top * (1 - a) + bottom * a, (height, width, 3)).copy()
        else:
            grey = float(rng.uniform(110, 200))
            # bilinear: the frozen sets' clouds (a third positional argument cv2.INTER_CUBIC was taken as dst)
            clouds = cv2.resize(
                rng.normal(0, 1, (6, 12)).astype(np.float32), (width, height), interpolation=cv2.INTER_LINEAR
            )
            sky = (grey + 18 * clouds + 20 * a[..., 0])[..., None] * np.array([1.02, 1.0, 0.97], np.float32)
        sky_bgr: np.ndarray = np.clip(sky, 0, 255).astype(np.uint8)
        return sky_bgr


def fill_world_quad(
    frame: np.ndarray,
    camera: Camera,
    pose: Pose,
    xy: list[tuple[float, float]],
    zs: tuple[float, ...],
    colour: tuple[float, ...],
    mask: np.ndarray | None = None,
) -> None:
    """Fill the world quad of lateral and height ``(x, y)`` metres at depths ``zs`` into ``frame`` (and 255 into
    ``mask``), as `fill_world_polygon`."""
    world = np.array([(x, y, z) for (x, y), z in zip(xy, zs)], np.float64)
    fill_world_polygon(frame, camera, pose, world, colour, mask)
