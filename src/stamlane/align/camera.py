"""The one camera model of stamlane: a pinhole camera over a flat road (the synthetic clips, the ego-motion
homographies of ``stamlane.align.egomotion`` and their tests all use it).

World frame (metres): ``X`` to the right, ``Y`` up, ``Z`` forward along the road; the road is the plane
``Y = 0``. A camera pose is its ground position ``(x, z)``, its height, its heading ``yaw`` (radians,
positive turns towards +X) and its ``pitch`` (radians, positive looks down). Image pixels follow
``stamlane.types``: ``(u, v)`` with ``u`` right, ``v`` down, pixel centres at integers, so the image centre
of a ``W`` x ``H`` image is ``((W - 1) / 2, (H - 1) / 2)``, the default principal point (`Camera.centred`).

Because the road is a plane, each pose gives a homography ``image_from_ground`` mapping ground points
``(X, Z, 1)`` to image pixels; between two poses of one clip ``key_from_hist =
image_from_ground[key] @ inv(image_from_ground[hist])`` is exact for every road pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Camera", "Pose"]

NEAR_M = 0.3
"""Near clipping distance (metres along the optical axis) for projected polygons."""


@dataclass(frozen=True)
class Pose:
    """One camera pose: ground position ``(x, z)`` in metres, height in metres, yaw and pitch in radians."""

    x: float
    z: float
    height: float
    yaw: float
    pitch: float


@dataclass(frozen=True)
class Camera:
    """Intrinsics of a pinhole camera without distortion.

    Attributes:
        width: image width in pixels.
        height: image height in pixels.
        focal: focal length in pixels (square pixels).
        cx: principal point column.
        cy: principal point row (the horizon row at zero pitch).
    """

    width: int
    height: int
    focal: float
    cx: float
    cy: float

    @classmethod
    def for_size(cls, width: int, height: int, hfov_deg: float = 60.0, horizon: float = 0.42) -> Camera:
        """A camera of ``hfov_deg`` horizontal field of view whose level horizon lies at ``horizon * height``."""
        focal = (width / 2.0) / np.tan(np.radians(hfov_deg) / 2.0)
        return cls(width, height, float(focal), (width - 1) / 2.0, horizon * (height - 1))

    @classmethod
    def centred(cls, width: int, height: int, focal: float) -> Camera:
        """A camera whose principal point is the image centre ``((W - 1) / 2, (H - 1) / 2)``."""
        return cls(width, height, float(focal), (width - 1) / 2.0, (height - 1) / 2.0)

    def pitch_for_horizon(self, horizon_row: float) -> float:
        """The downward pitch (radians) that puts the horizon at image row ``horizon_row`` (`horizon_row`'s
        inverse)."""
        return float(np.arctan2(self.cy - horizon_row, self.focal))

    @property
    def K(self) -> np.ndarray:
        """Intrinsic matrix, (3, 3) float64."""
        return np.array([[self.focal, 0, self.cx], [0, self.focal, self.cy], [0, 0, 1.0]])

    def camera_from_world(self, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """Rotation ``R`` (3, 3) and camera centre ``c`` (3,) such that ``cam = R @ (p_world - c)``.

        Camera axes: x right, y down, z forward (OpenCV).
        """
        cy_, sy = np.cos(pose.yaw), np.sin(pose.yaw)
        cp, sp = np.cos(pose.pitch), np.sin(pose.pitch)
        flip_y = np.diag([1.0, -1.0, 1.0])  # world Y up -> camera y down
        r_yaw = np.array([[cy_, 0, -sy], [0, 1, 0], [sy, 0, cy_]])
        r_pitch = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
        return r_pitch @ r_yaw @ flip_y, np.array([pose.x, pose.height, pose.z])

    def image_from_ground(self, pose: Pose) -> np.ndarray:
        """Homography from ground points ``(X, Z, 1)`` (metres) to image pixels, (3, 3) float64.

        Not rescaled: the third homogeneous coordinate of a mapped point is its depth in metres
        (positive in front of the camera).
        """
        rot, centre = self.camera_from_world(pose)
        # p_world = (X, 0, Z) = G @ (X, Z, 1); cam = R @ (G @ g - c)
        ground = np.array([[1.0, 0, -centre[0]], [0, 0, -centre[1]], [0, 1.0, -centre[2]]])
        image_from_ground: np.ndarray = self.K @ rot @ ground
        return image_from_ground

    def horizon_row(self, pose: Pose) -> float:
        """Image row of the horizon (points at infinity on the ground); the camera has no roll."""
        row: float = self.cy - self.focal * np.tan(pose.pitch)
        return row

    def project(self, pose: Pose, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points.

        Args:
            pose: the camera pose.
            points: world points, (N, 3) metres.

        Returns:
            image points (N, 2) pixels, and depth along the optical axis (N,) metres (<= 0 behind).
        """
        rot, centre = self.camera_from_world(pose)
        cam = (points - centre) @ rot.T
        depth = cam[:, 2]
        safe = np.where(np.abs(depth) < 1e-9, 1e-9, depth)
        uv = np.stack([self.focal * cam[:, 0] / safe + self.cx, self.focal * cam[:, 1] / safe + self.cy], axis=1)
        return uv, depth

    def project_polygon(self, pose: Pose, polygon: np.ndarray) -> np.ndarray | None:
        """Project a planar world polygon, clipped at the near plane.

        Args:
            pose: the camera pose.
            polygon: vertices, (N, 3) metres, in order.

        Returns:
            image polygon (M, 2) float pixels, or None when nothing lies in front of the camera.
        """
        rot, centre = self.camera_from_world(pose)
        cam = (polygon - centre) @ rot.T
        clipped = _clip_near(cam, NEAR_M)
        if len(clipped) < 3:
            return None
        return np.stack(
            [
                self.focal * clipped[:, 0] / clipped[:, 2] + self.cx,
                self.focal * clipped[:, 1] / clipped[:, 2] + self.cy,
            ],
            axis=1,
        )


def _clip_near(cam: np.ndarray, near: float) -> np.ndarray:
    """Sutherland-Hodgman clipping of a camera-frame polygon (N, 3) against the plane ``z >= near``."""
    out = []
    n = len(cam)
    for i in range(n):
        a, b = cam[i], cam[(i + 1) % n]
        a_in, b_in = a[2] >= near, b[2] >= near
        if a_in:
            out.append(a)
        if a_in != b_in:
            t = (near - a[2]) / (b[2] - a[2])
            out.append(a + t * (b - a))
    return np.array(out).reshape(-1, 3)
