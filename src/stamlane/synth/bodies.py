"""Vehicles with bodies (the dashcam2 and dashcam3 worlds, `stamlane.synth.scenery`): wheels, a body and a narrower
cabin with slanted glass for cars, a cab and a cargo box on a chassis for trucks, tail lights, number plate and bumper
at the rear, headlights and grille at the front, seen from behind and from the side.

The vehicles move as `stamlane.synth.vehicles.Vehicle` says (on the `stamlane.synth.road.Road`); this module only
draws them, after the ground, the scenery and the shadows, so that the ground modules never import the vehicles.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from stamlane.align.camera import Camera, Pose
from stamlane.synth.dashcam import fill_world_polygon
from stamlane.synth.road import Road
from stamlane.synth.vehicles import Vehicle

__all__ = ["BodyStyle", "draw_bodies"]


@dataclass(frozen=True)
class BodyStyle:
    """How one vehicle's box is drawn: ``cabin`` ``(rear, front)``: fractions of its length where a car's cabin
    stands (glass from ``belt`` of its height up), ``glass`` BGR of its windows, ``lights`` BGR of its tail lights."""

    cabin: tuple[float, float]
    belt: float
    glass: tuple[float, float, float]
    lights: tuple[float, float, float]

    @classmethod
    def sample(cls, rng: np.random.Generator, boxy: bool) -> BodyStyle:
        rear = float(rng.uniform(0.02, 0.08) if boxy else rng.uniform(0.12, 0.25))
        front = float(rng.uniform(0.6, 0.72))
        tint = float(rng.uniform(25, 70))
        return cls(
            (rear, front),
            float(rng.uniform(0.5, 0.6)),
            (tint * 1.1, tint, tint * 0.9),
            (float(rng.uniform(20, 50)), float(rng.uniform(20, 50)), float(rng.uniform(170, 235))),
        )


def _box(
    origin: np.ndarray,
    right: np.ndarray,
    fwd: np.ndarray,
    u: tuple[float, float],
    y: tuple[float, float],
    s: tuple[float, float],
    inset: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """The 8 corners (as `Vehicle.corners`: bottom rear-left, rear-right, front-right, front-left, then the top) of a
    box in a vehicle's frame: ``u`` across (right), ``y`` up, ``s`` along (from the rear); ``inset``: how far the top
    face is drawn in at the sides, the rear and the front (slanted glass)."""
    side, back, front = inset
    layers = []
    for height, du, ds0, ds1 in ((y[0], 0.0, 0.0, 0.0), (y[1], side, back, front)):
        for uu, ss in (
            (u[0] + du, s[0] + ds0),
            (u[1] - du, s[0] + ds0),
            (u[1] - du, s[1] - ds1),
            (u[0] + du, s[1] - ds1),
        ):
            p = origin + uu * right + ss * fwd
            layers.append((p[0], height, p[1]))
    return np.array(layers, np.float64)


_FACES = {"rear": (0, 1, 5, 4), "front": (2, 3, 7, 6), "left": (3, 0, 4, 7), "right": (1, 2, 6, 5), "top": (4, 5, 6, 7)}
_SHADE = {"rear": 0.78, "front": 0.82, "left": 0.62, "right": 0.62, "top": 1.0}


def _visible_faces(corners: np.ndarray, cam: np.ndarray) -> list[str]:
    centre = corners.mean(axis=0)
    names = []
    for name, idx in _FACES.items():
        face = corners[list(idx)]
        fc = face.mean(axis=0)
        normal = np.cross(face[1] - face[0], face[3] - face[0])
        if np.dot(normal, fc - centre) < 0:
            normal = -normal
        if np.dot(normal, cam - fc) > 0:
            names.append(name)
    return names


def _draw_box(
    frame: np.ndarray,
    mask: np.ndarray,
    camera: Camera,
    pose: Pose,
    corners: np.ndarray,
    colour: tuple[float, ...],
    faces: Mapping[str, tuple[float, ...]] | None = None,
    only: tuple[str, ...] = tuple(_FACES),
) -> list[str]:
    """Draw a box's faces that face the camera (``faces``: a colour per face name instead of the shaded ``colour``;
    ``only``: of these faces); returns their names."""
    cam = np.array([pose.x, pose.height, pose.z])
    names = [name for name in _visible_faces(corners, cam) if name in only]
    for name in names:
        col = (faces or {}).get(name) or tuple(c * _SHADE[name] for c in colour)
        fill_world_polygon(frame, camera, pose, corners[list(_FACES[name])], col, mask)
    return names


def _panel(
    frame: np.ndarray,
    camera: Camera,
    pose: Pose,
    face: np.ndarray,
    a: tuple[float, float],
    b: tuple[float, float],
    colour: tuple[float, ...],
) -> None:
    """A rectangle on a face (4 corners: bottom-left, bottom-right, top-right, top-left) from fractions ``a`` = (across,
    up) to ``b``."""
    bl, br, _tr, tl = face
    across, up = br - bl, tl - bl
    quad = np.array(
        [
            bl + a[0] * across + a[1] * up,
            bl + b[0] * across + a[1] * up,
            bl + b[0] * across + b[1] * up,
            bl + a[0] * across + b[1] * up,
        ]
    )
    fill_world_polygon(frame, camera, pose, quad, colour)


def draw_bodies(
    frame: np.ndarray,
    mask: np.ndarray,
    vehicles: list[Vehicle],
    styles: list[BodyStyle],
    road: Road,
    camera: Camera,
    pose: Pose,
    t: float,
) -> None:
    """Draw the vehicles (`stamlane.synth.vehicles.Vehicle`, each with its `BodyStyle`) far to near into ``frame``
    with wheels, body, cabin or cargo box, glass and lights, and mark their pixels in ``mask``: what
    `stamlane.synth.vehicles.draw_vehicles` draws as boxes."""
    cam = np.array([pose.x, pose.height, pose.z])
    order = sorted(
        range(len(vehicles)), key=lambda i: -np.hypot(*(np.array(vehicles[i].state(road, t)[:2]) - [pose.x, pose.z]))
    )
    for i in order:
        v, style = vehicles[i], styles[i]
        x, z, heading = v.state(road, t)
        fwd = np.array([np.sin(heading), np.cos(heading)])
        right = np.array([np.cos(heading), -np.sin(heading)])
        origin = np.array([x, z])
        half, length, height = v.width / 2.0, v.length, v.height
        colour = tuple(float(c) for c in v.colour)
        truck = height > 2.5
        radius = 0.5 if truck else 0.33
        axles = (1.1, 2.4, length - 1.3) if truck else (0.85, length - 0.95)
        wheels = [
            (_box(origin, right, fwd, (u - 0.13, u + 0.13), (0.0, 2 * radius), (s - radius, s + radius)), u)
            for s in axles
            for u in (-half + 0.14, half - 0.14)
        ]
        # the tyres on the camera's side show their outer face in front of the body; every tyre is drawn whole behind it
        near = [(w, "right" if u > 0 else "left") for w, u in wheels if np.dot(u * right, cam[[0, 2]] - origin) > 0]
        for w, _ in wheels:
            _draw_box(frame, mask, camera, pose, w, (28, 28, 30))
        if truck:
            chassis = _box(origin, right, fwd, (-half + 0.3, half - 0.3), (0.45, 1.0), (0.0, length))
            _draw_box(frame, mask, camera, pose, chassis, (35, 35, 38))
            cargo = _box(origin, right, fwd, (-half, half), (1.0, height), (0.0, length - 2.6))
            drawn = _draw_box(frame, mask, camera, pose, cargo, colour)
            if "rear" in drawn:
                rear = cargo[list(_FACES["rear"])]
                _panel(frame, camera, pose, rear, (0.495, 0.02), (0.505, 0.98), (60, 60, 60))  # the doors' seam
                for a, b in (((0.03, 0.02), (0.13, 0.1)), ((0.87, 0.02), (0.97, 0.1))):
                    _panel(frame, camera, pose, rear, a, b, style.lights)
            cab = _box(
                origin,
                right,
                fwd,
                (-half + 0.05, half - 0.05),
                (0.5, height - 0.4),
                (length - 2.4, length),
                (0.05, 0.0, 0.3),
            )
            drawn = _draw_box(frame, mask, camera, pose, cab, (210, 210, 205))
            if "front" in drawn:
                _panel(frame, camera, pose, cab[list(_FACES["front"])], (0.05, 0.55), (0.95, 0.92), style.glass)
        else:
            body_top = style.belt * height
            body = _box(origin, right, fwd, (-half, half), (0.25, body_top), (0.0, length))
            drawn = _draw_box(frame, mask, camera, pose, body, colour)
            rear, front = body[list(_FACES["rear"])], body[list(_FACES["front"])]
            if "rear" in drawn:
                _panel(frame, camera, pose, rear, (0.0, 0.0), (1.0, 0.22), (35, 35, 38))  # bumper
                _panel(frame, camera, pose, rear, (0.4, 0.3), (0.6, 0.5), (215, 215, 210))  # number plate
                for a, b in (((0.02, 0.55), (0.2, 0.85)), ((0.8, 0.55), (0.98, 0.85))):
                    _panel(frame, camera, pose, rear, a, b, style.lights)
            if "front" in drawn:
                _panel(frame, camera, pose, front, (0.3, 0.25), (0.7, 0.6), (40, 40, 42))  # grille
                for a, b in (((0.03, 0.55), (0.22, 0.85)), ((0.78, 0.55), (0.97, 0.85))):
                    _panel(frame, camera, pose, front, a, b, (170, 225, 235))
            s0, s1 = style.cabin[0] * length, style.cabin[1] * length + 0.6
            slant = min(0.5, (s1 - s0) / 4)
            cabin = _box(
                origin,
                right,
                fwd,
                (-half + 0.08, half - 0.08),
                (body_top, height),
                (s0, s1),
                (0.12, slant * 0.6, slant),
            )
            glass = {name: style.glass for name in ("rear", "front", "left", "right")}
            _draw_box(frame, mask, camera, pose, cabin, colour, glass)
        for w, outer in near:
            _draw_box(frame, mask, camera, pose, w, (28, 28, 30), only=(outer,))
