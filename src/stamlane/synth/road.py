"""The road of a synthetic clip: lane-mark geometry on the ground plane and its top-down texture.

Ground coordinates are metres (``X`` right, ``Z`` forward, see ``camera``). The road centre
follows ``X = c(Z) = kappa Z^2 / 2 + dkappa Z^3 / 6``; a lane mark lies at a fixed lateral offset from
it. The texture is ONE top-down image of the whole stretch a clip drives over, rendered once per clip:
asphalt with stones, cracks and repair patches (corners for ORB), the paint (solid or dashed, worn in
places), a shoulder and verge, and static shadows. Each frame is then a single ``cv2.warpPerspective``
of it (``texture_from_ground`` composes with the camera's ``image_from_ground``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from stamlane.synth.dashcam import Marking, Surface
    from stamlane.synth.scenery import RepairedSurface, Verge

__all__ = ["LaneMark", "Road", "render_texture", "sample_road"]

WHITE = (235, 235, 235)
YELLOW = (40, 190, 225)  # BGR


@dataclass
class LaneMark:
    """One painted lane mark at a lateral ``offset`` (metres) from the road centre."""

    offset: float
    dashed: bool
    width: float = 0.15
    dash: float = 3.0
    gap: float = 6.0
    phase: float = 0.0
    colour: tuple[int, int, int] = WHITE
    worn: list[tuple[float, float, float]] = field(default_factory=list)
    """``(z0, z1, strength)`` stretches where the paint is worn away by ``strength`` in [0, 1]."""
    dots: str = ""
    """Raised pavement markers (Botts' dots) of a dashed mark: "gaps" in its gaps, "only" instead of its paint, ""
    none (the dashcam world's, `stamlane.synth.dashcam.MARKINGS`)."""


@dataclass
class Road:
    """A road stretch and the area its texture covers.

    Attributes:
        kappa: curvature at ``Z = 0`` (1/m, positive bends right).
        dkappa: curvature change per metre (1/m^2).
        lane_width: metres between adjacent marks.
        marks: the lane marks, left to right.
        z_range: ``(z_min, z_max)`` metres covered by the texture.
        ppm: texture pixels per metre.
        margin: metres of verge beside the outer marks inside the texture.
    """

    kappa: float
    dkappa: float
    lane_width: float
    marks: list[LaneMark]
    z_range: tuple[float, float]
    ppm: float
    margin: float = 10.0

    def centre(self, z: np.ndarray | float) -> np.ndarray:
        """Road centre ``X`` (metres) at distance ``z``."""
        z = np.asarray(z, dtype=np.float64)
        return self.kappa * z**2 / 2.0 + self.dkappa * z**3 / 6.0

    def slope(self, z: np.ndarray | float) -> np.ndarray:
        """``dX/dZ`` of the road centre at ``z``."""
        z = np.asarray(z, dtype=np.float64)
        return self.kappa * z + self.dkappa * z**2 / 2.0

    @property
    def shear(self) -> float:
        """Mean slope of the road over ``z_range``: the texture is sheared by it so a curve fits a narrow image."""
        z0, z1 = self.z_range
        return float((self.centre(z1) - self.centre(z0)) / (z1 - z0))

    def sheared_centre(self, z: np.ndarray | float) -> np.ndarray:
        """Road centre in the texture's sheared lateral coordinate ``X - shear * Z`` (metres)."""
        return self.centre(z) - self.shear * np.asarray(z, dtype=np.float64)

    @property
    def x_range(self) -> tuple[float, float]:
        """``(min, max)`` of the sheared lateral coordinate ``X - shear * Z`` covered by the texture, metres."""
        c = self.sheared_centre(np.linspace(*self.z_range, 64))
        left = min(m.offset for m in self.marks)
        right = max(m.offset for m in self.marks)
        return float(c.min() + left - self.margin), float(c.max() + right + self.margin)

    def texture_from_ground(self) -> np.ndarray:
        """Affine map from ground ``(X, Z, 1)`` metres to texture pixels, (3, 3).

        Column ``(X - shear Z - x_min) * ppm``, row ``(z_max - Z) * ppm`` (far end at the top).
        """
        x_min, _ = self.x_range
        _, z_max = self.z_range
        p = self.ppm
        return np.array([[p, -p * self.shear, -p * x_min], [0, -p, p * z_max], [0, 0, 1.0]])

    def texture_size(self) -> tuple[int, int]:
        """Texture ``(H, W)`` in pixels (rows along the road, columns across it)."""
        x_min, x_max = self.x_range
        z_min, z_max = self.z_range
        return int(np.ceil((z_max - z_min) * self.ppm)) + 1, int(np.ceil((x_max - x_min) * self.ppm)) + 1

    def mark_points(self, mark: LaneMark, z: np.ndarray) -> np.ndarray:
        """Ground points ``(X, Z)`` of a mark at distances ``z``, (N, 2) metres."""
        return np.stack([self.centre(z) + mark.offset, z], axis=1)


def sample_road(
    rng: np.random.Generator,
    z_range: tuple[float, float],
    ppm: float,
    *,
    curved_prob: float = 0.5,
    max_kappa: float = 1 / 350,
    worn_prob: float = 0.4,
    worn_stretches: tuple[int, int] = (1, 3),
    worn_strength: tuple[float, float] = (0.4, 0.9),
    dash_gap: tuple[float, float] = (4.0, 8.0),
    marking: Marking | None = None,
) -> tuple[Road, int]:
    """Draw a road of 2-5 lane marks.

    Args:
        worn_prob: chance of a mark to be worn in ``worn_stretches`` (inclusive range) stretches of 5-30 m
            whose paint is ``worn_strength`` gone.
        dash_gap: range of the metres between dashes (the dashes are 2-4 m).
        marking: the clip's marking standard (`stamlane.synth.dashcam.Marking`, the ``standards`` markings): its
            dash, gap and widths replace the classic ones, and its dashed marks may have raised pavement markers;
            None: the classic marks, draw for draw.

    Returns:
        the road and the index of the ego lane (0 = between marks 0 and 1).
    """
    n_marks = int(rng.integers(2, 6))
    lane_width = float(rng.uniform(3.3, 3.9))
    offsets = (np.arange(n_marks) - (n_marks - 1) / 2.0) * lane_width
    ego_lane = int(rng.integers(0, n_marks - 1))
    # shift so that the ego lane centre is at X = 0 of the road centre line
    offsets = offsets - (offsets[ego_lane] + offsets[ego_lane + 1]) / 2.0
    curved = rng.random() < curved_prob
    kappa = float(rng.uniform(-max_kappa, max_kappa)) if curved else 0.0
    dkappa = float(rng.uniform(-1, 1) * max_kappa / 200.0) if curved else 0.0
    marks = []
    dash, gap = float(rng.uniform(2.0, 4.0)), float(rng.uniform(*dash_gap))
    if marking is not None:
        dash, gap = marking.dash, marking.gap
    for i, off in enumerate(offsets):
        outer = i in (0, n_marks - 1)
        dashed = (not outer) and rng.random() < 0.8
        colour = YELLOW if (i == 0 and rng.random() < 0.3) else WHITE
        worn = []
        if rng.random() < worn_prob:
            for _ in range(int(rng.integers(worn_stretches[0], worn_stretches[1] + 1))):
                z0 = float(rng.uniform(*z_range))
                worn.append((z0, z0 + float(rng.uniform(5, 30)), float(rng.uniform(*worn_strength))))
        width = float(rng.uniform(0.12, 0.2))
        phase = float(rng.uniform(0, dash + gap))
        dots = ""
        if marking is not None:  # the standard's draws, after the classic ones: the classic road stays
            width, dots = marking.restyle(rng, dashed)
        marks.append(
            LaneMark(
                offset=float(off),
                dashed=dashed,
                width=width,
                dash=dash,
                gap=gap,
                phase=phase,
                colour=colour,
                worn=worn,
                dots=dots,
            )
        )
    return Road(kappa, dkappa, lane_width, marks, z_range, ppm), ego_lane


def render_texture(
    road: Road,
    rng: np.random.Generator,
    *,
    shadows: int = 4,
    shadow_depth: float = 0.5,
    unpainted: bool = False,
    surface: Surface | RepairedSurface | None = None,
    cast: list[np.ndarray] | None = None,
    cast_depth: float = 0.0,
    verge: Verge | None = None,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Render the top-down texture of a road.

    Args:
        road: the road.
        rng: random generator (the texture is a deterministic function of its state).
        shadows: number of static shadow blobs (trees, poles, a bridge) to cast.
        shadow_depth: how dark the darkest shadow is, in [0, 1] (1 = black).
        unpainted: also return the same texture without the lane paint (same asphalt, same shadows, the same
            draws from ``rng``): rendered beside the painted one, it shows where the paint is visible
            (`stamlane.synth.visibility`).
        surface: the road surface of a world's ``surface`` part (`stamlane.synth.dashcam.Surface`: concrete or
            asphalt with joints, seams, a shoulder of another shade, wheel paths; or it repaired,
            `stamlane.synth.scenery.RepairedSurface`), drawn over the asphalt before the paint; None: the asphalt.
        cast: ground polygons ``(N, 2)`` metres ``(X, Z)`` of sharp sun shadows (of the barrier, rail and poles,
            `stamlane.synth.scenery.Sun.shadows`), darkening the ground and its paint by ``cast_depth``; None: none
            (no draws either way).
        verge: the ground beyond the shoulders (the ``kinds`` verges, `stamlane.synth.scenery.Verge`), drawn from
            its own seed; None: the classic green verge.

    Returns:
        BGR uint8 image ``(height, width, 3)`` of ``road.texture_size()``; pixel ``texture_from_ground @ (X, Z, 1)``;
        with ``unpainted``, the pair ``(texture, texture without paint)``.
    """
    h, w = road.texture_size()
    tex_from_ground = road.texture_from_ground()
    p = road.ppm

    # --- verge and asphalt base (single-channel float32 planes; merged to BGR at the end) ----------
    zs = np.linspace(road.z_range[1], road.z_range[0], h)  # row -> Z
    centre_cols = ((road.sheared_centre(zs) - road.x_range[0]) * p).astype(np.float32)
    left = min(m.offset for m in road.marks) * p
    right = max(m.offset for m in road.marks) * p
    shoulder = float(rng.uniform(0.5, 2.0)) * p
    rel = np.arange(w, dtype=np.float32)[None, :] - centre_cols[:, None]
    on_road = (rel > left - shoulder) & (rel < right + shoulder)

    low = cv2.resize(
        rng.normal(0, 1, (max(h // 48, 2), max(w // 48, 2))).astype(np.float32), (w, h), interpolation=cv2.INTER_CUBIC
    )
    grain = rng.integers(-10, 11, (h, w), dtype=np.int16).astype(np.float32)
    base_grey = float(rng.uniform(80, 120))
    lum: np.ndarray = cv2.addWeighted(low, 8.0, grain, 1.0, base_grey)
    # stones: bright and dark specks of 1-3 texels
    n_stones = int(w * h * 0.004)
    ys, xs = rng.integers(0, h, n_stones), rng.integers(0, w, n_stones)
    lum[ys, xs] += rng.choice(np.array([-45.0, 45.0], np.float32), n_stones)
    # gravel and tar spots of ~20 cm: distinctive corners at mid distance, so ORB matches the road rather
    # than the (corner-rich, moving) vehicles
    cell = max(2, round(0.2 * p))
    spots = rng.choice(
        np.array([-35.0, 0.0, 35.0], np.float32), size=(h // cell + 1, w // cell + 1), p=[0.04, 0.92, 0.04]
    )
    lum += cv2.resize(spots, (w, h), interpolation=cv2.INTER_NEAREST)
    lum = cv2.GaussianBlur(lum, (3, 3), 0.6)

    # repair patches and cracks on the asphalt: strong corners at every distance
    for _ in range(int((h / p) / 2)):
        zc = float(rng.uniform(*road.z_range))
        xc = float(road.centre(zc) + rng.uniform(left / p - 1, right / p + 1))
        pw, ph = float(rng.uniform(0.4, 2.5)), float(rng.uniform(0.4, 3.0))
        angle_deg = float(rng.uniform(0, 180))
        ctr = (tex_from_ground @ np.array([xc, zc, 1.0]))[:2]
        box = cv2.boxPoints(((float(ctr[0]), float(ctr[1])), (pw * p, ph * p), angle_deg)).astype(np.int32)
        tone = float(rng.choice([-1, 1]) * rng.uniform(15, 35))
        cv2.fillConvexPoly(lum, box, base_grey + tone, lineType=cv2.LINE_AA)
    for _ in range(int((h / p) / 5)):
        zc = float(rng.uniform(*road.z_range))
        xc = float(road.centre(zc) + rng.uniform(left / p, right / p))
        steps = rng.normal(0, 0.5, (int(rng.integers(3, 8)), 2)).cumsum(axis=0) + np.array([xc, zc])
        pts = (np.c_[steps, np.ones(len(steps))] @ tex_from_ground.T)[:, :2].astype(np.int32)
        cv2.polylines(lum, [pts], False, base_grey - 40, max(1, int(0.04 * p)), lineType=cv2.LINE_AA)

    if surface is not None:
        lum = surface.draw(lum, rel, zs.astype(np.float32), p, [m.offset for m in road.marks], base_grey)

    green = np.array([60, 110, 90], np.float32) * float(rng.uniform(0.7, 1.1))
    verge_lum = cv2.addWeighted(low, 12.0, grain, 2.0, 0.0)
    planes = [np.where(on_road, lum * tint, verge_lum + g) for tint, g in zip((1.02, 1.0, 0.97), green)]
    if verge is not None:
        ground, beyond = verge.planes(rel, zs, p, (left - shoulder, right + shoulder))
        planes = [np.where(beyond, v, pl) for v, pl in zip(ground, planes)]

    # --- paint -------------------------------------------------------------------------------------
    alpha: np.ndarray = np.zeros((h, w), np.float32)
    colour = [np.zeros((h, w), np.float32) for _ in range(3)]
    z_fine = np.arange(road.z_range[0], road.z_range[1], 0.25)
    for mark in road.marks:
        pts = road.mark_points(mark, z_fine)
        pix = (np.c_[pts, np.ones(len(pts))] @ tex_from_ground.T)[:, :2]
        thick = max(2, round(float(mark.width) * p))
        strength = np.ones(len(z_fine), np.float32)
        for z0, z1, s in mark.worn:
            strength[(z_fine >= z0) & (z_fine <= z1)] = 1.0 - s
        if mark.dashed:
            on = np.mod(z_fine - mark.phase, mark.dash + mark.gap) < mark.dash
        else:
            on = np.ones(len(z_fine), bool)
        if mark.dots:
            _draw_dots(road, mark, tex_from_ground, alpha, colour)
            if mark.dots == "only":
                on[:] = False
        # one polyline per run of painted samples of one strength (a dash, or a stretch of solid line)
        key = np.where(on, strength, -1.0)
        cuts = np.flatnonzero(np.diff(key) != 0) + 1
        for run in np.split(np.arange(len(z_fine)), cuts):
            if len(run) < 2 or key[run[0]] < 0:
                continue
            pts = np.round(pix[run] * 16).astype(np.int32)
            cv2.polylines(alpha, [pts], False, float(key[run[0]]), thick, lineType=cv2.LINE_AA, shift=4)
            for plane, c in zip(colour, mark.colour):
                cv2.polylines(plane, [pts], False, float(c), thick + 2, shift=4)
    # scuffs: paint is patchy everywhere, more where worn
    scuff = cv2.resize(
        rng.random((max(h // 6, 2), max(w // 6, 2))).astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR
    )
    alpha = cv2.multiply(alpha, np.clip(0.55 + scuff, 0.0, 1.0), scale=0.92)
    bare = planes
    planes = [cv2.add(cv2.multiply(pl, 1.0 - alpha), cv2.multiply(alpha, col)) for pl, col in zip(planes, colour)]

    # --- static shadows ------------------------------------------------------------------------------
    if shadows > 0:
        shade: np.ndarray = np.zeros((h, w), np.float32)
        for _ in range(shadows):
            zc = float(rng.uniform(*road.z_range))
            side = rng.choice([left / p - shoulder / p - 1.5, right / p + shoulder / p + 1.5])
            xc = float(road.centre(zc) + side)
            if rng.random() < 0.15:  # a bridge or tree line across the whole road
                z0, z1 = zc, zc + float(rng.uniform(3, 10))
                c0, c1 = float(road.centre(z0)), float(road.centre(z1))
                poly = np.array([[c0 - 40, z0], [c0 + 40, z0], [c1 + 40, z1], [c1 - 40, z1]], np.float64)
            else:
                n = 12
                ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
                rad_x = float(rng.uniform(2, 6)) * (1 + 0.3 * rng.random(n))
                rad_z = float(rng.uniform(3, 10)) * (1 + 0.3 * rng.random(n))
                poly = np.stack([xc + rad_x * np.cos(ang) * 1.4, zc + rad_z * np.sin(ang)], axis=1)
            pix = (np.c_[poly, np.ones(len(poly))] @ tex_from_ground.T)[:, :2].astype(np.int32)
            cv2.fillPoly(shade, [pix], float(rng.uniform(0.5, 1.0)), lineType=cv2.LINE_AA)
        k = int(max(3, 0.6 * p)) | 1
        shade = cv2.GaussianBlur(np.minimum(shade, 1.0), (k, k), 0)
        light = 1.0 - shadow_depth * shade
        planes = [cv2.multiply(pl, light) for pl in planes]
        bare = [cv2.multiply(pl, light) for pl in bare]

    if cast:  # sharp shadows of the sun: a penumbra of ~5 cm
        sharp: np.ndarray = np.zeros((h, w), np.float32)
        for poly in cast:
            pix = np.round((np.c_[poly, np.ones(len(poly))] @ tex_from_ground.T)[:, :2] * 16).astype(np.int32)
            cv2.fillPoly(sharp, [pix], 1.0, lineType=cv2.LINE_AA, shift=4)
        sharp = cv2.GaussianBlur(sharp, (0, 0), max(0.8, 0.05 * p))
        light = 1.0 - cast_depth * np.minimum(sharp, 1.0)
        planes = [cv2.multiply(pl, light) for pl in planes]
        bare = [cv2.multiply(pl, light) for pl in bare]

    texture = cv2.merge([np.clip(pl, 0, 255).astype(np.uint8) for pl in planes])
    if not unpainted:
        return texture
    return texture, cv2.merge([np.clip(pl, 0, 255).astype(np.uint8) for pl in bare])


def _draw_dots(
    road: Road, mark: LaneMark, tex_from_ground: np.ndarray, alpha: np.ndarray, colour: list[np.ndarray]
) -> None:
    """Raised pavement markers of ``mark`` into the paint planes: a white dot every ``DOT_SPACING_M`` along it, in
    its gaps (``dots == "gaps"``) or all along it (``"only"``)."""
    from stamlane.synth.dashcam import DOT_RADIUS_M, DOT_SPACING_M

    z = np.arange(road.z_range[0] + mark.phase % DOT_SPACING_M, road.z_range[1], DOT_SPACING_M)
    if mark.dots == "gaps":
        z = z[np.mod(z - mark.phase, mark.dash + mark.gap) >= mark.dash + 0.3]
    pts = road.mark_points(mark, z)
    pix = np.round((np.c_[pts, np.ones(len(pts))] @ tex_from_ground.T)[:, :2] * 16).astype(np.int32)
    radius = max(16, round(DOT_RADIUS_M * road.ppm * 16))
    for x, y in pix:
        cv2.circle(alpha, (int(x), int(y)), radius, 1.0, -1, lineType=cv2.LINE_AA, shift=4)
        for plane in colour:
            cv2.circle(plane, (int(x), int(y)), radius + 16, 240.0, -1, shift=4)
