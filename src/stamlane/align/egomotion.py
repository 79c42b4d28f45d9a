"""Ground-plane homographies of a moving camera, for pairs with a known ``key_from_hist`` (tests, benchmarks).

The camera model is ``stamlane.align.camera`` (the synthetic generator's): pixel centres at integers, principal point
at the image centre ``((W - 1) / 2, (H - 1) / 2)``. A `RoadCamera` is that camera mounted on a car: its height
above the road and the image row of the horizon (which sets its pitch). The history frame's camera stands at
the origin of the road; the key frame's has moved ``forward`` metres and turned.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stamlane.align.camera import Camera, Pose

__all__ = ["RoadCamera", "image_from_ground", "key_from_hist_motion"]


@dataclass(frozen=True)
class RoadCamera:
    """A `stamlane.align.camera.Camera` (principal point at the image centre) mounted above a flat road.

    Attributes:
        width: image width in pixels.
        height: image height in pixels.
        focal: focal length in pixels.
        horizon_row: image row of the horizon (sets the camera's pitch).
        camera_height: metres above the road.
    """

    width: int = 1280
    height: int = 720
    focal: float = 1000.0
    horizon_row: float = 280.0
    camera_height: float = 1.5

    @property
    def camera(self) -> Camera:
        """The intrinsics: the one camera model, principal point at the image centre."""
        return Camera.centred(self.width, self.height, self.focal)

    @property
    def K(self) -> np.ndarray:
        """``(3, 3)`` intrinsics."""
        return self.camera.K

    @property
    def pitch(self) -> float:
        """Downward pitch in radians that puts the horizon at ``horizon_row``."""
        return self.camera.pitch_for_horizon(self.horizon_row)

    def pose(self, forward: float = 0.0, yaw: float = 0.0, pitch: float = 0.0) -> Pose:
        """The camera ``forward`` metres along the road, turned by ``yaw`` and pitched ``pitch`` radians more."""
        return Pose(0.0, forward, self.camera_height, yaw, self.pitch + pitch)


def image_from_ground(camera: RoadCamera, yaw: float = 0.0, pitch: float = 0.0, forward: float = 0.0) -> np.ndarray:
    """``(3, 3)`` homography from ground ``(X, Z, 1)`` metres to pixels for the camera moved ``forward``
    metres along the road, turned by ``yaw`` and pitched by ``camera.pitch + pitch`` radians."""
    return camera.camera.image_from_ground(camera.pose(forward, yaw, pitch))


def key_from_hist_motion(
    camera: RoadCamera, forward: float, yaw: float = 0.0, pitch: float = 0.0, hist_yaw: float = 0.0
) -> np.ndarray:
    """``(3, 3)`` ``key_from_hist`` of the ground when the camera moved ``forward`` metres and turned by
    ``yaw`` / ``pitch`` radians between the history and the key frame (normalised to ``H[2, 2] = 1``)."""
    h = image_from_ground(camera, hist_yaw + yaw, pitch, forward) @ np.linalg.inv(image_from_ground(camera, hist_yaw))
    normalised: np.ndarray = h / h[2, 2]
    return normalised
