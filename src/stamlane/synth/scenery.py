"""The parts of the dashcam2 world (``SynthConfig(world="dashcam2")``): the dashcam world plus what a detector mistakes
for paint.

The real-road check (docs/results/real-roads/) found the models following a concrete barrier's foot and drawing lines
through cars. The dashcam world (format 7, `stamlane.synth.dashcam`) added barriers, guard rails, joints and seams;
this world keeps all of it and adds, per clip:

- **the sun** (`Sun`, the ``sun`` lights): a direction and height, so every shadow falls the same way: the vehicles' moving shadows,
  and static shadows on the road cast by the barrier, the guard rail and lamp or sign poles (long thin dark stripes
  across the lanes when the sun is low and to the side); weak, soft shadows under an overcast sky;
- **curbs and poles** (`Scenery`, the ``curbs_poles`` furniture): a raised curb (a vertical face and a light top, two long edges parallel to the
  lanes) on a side without a barrier, poles beside the road;
- **surface repairs** (`RepairedSurface`, the ``repaired`` surface): long strips of newer or older asphalt along a lane with straight edges,
  straight tar-sealed joints beside the marks, sealed transverse cracks: bright or dark lines the paint is not;
- **vehicles with bodies** (`stamlane.synth.bodies`: `BodyStyle`, `draw_bodies`; the ``bodies`` vehicles), drawn
  over all of it;

and the dashcam3 world's **verges** (`Verge`, the ``kinds`` verges). Each is a variant of a scene part
(`stamlane.synth.worlds`): it draws from the clip's generator only in a world that picks it, at its part's place in
the order (`stamlane.synth.parts`), so the classic world and the dashcam world of format 7 draw what they drew, byte
for byte (``tests/synth/test_scenery.py``).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from stamlane.align.camera import Camera, Pose
from stamlane.synth.dashcam import Roadside, Surface, fill_world_quad

__all__ = [
    "SUN_ELEVATION_DEG",
    "VERGE_CHANCES",
    "VERGE_KINDS",
    "RepairedSurface",
    "Scenery",
    "Sun",
    "Verge",
]

SUN_ELEVATION_DEG = (12.0, 60.0)
"""Range of the sun's height above the horizon (degrees): a low morning or evening sun casts shadows 4.7 times as
long as the object is high, a midday sun at mid latitudes about half as long."""
POLE_SPACING_M = (25.0, 80.0)
"""Metres between two poles (lamps, signs) on one side of the road."""


@dataclass(frozen=True)
class Sun:
    """Where the light comes from: ``azimuth`` (radians, 0 = straight ahead, positive to the right) and ``elevation``
    (radians) of the sun, and ``depth``: how much a shadow darkens the ground (0: none, overcast skies little)."""

    azimuth: float
    elevation: float
    depth: float

    @classmethod
    def sample(cls, rng: np.random.Generator, clear_sky: bool) -> Sun:
        return cls(
            float(rng.uniform(-np.pi, np.pi)),
            float(np.radians(rng.uniform(*SUN_ELEVATION_DEG))),
            float(rng.uniform(0.45, 0.7) if clear_sky else rng.uniform(0.08, 0.22)),
        )

    def displacement(self) -> np.ndarray:
        """Ground displacement ``(X, Z)`` of a shadow per metre of height: away from the sun, ``1 / tan(elevation)``
        long (`stamlane.synth.vehicles.shadow_polygons` takes it as ``sun``)."""
        shift: np.ndarray = -np.array([np.sin(self.azimuth), np.cos(self.azimuth)]) / np.tan(self.elevation)
        return shift

    def shadows(
        self,
        roadside: Roadside | None,
        poles: list[tuple[float, float, float]],
        centre: Callable[[np.ndarray], np.ndarray],
        z_range: tuple[float, float],
    ) -> list[np.ndarray]:
        """Ground polygons ``(N, 2)`` metres ``(X, Z)`` of the static shadows cast on the road by the barrier and the
        rail of ``roadside`` and by the ``poles`` (`Scenery.poles`), for `stamlane.synth.road.render_texture`'s
        ``cast`` (darkened by `depth`)."""
        d = self.displacement()
        polys = []
        zs = np.arange(z_range[0], z_range[1] + 10.0, 10.0)
        for z0, z1 in itertools.pairwise(zs):
            c0, c1 = float(centre(np.asarray(z0))), float(centre(np.asarray(z1)))
            bands = []
            if roadside is not None and roadside.barrier is not None:
                out = -0.6 if roadside.barrier < 0 else 0.6  # the barrier's thickness, away from the road
                bands.append((roadside.barrier, out, 0.0, 0.85))
            if roadside is not None and roadside.rail is not None:
                bands.append((roadside.rail, 0.0, 0.45, 0.78))
            for lateral, thick, low, high in bands:
                foot = np.array(
                    [[c0 + lateral, z0], [c1 + lateral, z1], [c1 + lateral + thick, z1], [c0 + lateral + thick, z0]]
                )
                hull = cv2.convexHull(np.concatenate([foot + low * d, foot + high * d]).astype(np.float32))[:, 0]
                polys.append(hull.astype(np.float64))
        for lateral, z, height in poles:
            x = float(centre(np.asarray(z))) + lateral
            side = np.array([d[1], -d[0]]) / max(float(np.hypot(*d)), 1e-6) * 0.12
            base = np.array([x, z])
            polys.append(np.array([base - side, base + side, base + side + height * d, base - side + height * d]))
        return polys


VERGE_KINDS = ("grass", "dirt", "dry grass", "gravel")
"""What lies beside the shoulder in the dashcam3 world, per side (chances `VERGE_CHANCES`): the classic green verge, or
bare ground brighter than the asphalt, whose long straight edge a detector draws as a lane (the real highway of
docs/results/real-roads/)."""
VERGE_CHANCES = (0.25, 0.3, 0.3, 0.15)
"""The chance of each of `VERGE_KINDS` on a side."""


@dataclass(frozen=True)
class Verge:
    """The ground beyond each shoulder (the dashcam3 world): per side a kind of `VERGE_KINDS`, its BGR colour, how far
    its edge wanders (metres) and the seed of its own texture, drawn once so that the clip's other draws stay where
    they were.

    Attributes:
        kinds: ``(left, right)`` kinds.
        colours: ``(left, right)`` BGR colours, 0-255.
        ragged: ``(left, right)``: the edge wanders between the asphalt's edge and this many metres into the
            shoulder.
        seed: the seed of the verge's own noise (grain, stones, the edge's wander).
    """

    kinds: tuple[str, str]
    colours: tuple[tuple[float, float, float], tuple[float, float, float]]
    ragged: tuple[float, float]
    seed: int

    @classmethod
    def sample(cls, rng: np.random.Generator) -> Verge:
        kinds = tuple(VERGE_KINDS[int(rng.choice(len(VERGE_KINDS), p=VERGE_CHANCES))] for _ in range(2))
        colours = tuple(_verge_colour(kind, rng) for kind in kinds)
        ragged = (float(rng.uniform(0.0, 0.25)), float(rng.uniform(0.0, 0.25)))
        return cls((kinds[0], kinds[1]), (colours[0], colours[1]), ragged, int(rng.integers(1 << 31)))

    def planes(
        self, rel: np.ndarray, zs: np.ndarray, ppm: float, edges: tuple[float, float]
    ) -> tuple[list[np.ndarray], np.ndarray]:
        """The verge's B, G, R planes (float32, the texture's shape) and where it lies (bool): beyond ``edges``
        (the asphalt's left and right edges, texels from the road centre), its edge wandering up to `ragged` metres
        into the shoulder.

        Args:
            rel: texels from the road centre per texel (``(H, W)`` or broadcastable).
            zs: metres ahead per texture row.
            ppm: texels per metre.
        """
        noise = np.random.default_rng(self.seed)
        h, w = len(zs), rel.shape[1]
        wander = np.cumsum(noise.normal(0.0, 1.0, (2, h)), axis=1)
        wander = wander / np.maximum(np.abs(wander).max(axis=1, keepdims=True), 1e-6)
        # the edge eats 0 to `ragged` metres into the shoulder, so that no strip of the classic verge shows
        left = edges[0] + self.ragged[0] * ppm * (wander[0][:, None] + 1.0) / 2.0
        right = edges[1] - self.ragged[1] * ppm * (wander[1][:, None] + 1.0) / 2.0
        on_left, on_right = rel < left, rel > right
        low = cv2.resize(noise.normal(0, 1, (max(h // 32, 2), max(w // 32, 2))).astype(np.float32), (w, h))
        grain = noise.normal(0, 1, (h, w)).astype(np.float32)
        stones = (noise.random((h, w)) < 0.01) * noise.choice([-40.0, 40.0], (h, w))  # 1 % of texels, bright or dark
        shade = (10.0 * low + 7.0 * grain + stones).astype(np.float32)
        planes = []
        for k in range(3):
            plane = np.where(on_left, self.colours[0][k], self.colours[1][k]).astype(np.float32)
            planes.append(plane + shade)
        mask: np.ndarray = on_left | on_right
        return planes, mask


def _verge_colour(kind: str, rng: np.random.Generator) -> tuple[float, float, float]:
    """A BGR colour of a verge ``kind``: green grass darker than asphalt; dirt, dry grass and gravel brighter."""
    if kind == "grass":
        g = float(rng.uniform(90, 130))
        return (g * 0.55, g, g * 0.8)
    if kind == "dirt":
        v = float(rng.uniform(130, 190))
        return (v * 0.72, v * 0.88, v)
    if kind == "dry grass":
        v = float(rng.uniform(150, 205))
        return (v * 0.62, v * 0.9, v)
    v = float(rng.uniform(135, 185))
    return (v * 0.95, v * 0.97, v)


@dataclass(frozen=True)
class RepairedSurface:
    """The dashcam world's `Surface` with repairs that run along and across the road (metres from the road centre).

    Attributes:
        surface: the format-7 surface drawn first.
        strips: ``(lateral centre, width, z0, length, grey change)``: a strip of other asphalt with straight edges.
        joints: ``(lateral, z0, length)``: a straight tar-sealed joint (dark, ~5 cm) along the road.
        cracks: ``(z, lateral from, lateral to, wobble)``: a sealed crack across the road.
    """

    surface: Surface
    strips: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    joints: list[tuple[float, float, float]] = field(default_factory=list)
    cracks: list[tuple[float, float, float, float]] = field(default_factory=list)

    @classmethod
    def sample(
        cls, rng: np.random.Generator, surface: Surface, z_range: tuple[float, float], offsets: list[float]
    ) -> RepairedSurface:
        length = z_range[1] - z_range[0]
        left, right = min(offsets), max(offsets)
        strips = [
            (
                float(rng.uniform(left, right)),
                float(rng.uniform(0.6, 2.2)),
                float(rng.uniform(*z_range)),
                float(rng.uniform(8, 60)),
                float(rng.choice([-1, 1]) * rng.uniform(10, 35)),
            )
            for _ in range(int(rng.poisson(length / 70.0)))
        ]
        joints = [
            (
                float(mark + rng.choice([-1, 1]) * rng.uniform(0.15, 0.7)),
                float(rng.uniform(*z_range)),
                float(rng.uniform(20, 120)),
            )
            for mark in offsets
            if rng.random() < 0.5
        ]
        cracks = [
            (
                float(rng.uniform(*z_range)),
                float(rng.uniform(left - 1, 0)),
                float(rng.uniform(0, right + 1)),
                float(rng.uniform(0, 0.5)),
            )
            for _ in range(int(rng.poisson(length / 30.0)))
        ]
        return cls(surface, strips, joints, cracks)

    def draw(
        self, lum: np.ndarray, rel: np.ndarray, zs: np.ndarray, ppm: float, offsets: list[float], base: float
    ) -> np.ndarray:
        """The texture's grey plane with the surface and its repairs (the arguments of `Surface.draw`)."""
        lum = self.surface.draw(lum, rel, zs, ppm, offsets, base)
        metres = rel / ppm
        line = max(1.0, 0.025 * ppm)  # half width of a sealed joint in texels
        for centre, width, z0, length, shade in self.strips:
            rows = (zs >= z0) & (zs <= z0 + length)
            inside = np.abs(metres[rows] - centre) < width / 2
            lum[rows] = np.where(inside, lum[rows] + shade, lum[rows])
            edge = np.abs(np.abs(metres[rows] - centre) - width / 2) * ppm < line  # the strip's sealed edges
            lum[rows] = np.where(edge, lum[rows] * 0.55, lum[rows])
        for lateral, z0, length in self.joints:
            rows = (zs >= z0) & (zs <= z0 + length)
            near = np.abs(metres[rows] - lateral) * ppm < line
            lum[rows] = np.where(near, lum[rows] * 0.5, lum[rows])
        for z, x0, x1, wobble in self.cracks:
            across = (metres >= x0) & (metres <= x1)
            bend = z + wobble * np.sin(metres * 1.3 + z)
            near = (np.abs(zs[:, None] - bend) * ppm < line) & across
            lum = np.where(near, lum * 0.5, lum)
        return lum.astype(np.float32)


@dataclass(frozen=True)
class Scenery:
    """The curbs and poles beside the road (the ``curbs_poles`` furniture; the sun casts the poles' shadows,
    `Sun.shadows`).

    Attributes:
        curbs: lateral metres (from the road centre) of each curb's face, with ``curb_height`` and a top ``curb_top``
            metres wide, away from the road; ``curb_grey`` its concrete.
        poles: ``(lateral, z, height)`` of each pole (0.2 m thick, grey).
    """

    curbs: list[float]
    curb_height: float
    curb_top: float
    curb_grey: float
    poles: list[tuple[float, float, float]]

    @classmethod
    def sample(
        cls, rng: np.random.Generator, barrier: float | None, left: float, right: float, z_range: tuple[float, float]
    ) -> Scenery:
        """Curbs (50 % per side without a barrier: ``barrier``, the lateral metres of one, `Roadside.barrier`)
        0.3-2.5 m beyond the outer marks (``left``, ``right``: their lateral metres), poles every `POLE_SPACING_M` on
        one or both sides."""
        barrier_side = float(np.sign(barrier)) if barrier is not None else 0.0
        curbs = [
            mark + side * float(rng.uniform(0.3, 2.5))
            for mark, side in ((left, -1.0), (right, 1.0))
            if side != barrier_side and rng.random() < 0.5
        ]
        poles = []
        for mark, side in ((left, -1.0), (right, 1.0)):
            if rng.random() < 0.6:
                z = z_range[0] + float(rng.uniform(0, POLE_SPACING_M[1]))
                spacing = float(rng.uniform(*POLE_SPACING_M))
                lateral = mark + side * float(rng.uniform(2.0, 5.0))
                while z < z_range[1]:
                    poles.append((lateral, z, float(rng.uniform(6.0, 11.0))))
                    z += spacing * float(rng.uniform(0.9, 1.1))
        return cls(
            curbs, float(rng.uniform(0.10, 0.18)), float(rng.uniform(0.15, 0.3)), float(rng.uniform(140, 215)), poles
        )

    def draw(
        self, frame: np.ndarray, centre: Callable[[np.ndarray], np.ndarray], camera: Camera, pose: Pose, far: float
    ) -> None:
        """Draw the curbs and poles into ``frame`` (BGR uint8, in place), far to near (before the vehicles)."""
        zs = pose.z + np.concatenate([np.arange(0.5, 20.0, 1.0), np.arange(20.0, far, 4.0)])[::-1]
        g, h, top = self.curb_grey, self.curb_height, self.curb_top
        for z1, z0 in itertools.pairwise(zs):
            c0, c1 = float(centre(np.asarray(z0))), float(centre(np.asarray(z1)))
            for lateral in self.curbs:
                x0, x1 = c0 + lateral, c1 + lateral
                away = -top if lateral < 0 else top
                face = [(x0, 0.0), (x1, 0.0), (x1, h), (x0, h)]
                lid = [(x0, h), (x1, h), (x1 + away, h), (x0 + away, h)]
                fill_world_quad(frame, camera, pose, face, (z0, z1, z1, z0), (g * 0.7, g * 0.72, g * 0.75))
                fill_world_quad(frame, camera, pose, lid, (z0, z1, z1, z0), (g, g, g * 1.02))
        for lateral, z, height in sorted(self.poles, key=lambda p: -p[1]):
            if not pose.z + 0.5 < z < pose.z + far:
                continue
            x = float(centre(np.asarray(z))) + lateral
            pole = [(x - 0.1, 0.0), (x + 0.1, 0.0), (x + 0.1, height), (x - 0.1, height)]
            fill_world_quad(frame, camera, pose, pole, (z, z, z, z), (105, 110, 115))
