"""Synthetic road frames seen from a moving camera, with the exact ground ``key_from_hist`` (tests, benchmark).

A bird's-eye road texture (asphalt grain, blotches, tar seams, dashed lane marks) is projected through
``egomotion.image_from_ground`` for each camera pose, so every frame is a true view of the same plane.
"""

from __future__ import annotations

import cv2
import numpy as np

from stamlane.align.egomotion import RoadCamera, image_from_ground

__all__ = ["render_road", "road_texture"]

PX_PER_M = 40.0  # texture resolution
ROAD_X = (-16.0, 16.0)  # metres, lateral extent of the texture
ROAD_Z = (-4.0, 120.0)  # metres, longitudinal extent (behind the camera too, so forward motion stays covered)


def road_texture(seed: int = 0, texture: float = 1.0) -> np.ndarray:
    """Bird's-eye road texture, uint8 ``(H_t, W_t)`` grey; row 0 is the far end (``Z = ROAD_Z[1]``).

    Args:
        seed: random seed.
        texture: strength of the asphalt texture (1 = ordinary road, 0.2 = weak texture, 0 = none).
    """
    rng = np.random.default_rng(seed)
    width = int((ROAD_X[1] - ROAD_X[0]) * PX_PER_M)
    height = int((ROAD_Z[1] - ROAD_Z[0]) * PX_PER_M)
    base = np.full((height, width), 95.0, np.float32)
    blotch = cv2.GaussianBlur(rng.normal(0, 1, (height // 8, width // 8)).astype(np.float32), (0, 0), 3)
    base += 25 * texture * cv2.resize(blotch / (blotch.std() + 1e-6), (width, height))
    base += 10 * texture * cv2.GaussianBlur(rng.normal(0, 1, (height, width)).astype(np.float32), (0, 0), 1.5)
    base += 14 * texture * rng.normal(0, 1, (height, width)).astype(np.float32)  # grain: aggregate, 2.5 cm
    for _ in range(int(60 * texture)):  # tar seams and cracks
        x0, z0 = rng.uniform(0, width), rng.uniform(0, height)
        angle = rng.uniform(0, np.pi)
        length = rng.uniform(40, 400)
        x1, z1 = x0 + length * np.cos(angle), z0 + length * np.sin(angle)
        cv2.line(base, (int(x0), int(z0)), (int(x1), int(z1)), float(rng.uniform(40, 70)), int(rng.integers(2, 6)))
    for lane_x in (-5.25, -1.75, 1.75, 5.25):  # 3.5 m lanes, 3 m dashes every 12 m (US highway)
        x = int((lane_x - ROAD_X[0]) * PX_PER_M)
        half = int(0.075 * PX_PER_M)
        solid = abs(lane_x) > 5
        phase = rng.uniform(0, 12)
        for z in np.arange(ROAD_Z[0] - 12 + phase, ROAD_Z[1], 12.0 if not solid else 1000.0):
            z_end = z + (3.0 if not solid else 1000.0)
            r0 = int((ROAD_Z[1] - min(z_end, ROAD_Z[1])) * PX_PER_M)
            r1 = int((ROAD_Z[1] - max(z, ROAD_Z[0])) * PX_PER_M)
            base[max(r0, 0) : max(r1, 0), x - half : x + half + 1] = 215
    return np.clip(base, 0, 255).astype(np.uint8)


def _texture_from_ground() -> np.ndarray:
    """``(3, 3)`` from ground ``(X, Z, 1)`` metres to texture pixels."""
    return np.array([[PX_PER_M, 0, -ROAD_X[0] * PX_PER_M], [0, -PX_PER_M, ROAD_Z[1] * PX_PER_M], [0, 0, 1]])


def render_road(
    texture: np.ndarray,
    camera: RoadCamera,
    *,
    yaw: float = 0.0,
    pitch: float = 0.0,
    forward: float = 0.0,
    color: bool = True,
) -> np.ndarray:
    """Render the road texture seen by ``camera`` at a pose (see ``egomotion.image_from_ground``).

    Returns:
        uint8 ``(H, W, 3)`` BGR (or ``(H, W)`` grey when ``color`` is False); sky above the vanishing line,
        the road fading into haze towards it.
    """
    image_from_ground_ = image_from_ground(camera, yaw, pitch, forward)
    image_from_texture = image_from_ground_ @ np.linalg.inv(_texture_from_ground())
    size = (camera.width, camera.height)
    road = cv2.warpPerspective(texture, image_from_texture, size, flags=cv2.INTER_LINEAR, borderValue=95)
    # each pixel's ground distance: w of ground_from_image; rays above the vanishing line have w <= 0
    ground_from_image = np.linalg.inv(image_from_ground_)
    ys, xs = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float32)
    w = ground_from_image[2, 0] * xs + ground_from_image[2, 1] * ys + ground_from_image[2, 2]
    z = (ground_from_image[1, 0] * xs + ground_from_image[1, 1] * ys + ground_from_image[1, 2]) / np.where(
        np.abs(w) < 1e-9, 1e-9, w
    )
    haze = np.where(w > 0, np.clip((z - 40.0) / 80.0, 0, 1), 1.0).astype(np.float32)
    sky = np.float32(185) - 0.05 * ys
    gray: np.ndarray = (road.astype(np.float32) * (1 - haze) + sky * haze).clip(0, 255).astype(np.uint8)
    if not color:
        return gray
    bgr: np.ndarray = cv2.merge([gray, gray, (gray.astype(np.float32) * 0.97).astype(np.uint8)])
    return bgr
