"""Overlay pictures: predicted (and annotated) lanes drawn on the original key frame."""

from __future__ import annotations

import cv2
import numpy as np

from stamlane.types import Lanes

__all__ = ["LANE_COLOURS", "draw_lanes"]

LANE_COLOURS: tuple[tuple[int, int, int], ...] = (
    (0, 0, 255),
    (0, 200, 0),
    (255, 0, 0),
    (0, 200, 255),
    (255, 0, 255),
    (255, 255, 0),
    (0, 128, 255),
    (128, 0, 255),
)
"""BGR colour of the i-th predicted lane (left to right), cycled."""


def draw_lanes(image: np.ndarray, lanes: Lanes, gt_lanes: Lanes | None = None, thickness: int = 0) -> np.ndarray:
    """Draw lanes on a copy of an image.

    Args:
        image: ``(H, W, 3)`` uint8 BGR, the ORIGINAL key frame (lanes are in its pixels).
        lanes: predicted lanes, ``(N, 2)`` ``(x, y)`` arrays; one colour each (``LANE_COLOURS``).
        gt_lanes: annotated lanes, drawn first as thin white lines (``None``: none).
        thickness: line width in pixels; 0 = ``max(2, W // 320)``.

    Returns:
        the picture, ``(H, W, 3)`` uint8 BGR.
    """
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected a (H, W, 3) uint8 image, got {image.shape} {image.dtype}")
    out = image.copy()
    width = thickness or max(2, image.shape[1] // 320)
    for lane in gt_lanes or []:
        pts = np.round(np.asarray(lane, dtype=np.float64)).astype(np.int32).reshape(-1, 1, 2)
        if len(pts) >= 2:
            cv2.polylines(out, [pts], False, (255, 255, 255), max(1, width // 2), cv2.LINE_AA)
    for i, lane in enumerate(lanes):
        pts = np.round(np.asarray(lane, dtype=np.float64)).astype(np.int32).reshape(-1, 1, 2)
        colour = LANE_COLOURS[i % len(LANE_COLOURS)]
        if len(pts) >= 2:
            cv2.polylines(out, [pts], False, colour, width, cv2.LINE_AA)
        for x, y in pts[:, 0]:
            cv2.circle(out, (int(x), int(y)), width, colour, -1, cv2.LINE_AA)
    return out
