"""Ground-plane homographies of a moving pinhole camera (for generating pairs with a known ``key_from_hist``).

Frames: camera x right, y down, z forward; the ground is the plane ``y = camera_height`` of the world frame,
which is the history camera's frame before its pitch. A ground point is ``(X, Z)`` in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Camera", "image_from_ground", "key_from_hist_motion", "rotation"]


@dataclass(frozen=True)
class Camera:
    """A pinhole camera above a flat road.

    Attributes:
        width: image width in pixels.
        height: image height in pixels.
        focal: focal length in pixels.
        horizon_row: image row of the vanishing line (sets the camera's pitch).
        camera_height: metres above the road.
    """

    width: int = 1280
    height: int = 720
    focal: float = 1000.0
    horizon_row: float = 280.0
    camera_height: float = 1.5

    @property
    def K(self) -> np.ndarray:
        """``(3, 3)`` intrinsics with the principal point at the image centre."""
        return np.array([[self.focal, 0, self.width / 2], [0, self.focal, self.height / 2], [0, 0, 1.0]])

    @property
    def pitch(self) -> float:
        """Downward pitch in radians that puts the vanishing line at ``horizon_row``."""
        return float(np.arctan2(self.height / 2 - self.horizon_row, self.focal))


def rotation(yaw: float = 0.0, pitch: float = 0.0) -> np.ndarray:
    """``(3, 3)`` camera_from_world rotation for a yaw (right positive) and a downward pitch, radians."""
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    r_yaw = np.array([[cy, 0, -sy], [0, 1, 0], [sy, 0, cy]])
    r_pitch = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    return r_pitch @ r_yaw


def image_from_ground(camera: Camera, yaw: float = 0.0, pitch: float = 0.0, forward: float = 0.0) -> np.ndarray:
    """``(3, 3)`` homography from ground ``(X, Z, 1)`` metres to pixels for a camera moved ``forward``
    metres along the world z axis, turned by ``yaw`` and pitched by ``camera.pitch + pitch`` radians."""
    r = rotation(yaw, camera.pitch + pitch)
    centre = np.array([0.0, 0.0, forward])
    ground = np.stack([[1.0, 0, 0], [0, 0, 1.0], np.array([0, camera.camera_height, 0]) - centre], axis=1)
    return camera.K @ r @ ground


def key_from_hist_motion(
    camera: Camera, forward: float, yaw: float = 0.0, pitch: float = 0.0, hist_yaw: float = 0.0
) -> np.ndarray:
    """``(3, 3)`` ``key_from_hist`` of the ground when the camera moved ``forward`` metres and turned by
    ``yaw`` / ``pitch`` radians between the history and the key frame (normalised to ``H[2, 2] = 1``)."""
    h = image_from_ground(camera, hist_yaw + yaw, pitch, forward) @ np.linalg.inv(image_from_ground(camera, hist_yaw))
    return h / h[2, 2]
