"""Training targets of a key frame: binary and instance lane masks at the network resolution."""

from __future__ import annotations

import warnings

import cv2
import numpy as np

from stamlane.data.labels import DataError

__all__ = ["MAX_TRAINING_LANES", "draw_lane_targets", "left_to_right"]

MAX_TRAINING_LANES = 255
"""Lanes one training frame may hold: their ids are drawn into an 8-bit instance mask (the evaluators score more)."""
_SHIFT = 4  # sub-pixel bits for cv2 drawing: points are drawn at 1/16 px precision


def left_to_right(lanes: list[np.ndarray]) -> list[int]:
    """Indices that sort lanes from left to right.

    Lanes are compared at one shared row: the lowest row every lane reaches (the smallest of the lanes'
    bottom rows) when every lane spans it; otherwise each lane is represented by the x of its bottom
    (largest-y) point. Lanes converge towards the horizon, so the bottom is where they are apart.

    Args:
        lanes: ``(N, 2)`` arrays of ``(x, y)`` points, each with at least one point.
    """
    if len(lanes) < 2:
        return list(range(len(lanes)))
    bottoms = [float(lane[:, 1].max()) for lane in lanes]
    tops = [float(lane[:, 1].min()) for lane in lanes]
    row = min(bottoms)
    if all(t <= row <= b for t, b in zip(tops, bottoms)):
        keys = []
        for lane in lanes:
            order = np.argsort(lane[:, 1])
            keys.append(float(np.interp(row, lane[order, 1], lane[order, 0])))
    else:
        keys = [float(lane[np.argmax(lane[:, 1]), 0]) for lane in lanes]
    return sorted(range(len(lanes)), key=lambda i: keys[i])


def draw_lane_targets(
    lanes: list[np.ndarray], size: tuple[int, int], thickness: int = 3, source: str = ""
) -> tuple[np.ndarray, np.ndarray]:
    """Draw lanes as polylines into binary and instance masks.

    Args:
        lanes: lanes in NETWORK pixels, ``(N, 2)`` float ``(x, y)``; lanes with fewer than 2 points are
            skipped with a warning naming ``source``.
        size: ``(H, W)`` of the masks (the network input size).
        thickness: line width in network pixels.
        source: the label file, for the warning.

    Returns:
        ``binary`` int64 (H, W) (1 on lanes) and ``instance`` int64 (H, W) (0 background, lanes 1..n from
        left to right as seen in the network image; where two lanes touch the higher id wins). Lines are
        1-px polylines dilated by a disk of diameter ``thickness``.

    Raises:
        DataError: more than `MAX_TRAINING_LANES` lanes of two points or more.
    """
    if thickness < 1:
        raise ValueError(f"thickness must be >= 1, got {thickness}")
    h, w = size
    usable = []
    for i, lane in enumerate(lanes):
        if len(lane) < 2:
            warnings.warn(f"{source or 'lane labels'}: lane {i} has {len(lane)} point(s); skipped", stacklevel=2)
            continue
        usable.append(lane)
    if len(usable) > MAX_TRAINING_LANES:  # the evaluators score up to 512; ids past 255 would merge in uint8
        raise DataError(f"{source or 'lane labels'}: {len(usable)} lanes in one frame; at most {MAX_TRAINING_LANES}")
    instance: np.ndarray = np.zeros((h, w), np.uint8)  # uint8; cv2.dilate keeps it
    for k, idx in enumerate(left_to_right(usable), start=1):
        order = np.argsort(usable[idx][:, 1])
        pts = np.round(usable[idx][order] * (1 << _SHIFT)).astype(np.int32)
        cv2.polylines(instance, [pts], False, k, 1, lineType=cv2.LINE_8, shift=_SHIFT)
    if thickness > 1:  # a disk of the asked diameter: cv2's own thick lines come out ~2 px wider
        disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (thickness, thickness))
        instance = cv2.dilate(instance, disk)
    instance64 = instance.astype(np.int64)
    return (instance64 > 0).astype(np.int64), instance64
