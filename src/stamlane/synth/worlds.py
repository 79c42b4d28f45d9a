"""The worlds of the generator: a world is a choice of each scene part, and `WORLDS` declares every world once.

A clip is drawn from ten scene parts (`World`'s fields), each with a few variants: the camera, the lane markings, the
sky, the sensor, the road surface, the barriers beside the road, the light, the curbs and poles, the verges and the
vehicles. `stamlane.synth.parts` draws each variant (one class per variant, the table of each part names them) in
one fixed order, whatever the world (`stamlane.synth.parts.Parts`); a world only picks. So:

- a new world is one entry of `WORLDS` that picks a variant of each part (``SynthConfig(world=...)`` and
  ``stamlane synth --world`` take it at once); an existing world is never changed, its clips are frozen;
- a new variant of a part is a class in `stamlane.synth.parts`, its name added to the part's table there and to its
  type here (``tests/synth/test_worlds.py`` checks the two agree); it draws from the clip's generator only when a
  world picks it, at its part's place in the order, so the worlds that do not pick it stay byte for byte.

The standard library only: the settings (`stamlane.synth.config`) check a world's name without loading the renderer.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal, get_args

__all__ = ["PART_VARIANTS", "WORLDS", "World"]

CameraVariant = Literal["fixed", "dashcam"]
MarkingsVariant = Literal["classic", "standards"]
SkyVariant = Literal["classic", "dashcam"]
SensorVariant = Literal["none", "dashcam"]
SurfaceVariant = Literal["asphalt", "jointed", "repaired"]
BarriersVariant = Literal["none", "barriers"]
LightsVariant = Literal["fixed", "sun"]
FurnitureVariant = Literal["none", "curbs_poles"]
VergesVariant = Literal["grass", "kinds"]
VehiclesVariant = Literal["boxes", "bodies"]


@dataclass(frozen=True)
class World:
    """What the clips of one world show: a variant of each scene part (`stamlane.synth.parts` says what each draws).

    Attributes:
        description: one line on what the world is for.
        camera: "fixed", the settings' horizon, field of view and height; "dashcam", spread per clip over dashcam
            ranges.
        markings: "classic", 2-4 m dashes and the settings' gaps; "standards", the dash, gap and width of a marking
            standard per clip, with raised pavement markers.
        sky: "classic", a pale gradient and a low tree line; "dashcam", clear blue or overcast with clouds, hills of
            a drawn height and the land's own colour beyond the road.
        sensor: "none"; "dashcam", blur, noise, exposure, vignetting and JPEG per clip (and the colour cast of
            ``SynthConfig.randomise``).
        surface: "asphalt", the classic asphalt; "jointed", concrete or asphalt with joints, seams, a shoulder of
            another shade and wheel paths; "repaired", the jointed surface with repair strips, sealed joints and cracks.
        barriers: "none"; "barriers", a concrete barrier and a guard rail beside the road.
        lights: "fixed", one low sun for the moving shadows; "sun", a sun drawn per clip that casts every shadow
            (the vehicles', the barriers', the poles').
        furniture: "none"; "curbs_poles", curbs on the sides without a barrier and lamp or sign poles.
        verges: "grass", the classic green verge; "kinds", grass, dirt, dry grass or gravel per side.
        vehicles: "boxes", box vehicles; "bodies", vehicles with wheels, body, cabin, glass and lights.
    """

    description: str
    camera: CameraVariant = "fixed"
    markings: MarkingsVariant = "classic"
    sky: SkyVariant = "classic"
    sensor: SensorVariant = "none"
    surface: SurfaceVariant = "asphalt"
    barriers: BarriersVariant = "none"
    lights: LightsVariant = "fixed"
    furniture: FurnitureVariant = "none"
    verges: VergesVariant = "grass"
    vehicles: VehiclesVariant = "boxes"

    def __post_init__(self) -> None:
        for part, variants in PART_VARIANTS.items():
            if getattr(self, part) not in variants:
                raise ValueError(f"a world's {part} must be one of {variants}, got {getattr(self, part)!r}")

    @property
    def randomisable(self) -> bool:
        """Whether ``SynthConfig.randomise`` means something here: its sensor draws the random colour cast."""
        return self.sensor == "dashcam"


PART_VARIANTS: dict[str, tuple[str, ...]] = {
    "camera": get_args(CameraVariant),
    "markings": get_args(MarkingsVariant),
    "sky": get_args(SkyVariant),
    "sensor": get_args(SensorVariant),
    "surface": get_args(SurfaceVariant),
    "barriers": get_args(BarriersVariant),
    "lights": get_args(LightsVariant),
    "furniture": get_args(FurnitureVariant),
    "verges": get_args(VergesVariant),
    "vehicles": get_args(VehiclesVariant),
}
"""The scene parts (`World`'s fields but ``description``, in their order) and the variants of each."""

_DASHCAM = World(
    "format 7's camera, markings, surfaces, barriers, skies and sensor effects",
    camera="dashcam",
    markings="standards",
    sky="dashcam",
    sensor="dashcam",
    surface="jointed",
    barriers="barriers",
)
_DASHCAM2 = replace(
    _DASHCAM,
    description="the dashcam world plus sun shadows, curbs, poles, surface repairs and vehicles with bodies",
    surface="repaired",
    lights="sun",
    furniture="curbs_poles",
    vehicles="bodies",
)
WORLDS: dict[str, World] = {
    "classic": World("the world of formats 1-6: a fixed camera, classic marks and asphalt, box vehicles"),
    "dashcam": _DASHCAM,
    "dashcam2": _DASHCAM2,
    "dashcam3": replace(_DASHCAM2, description="dashcam2 with dirt, dry grass or gravel verges", verges="kinds"),
}
"""Every world ``SynthConfig.world`` takes, by name (the name ``dataset.json`` records): a world is never changed
once a set was made of it (``tests/synth/test_splits_frozen.py``, ``test_scenery.py``); a new one is a new entry."""
