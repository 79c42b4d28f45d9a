"""The scene parts a world is made of (`stamlane.synth.worlds.World`): every variant of each, in one table per part.

`Parts.of` turns a world into its variants. `generate_clip` (`stamlane.synth.clip`) asks them for their draws in one
fixed order, the same for every world: `Parts.look` before the road (the camera, the markings, the sky, the
sensor), `Parts.scene` after the drive (the surface, the barriers, the light, the curbs and poles, the verges), then
the vehicles' bodies, the sky's painting and, per frame, the sensor. A variant that draws nothing leaves the
generator where it was, so a world draws exactly what the variants it picks draw, in that order: the order of the
draws the worlds made when they came (formats 7 and 8), which keeps every world's clips byte for byte.

A new variant: a function of its part's type (a part of one step) or a class with its part's methods (its
``Protocol``: the markings, the sky, the surface), one entry in the part's table below and its name in the part's type
of `stamlane.synth.worlds`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from stamlane.align.camera import Camera, Pose
from stamlane.synth.bodies import BodyStyle, draw_bodies
from stamlane.synth.config import SynthConfig
from stamlane.synth.dashcam import (
    CAM_HEIGHT_M,
    HFOV_DEG,
    HORIZON,
    MARKINGS,
    Marking,
    MarkingStandard,
    Roadside,
    Sensor,
    Sky,
    Surface,
)
from stamlane.synth.road import Road
from stamlane.synth.scenery import RepairedSurface, Scenery, Sun, Verge
from stamlane.synth.vehicles import SUN, Vehicle, draw_vehicles
from stamlane.synth.worlds import (
    BarriersVariant,
    CameraVariant,
    FurnitureVariant,
    LightsVariant,
    MarkingsVariant,
    SensorVariant,
    SkyVariant,
    SurfaceVariant,
    VehiclesVariant,
    VergesVariant,
    World,
)

__all__ = ["IMPLEMENTED", "Light", "Look", "Parts", "Scene"]

CLASSIC_HILLS = 0.04
"""Height of the classic world's tree line above the horizon, as a fraction of the frame height."""


# --- what the parts drew for one clip ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Look:
    """What a clip's parts draw before its road (`Parts.look`).

    Attributes:
        config: the settings with the clip's camera (its horizon, field of view and height).
        marking: the clip's marking standard and lengths; None: the classic marks.
        sky: the clip's sky, hills and land.
        sensor: the clip's camera sensor; None: none.
    """

    config: SynthConfig
    marking: Marking | None
    sky: Sky
    sensor: Sensor | None


@dataclass(frozen=True, eq=False)
class Light:
    """Where a clip's light comes from.

    Attributes:
        shift: ground displacement ``(X, Z)`` of a moving shadow per metre of height
            (`stamlane.synth.vehicles.shadow_polygons`).
        depth: how much a shadow darkens the ground (0: none).
        sun: the sun that casts the static shadows of what stands beside the road; None: no such shadows.
    """

    shift: np.ndarray
    depth: float
    sun: Sun | None = None


@dataclass(frozen=True)
class Scene:
    """What a clip's parts draw after its drive (`Parts.scene`).

    Attributes:
        surface: the road surface drawn over the asphalt; None: the classic asphalt.
        roadside: the barrier and rail; None: none.
        light: the clip's `Light`.
        furniture: the curbs and poles; None: none.
        verge: the ground beyond the shoulders; None: the classic green verge.
    """

    surface: Surface | RepairedSurface | None
    roadside: Roadside | None
    light: Light
    furniture: Scenery | None
    verge: Verge | None

    def cast(self, road: Road) -> list[np.ndarray] | None:
        """The sun's static shadows on ``road`` of the barrier, the rail and the poles (None without a sun)."""
        if self.light.sun is None:
            return None
        poles = self.furniture.poles if self.furniture is not None else []
        return self.light.sun.shadows(self.roadside, poles, road.centre, road.z_range)

    def beside(self) -> list[Roadside | Scenery]:
        """What stands beside the road, in the order it is drawn (far to near each): the barriers, then the curbs and
        poles."""
        return [thing for thing in (self.roadside, self.furniture) if thing is not None]


# --- the parts: a part of one step is a function, one of several a class; each variant a function or a class -----


CameraPart = Callable[[np.random.Generator, SynthConfig], SynthConfig]
"""The settings with the clip's camera (drawn after the marking standard)."""


def fixed_camera(rng: np.random.Generator, cfg: SynthConfig) -> SynthConfig:
    """The settings' camera (``horizon``, ``hfov_deg``, ``cam_height``); no draws."""
    return cfg


def dashcam_camera(rng: np.random.Generator, cfg: SynthConfig) -> SynthConfig:
    """A camera per clip spread over dashcam ranges (`stamlane.synth.dashcam.HORIZON`, ``HFOV_DEG``,
    ``CAM_HEIGHT_M``): the labels' rows and homographies follow from it."""
    horizon = float(rng.uniform(*HORIZON))
    hfov = float(rng.uniform(*HFOV_DEG))
    height = float(rng.uniform(*CAM_HEIGHT_M))
    return replace(cfg, horizon=horizon, hfov_deg=hfov, cam_height=height)


class MarkingsPart(Protocol):
    def standard(self, rng: np.random.Generator) -> MarkingStandard | None:
        """The clip's marking standard (drawn first of all); None: the classic marks."""
        ...

    def lengths(self, rng: np.random.Generator, standard: MarkingStandard | None) -> Marking | None:
        """The standard's dash and gap lengths for the clip (drawn after the camera)."""
        ...


class ClassicMarkings:
    """2-4 m dashes, the settings' ``dash_gap``, 12-20 cm lines (`stamlane.synth.road.sample_road`); no draws here."""

    def standard(self, rng: np.random.Generator) -> MarkingStandard | None:
        return None

    def lengths(self, rng: np.random.Generator, standard: MarkingStandard | None) -> Marking | None:
        return None


class StandardMarkings:
    """A marking standard of `stamlane.synth.dashcam.MARKINGS` per clip, its lengths ±10 %, its widths and raised
    pavement markers (`stamlane.synth.dashcam.Marking`)."""

    def standard(self, rng: np.random.Generator) -> MarkingStandard | None:
        return MARKINGS[int(rng.integers(0, len(MARKINGS)))]

    def lengths(self, rng: np.random.Generator, standard: MarkingStandard | None) -> Marking | None:
        assert standard is not None, "the standard this part drew"
        return Marking.sample(rng, standard)


class SkyPart(Protocol):
    def sample(self, rng: np.random.Generator) -> Sky:
        """The clip's sky and hills (drawn before the sensor)."""
        ...

    def with_land(self, rng: np.random.Generator, sky: Sky) -> Sky:
        """``sky`` with the land's colour (drawn after the sensor)."""
        ...

    def paint(self, rng: np.random.Generator, sky: Sky, classic: np.ndarray) -> np.ndarray:
        """The sky's image, BGR uint8 of the frame's size, given the classic sky drawn for every world."""
        ...


class ClassicSky:
    """A pale gradient with a low tree line (`stamlane.synth.clip`'s, drawn for every world); clear, no land colour."""

    def sample(self, rng: np.random.Generator) -> Sky:
        return Sky(clear=True, hills=CLASSIC_HILLS)

    def with_land(self, rng: np.random.Generator, sky: Sky) -> Sky:
        return sky

    def paint(self, rng: np.random.Generator, sky: Sky, classic: np.ndarray) -> np.ndarray:
        return classic


class DashcamSky:
    """Clear blue or overcast with clouds, hills of a drawn height, the land's colour (`stamlane.synth.dashcam.Sky`)."""

    def sample(self, rng: np.random.Generator) -> Sky:
        return Sky.sample(rng)

    def with_land(self, rng: np.random.Generator, sky: Sky) -> Sky:
        return sky.with_land(rng)

    def paint(self, rng: np.random.Generator, sky: Sky, classic: np.ndarray) -> np.ndarray:
        return sky.paint(rng, classic.shape[0], classic.shape[1])


SensorPart = Callable[[np.random.Generator, bool], Sensor | None]
"""The clip's sensor (the flag: ``SynthConfig.randomise``, a random colour cast); None: the frames as rendered."""


class SurfacePart(Protocol):
    def sample(self, rng: np.random.Generator, road: Road) -> Surface | None:
        """The road's surface (drawn first after the drive)."""
        ...

    def repair(self, rng: np.random.Generator, surface: Surface | None, road: Road) -> Surface | RepairedSurface | None:
        """``surface`` with its repairs (drawn after the curbs and poles)."""
        ...


class Asphalt:
    """The classic asphalt of `stamlane.synth.road.render_texture`; no draws here."""

    def sample(self, rng: np.random.Generator, road: Road) -> Surface | None:
        return None

    def repair(self, rng: np.random.Generator, surface: Surface | None, road: Road) -> Surface | RepairedSurface | None:
        return surface


class Jointed(Asphalt):
    """Concrete or asphalt with joints, seams, a shoulder of another shade and wheel paths
    (`stamlane.synth.dashcam.Surface`)."""

    def sample(self, rng: np.random.Generator, road: Road) -> Surface | None:
        return Surface.sample(rng, road.z_range, max(np.abs(_offsets(road))))


class Repaired(Jointed):
    """The jointed surface with repair strips, sealed joints and cracks (`stamlane.synth.scenery.RepairedSurface`)."""

    def repair(self, rng: np.random.Generator, surface: Surface | None, road: Road) -> Surface | RepairedSurface | None:
        assert surface is not None, "the surface this part drew"
        return RepairedSurface.sample(rng, surface, road.z_range, _offsets(road))


BarriersPart = Callable[[np.random.Generator, Road], Roadside | None]
"""The barrier and rail beside the road (drawn after the surface); None: none."""


def barriers(rng: np.random.Generator, road: Road) -> Roadside | None:
    """A concrete barrier and a guard rail beside the road (`stamlane.synth.dashcam.Roadside`)."""
    offsets = _offsets(road)
    return Roadside.sample(rng, min(offsets), max(offsets))


LightsPart = Callable[[np.random.Generator, Look], Light]
"""The clip's light under the sky of the look (drawn after the barriers)."""


def fixed_light(rng: np.random.Generator, look: Look) -> Light:
    """One low sun for the moving shadows (`stamlane.synth.vehicles.SUN`, ``moving_shadow_depth`` deep), no static
    shadows of what stands beside the road; no draws."""
    return Light(SUN, look.config.moving_shadow_depth)


def sun_light(rng: np.random.Generator, look: Look) -> Light:
    """A sun per clip (`stamlane.synth.scenery.Sun`) that casts every shadow, deep under a clear sky."""
    sun = Sun.sample(rng, look.sky.clear)
    return Light(sun.displacement(), sun.depth, sun)


FurniturePart = Callable[[np.random.Generator, Road, Roadside | None], Scenery | None]
"""The curbs and poles beside the road, none where the barriers stand (drawn after the light); None: none."""


def curbs_and_poles(rng: np.random.Generator, road: Road, roadside: Roadside | None) -> Scenery | None:
    """Curbs on the sides without a barrier, lamp or sign poles (`stamlane.synth.scenery.Scenery`)."""
    offsets = _offsets(road)
    barrier = roadside.barrier if roadside is not None else None
    return Scenery.sample(rng, barrier, min(offsets), max(offsets), road.z_range)


VergesPart = Callable[[np.random.Generator], Verge | None]
"""The ground beyond the shoulders (drawn last before the texture); None: the classic green verge."""

VehiclePainter = Callable[[np.ndarray, np.ndarray, Road, Camera, Pose, float], None]
"""Draws a clip's vehicles far to near into a frame (BGR uint8, in place) and marks their pixels in the mask:
``(frame, mask, road, camera, pose, t)``."""
VehiclesPart = Callable[[np.random.Generator, list[Vehicle]], VehiclePainter]
"""How the clip's vehicles look (drawn after the vehicles): their painter."""


def box_vehicles(rng: np.random.Generator, vehicles: list[Vehicle]) -> VehiclePainter:
    """Boxes with a rear window and lights (`stamlane.synth.vehicles.draw_vehicles`); no draws."""
    return lambda frame, mask, road, camera, pose, t: draw_vehicles(frame, mask, vehicles, road, camera, pose, t)


def body_vehicles(rng: np.random.Generator, vehicles: list[Vehicle]) -> VehiclePainter:
    """Wheels, body, cabin or cargo box, glass and lights (`stamlane.synth.bodies`), a `BodyStyle` per vehicle."""
    styles = [BodyStyle.sample(rng, v.height > 1.6) for v in vehicles]
    return lambda frame, mask, road, camera, pose, t: draw_bodies(frame, mask, vehicles, styles, road, camera, pose, t)


def _nothing(rng: np.random.Generator, *_: object) -> None:
    """The variant that is not there (no sensor, no barriers, no curbs or poles, the classic verge); no draws."""
    return None


def _offsets(road: Road) -> list[float]:
    """Lateral metres of the road's marks from its centre, left to right."""
    return [m.offset for m in road.marks]


# --- the tables and a world's parts --------------------------------------------------------------------------------

CAMERAS: dict[CameraVariant, CameraPart] = {"fixed": fixed_camera, "dashcam": dashcam_camera}
MARKINGS_PARTS: dict[MarkingsVariant, MarkingsPart] = {"classic": ClassicMarkings(), "standards": StandardMarkings()}
SKIES: dict[SkyVariant, SkyPart] = {"classic": ClassicSky(), "dashcam": DashcamSky()}
SENSORS: dict[SensorVariant, SensorPart] = {"none": _nothing, "dashcam": Sensor.sample}
SURFACES: dict[SurfaceVariant, SurfacePart] = {"asphalt": Asphalt(), "jointed": Jointed(), "repaired": Repaired()}
BARRIERS: dict[BarriersVariant, BarriersPart] = {"none": _nothing, "barriers": barriers}
LIGHTS: dict[LightsVariant, LightsPart] = {"fixed": fixed_light, "sun": sun_light}
FURNITURE: dict[FurnitureVariant, FurniturePart] = {"none": _nothing, "curbs_poles": curbs_and_poles}
VERGES: dict[VergesVariant, VergesPart] = {"grass": _nothing, "kinds": Verge.sample}
VEHICLES: dict[VehiclesVariant, VehiclesPart] = {"boxes": box_vehicles, "bodies": body_vehicles}

IMPLEMENTED: dict[str, tuple[str, ...]] = {
    "camera": tuple(CAMERAS),
    "markings": tuple(MARKINGS_PARTS),
    "sky": tuple(SKIES),
    "sensor": tuple(SENSORS),
    "surface": tuple(SURFACES),
    "barriers": tuple(BARRIERS),
    "lights": tuple(LIGHTS),
    "furniture": tuple(FURNITURE),
    "verges": tuple(VERGES),
    "vehicles": tuple(VEHICLES),
}
"""The variants each part's table holds, by name (`stamlane.synth.worlds.PART_VARIANTS` names the same)."""


@dataclass(frozen=True)
class Parts:
    """A world's variant of each part (`of`), and the order they draw in: `look`, `scene`, then the vehicles' looks,
    the sky's painting and, per frame, the sensor."""

    camera: CameraPart
    markings: MarkingsPart
    sky: SkyPart
    sensor: SensorPart
    surface: SurfacePart
    barriers: BarriersPart
    lights: LightsPart
    furniture: FurniturePart
    verges: VergesPart
    vehicles: VehiclesPart

    @classmethod
    def of(cls, world: World) -> Parts:
        """The variants ``world`` picks."""
        return cls(
            CAMERAS[world.camera],
            MARKINGS_PARTS[world.markings],
            SKIES[world.sky],
            SENSORS[world.sensor],
            SURFACES[world.surface],
            BARRIERS[world.barriers],
            LIGHTS[world.lights],
            FURNITURE[world.furniture],
            VERGES[world.verges],
            VEHICLES[world.vehicles],
        )

    def look(self, rng: np.random.Generator, cfg: SynthConfig) -> Look:
        """What the parts draw before the road, in this order: the marking standard, the camera, the standard's
        lengths, the sky, the sensor, the land's colour (format 7's order)."""
        standard = self.markings.standard(rng)
        cfg = self.camera(rng, cfg)
        marking = self.markings.lengths(rng, standard)
        sky = self.sky.sample(rng)
        sensor = self.sensor(rng, cfg.randomise)
        return Look(cfg, marking, self.sky.with_land(rng, sky), sensor)

    def scene(self, rng: np.random.Generator, road: Road, look: Look) -> Scene:
        """What the parts draw after the drive and the static shadows' count, before the texture, in this order: the
        surface, the barriers, the light, the curbs and poles, the surface's repairs, the verges (format 8's)."""
        surface = self.surface.sample(rng, road)
        roadside = self.barriers(rng, road)
        light = self.lights(rng, look)
        furniture = self.furniture(rng, road, roadside)
        repaired = self.surface.repair(rng, surface, road)
        return Scene(repaired, roadside, light, furniture, self.verges(rng))
