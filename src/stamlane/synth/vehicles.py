"""Vehicles of a synthetic clip: boxes that drive on the road, occlude lane marks and cast shadows.

A vehicle keeps a lateral offset from the road centre (changing lanes when asked) and its own speed, so
it moves relative to the ROAD (not only relative to the camera): after ground-plane alignment of the
history frames it sits elsewhere, and what it hides in the key frame an earlier frame may show.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stamlane.align.camera import Camera, Pose
from stamlane.synth.road import Road

__all__ = ["Vehicle", "draw_vehicles", "sample_vehicles", "shadow_polygons"]

SUN = np.array([1.3, 0.5])
"""Ground displacement (X, Z) of a cast shadow per metre of object height: a low sun, so the moving shadow
of a vehicle falls across the next lane mark (paint an aligned history frame shows unshadowed)."""


@dataclass
class Vehicle:
    """A box vehicle: ground state at ``t = 0`` and constant speeds; sizes in metres, colour BGR."""

    z0: float
    offset0: float
    speed: float
    lateral_speed: float
    change_start: float
    change_duration: float
    width: float
    length: float
    height: float
    colour: tuple[int, int, int]

    def state(self, road: Road, t: float) -> tuple[float, float, float]:
        """Rear-centre ground position ``(x, z)`` and heading (radians) at time ``t`` seconds."""
        z = self.z0 + self.speed * t
        active = np.clip((t - self.change_start) / max(self.change_duration, 1e-6), 0.0, 1.0)
        offset = self.offset0 + self.lateral_speed * self.change_duration * float(active)
        lat_v = self.lateral_speed if 0.0 < active < 1.0 else 0.0
        heading = float(np.arctan(road.slope(z)) + np.arctan2(lat_v, max(self.speed, 1e-3)))
        return float(road.centre(z) + offset), float(z), heading

    def corners(self, road: Road, t: float) -> np.ndarray:
        """The 8 box corners in world coordinates (8, 3): bottom 4 then top 4, rear-left first."""
        x, z, hd = self.state(road, t)
        fwd = np.array([np.sin(hd), np.cos(hd)])
        right = np.array([np.cos(hd), -np.sin(hd)])
        half = self.width / 2.0
        base = [
            np.array([x, z]) - half * right,
            np.array([x, z]) + half * right,
            np.array([x, z]) + half * right + self.length * fwd,
            np.array([x, z]) - half * right + self.length * fwd,
        ]
        bottom = [np.array([p[0], 0.0, p[1]]) for p in base]
        top = [np.array([p[0], self.height, p[1]]) for p in base]
        return np.array(bottom + top)


def sample_vehicles(
    rng: np.random.Generator,
    road: Road,
    ego_speed: float,
    duration: float,
    *,
    count: int,
    ego_track: np.ndarray,
    lane_change_prob: float = 0.3,
    truck_prob: float = 0.2,
    oncoming_prob: float = 0.4,
    ahead: tuple[float, float] = (3.0, 30.0),
    speed_ratio: tuple[float, float] = (0.35, 1.25),
) -> list[Vehicle]:
    """Draw ``count`` vehicles spread over the lanes, near the camera's path.

    Args:
        ego_track: the camera's ``(t, x, z)`` per frame, (T, 3); no vehicle comes within 5 m ahead of it
            (or beside it) in its own lane, and vehicles do not overlap at ``t = 0``.
        ahead: range (metres) of a vehicle's distance ahead of the camera's final position at the key frame.
        speed_ratio: range of a vehicle's speed on the road as a multiple of ``ego_speed`` (negative: towards
            the camera); oncoming lanes (``oncoming_prob``) override it.
    """
    offsets = np.array([m.offset for m in road.marks])
    lane_centres = (offsets[:-1] + offsets[1:]) / 2.0
    # lanes left of the ego lane carry oncoming traffic on some roads (only those move backwards on the road)
    ego_x = float(ego_track[-1, 1] - road.centre(ego_track[-1, 2]))
    oncoming = rng.random() < oncoming_prob
    vehicles: list[Vehicle] = []
    for _ in range(count * 6):
        if len(vehicles) >= count:
            break
        lane = int(rng.integers(0, len(lane_centres)))
        truck = rng.random() < truck_prob
        width, length, height = (
            (2.5, float(rng.uniform(8, 12)), 3.4) if truck else (1.8, 4.5, float(rng.uniform(1.4, 1.7)))
        )
        speed = ego_speed * float(rng.uniform(*speed_ratio))
        if oncoming and lane_centres[lane] < ego_x - 0.5 * road.lane_width:
            speed = -float(rng.uniform(10, 25))
        # where it is when the key frame is taken: ``ahead`` metres ahead of the ego's final position
        z_end = ego_speed * duration + float(rng.uniform(*ahead))
        z0 = z_end - speed * duration
        offset0 = float(lane_centres[lane] + rng.uniform(-0.3, 0.3))
        lateral_speed, start, dur = 0.0, 0.0, 1.0
        if speed > 0 and rng.random() < lane_change_prob and len(lane_centres) > 1:
            target = lane + int(rng.choice([-1, 1]))
            target = min(max(target, 0), len(lane_centres) - 1)
            if target == lane:
                target = lane + 1 if lane + 1 < len(lane_centres) else lane - 1
            dur = float(rng.uniform(1.0, 2.5))
            start = float(rng.uniform(-0.5 * dur, duration - 0.3 * dur))
            lateral_speed = (lane_centres[target] - lane_centres[lane]) / dur
        blue, green, red = (int(c) for c in rng.integers(20, 230, 3))
        v = Vehicle(
            z0,
            offset0,
            speed,
            float(lateral_speed),
            start,
            dur,
            width,
            length,
            height,
            (blue, green, red),
        )
        clash = any(
            abs(o.offset0 - v.offset0) < 2.5 and abs(o.z0 - v.z0) < max(o.length, v.length) + 3 for o in vehicles
        )
        if not clash and not _hits_ego(v, road, ego_track):
            vehicles.append(v)
    return vehicles


def _hits_ego(v: Vehicle, road: Road, ego_track: np.ndarray) -> bool:
    for t, x, z in ego_track:
        vx, vz, _ = v.state(road, float(t))
        if abs(vx - x) < (v.width / 2 + 1.6) and -v.length - 2.0 < vz - z < 5.0:
            return True
    return False


def shadow_polygons(vehicle: Vehicle, road: Road, t: float, sun: np.ndarray = SUN) -> list[np.ndarray]:
    """Ground polygons (each (4, 3) world points) of a vehicle's contact shadow and cast shadow; ``sun``: the ground
    displacement ``(X, Z)`` of the shadow per metre of height (`SUN`; the dashcam2 world's clip's
    `stamlane.synth.scenery.Sun.displacement`)."""
    c = vehicle.corners(road, t)
    bottom = c[:4].copy()
    centre = bottom.mean(axis=0)
    contact = centre + (bottom - centre) * 1.12
    cast = bottom.copy()
    cast[:, 0] += sun[0] * vehicle.height
    cast[:, 2] += sun[1] * vehicle.height
    hull = cv2.convexHull(np.concatenate([bottom[:, [0, 2]], cast[:, [0, 2]]]).astype(np.float32))[:, 0]
    cast_poly = np.stack([hull[:, 0], np.zeros(len(hull)), hull[:, 1]], axis=1).astype(np.float64)
    return [contact, cast_poly]


_FACES = [  # indices into Vehicle.corners, with a brightness factor
    ((0, 1, 5, 4), 0.75),  # rear
    ((2, 3, 7, 6), 0.8),  # front
    ((3, 0, 4, 7), 0.6),  # left
    ((1, 2, 6, 5), 0.6),  # right
    ((4, 5, 6, 7), 1.0),  # top
]


def draw_vehicles(
    frame: np.ndarray, mask: np.ndarray, vehicles: list[Vehicle], road: Road, camera: Camera, pose: Pose, t: float
) -> None:
    """Draw the vehicles far to near into ``frame`` (BGR uint8, in place) and mark their pixels in ``mask``."""
    cam_pos = np.array([pose.x, pose.height, pose.z])
    order = sorted(vehicles, key=lambda v: -np.hypot(*(np.array(v.state(road, t)[:2]) - [pose.x, pose.z])))
    for v in order:
        corners = v.corners(road, t)
        centre = corners.mean(axis=0)
        for idx, bright in _FACES:
            face = corners[list(idx)]
            fc = face.mean(axis=0)
            normal = np.cross(face[1] - face[0], face[3] - face[0])
            if np.dot(normal, fc - centre) < 0:
                normal = -normal
            if np.dot(normal, cam_pos - fc) <= 0:
                continue  # faces away from the camera
            poly = camera.project_polygon(pose, face)
            if poly is None:
                continue
            pts = np.round(poly * 16).astype(np.int32)
            col = tuple(int(c * bright) for c in v.colour)
            cv2.fillPoly(frame, [pts], col, lineType=cv2.LINE_AA, shift=4)
            cv2.fillPoly(mask, [pts], 255, shift=4)
            if idx == (0, 1, 5, 4):  # rear window and lights, for texture on the occluder
                _rear_details(frame, camera, pose, face)


def _rear_details(frame: np.ndarray, camera: Camera, pose: Pose, rear: np.ndarray) -> None:
    bl, br, _tr, tl = rear
    up = tl - bl
    right = br - bl
    window = np.array(
        [
            bl + 0.62 * up + 0.1 * right,
            bl + 0.62 * up + 0.9 * right,
            bl + 0.92 * up + 0.85 * right,
            bl + 0.92 * up + 0.15 * right,
        ]
    )
    for quad, col in [
        (window, (40, 35, 30)),
        (
            np.array([bl + 0.35 * up, bl + 0.35 * up + 0.18 * right, bl + 0.48 * up + 0.18 * right, bl + 0.48 * up]),
            (30, 30, 200),
        ),
        (
            np.array([bl + 0.35 * up + 0.82 * right, br + 0.35 * up, br + 0.48 * up, bl + 0.48 * up + 0.82 * right]),
            (30, 30, 200),
        ),
    ]:
        poly = camera.project_polygon(pose, quad)
        if poly is not None:
            cv2.fillPoly(frame, [np.round(poly * 16).astype(np.int32)], col, lineType=cv2.LINE_AA, shift=4)
