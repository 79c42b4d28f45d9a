"""Where the lane paint of a labelled point can be seen: in the key frame, only in its history, or nowhere.

Lane labels run through everything that hides the paint (vehicles, windscreen dirt, a washed-out frame, worn
paint, dash gaps), as TuSimple's do. What history frames can add to a detector is the paint the key frame does
not show and an earlier frame does. ``paint_visibility`` measures it for every labelled key-frame point of a
synthetic clip rendered with ``generate_clip(..., paint_contrast=True)``:

- the paint of a point is **visible in a frame** when it changes that frame by at least `VISIBLE_CONTRAST` grey
  levels within `WINDOW_PX` pixels of the point: the frame is rendered twice, with and without paint, from the
  same draws, after every effect (vehicles and their shadows, static shadows, the windscreen, glare, night and its
  noise), so this is what the camera records of the paint, whatever hides it;
- a history frame ``j`` frames back is looked at where the key frame's point lies on the ground in that frame,
  through the exact ground homography (exact alignment: what perfect pre-alignment shows).

The result per point is a bit mask over the frames (bit ``j`` = visible ``j`` frames back; bit 0 = the key frame),
from which `visibility_class` gives the class for a model of ``num_frames`` frames at ``stride``:
``"visible"`` (in the key frame), ``"revealed"`` (hidden in the key frame, visible in at least one of the model's
history frames), ``"hidden"`` (in none of them).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

__all__ = [
    "ABSENT",
    "VISIBILITY_CLASSES",
    "VISIBLE_CONTRAST",
    "WINDOW_PX",
    "paint_visibility",
    "visibility_class",
]

VISIBLE_CONTRAST = 20
"""Grey levels (of 255) by which the paint must change the frame near a point for the paint to count as visible:
well above the JPEG error of the stored frames (about 2-3 levels at quality 92) and the rounding of the rendering;
a worn stretch that kept a third of its paint on mid-grey asphalt is at about 40."""
WINDOW_PX = 2
"""Half-width (pixels) of the window around a point searched for the paint: the label is the mark's centre
line rounded to a pixel, and the paint of a far mark is one or two pixels wide."""
ABSENT = -1
"""The mask of a label entry without a point (TuSimple's x = -2)."""
VisibilityClass = Literal["visible", "revealed", "hidden"]
VISIBILITY_CLASSES: tuple[VisibilityClass, ...] = ("visible", "revealed", "hidden")


def _visible_at(contrast: np.ndarray, x: float, y: float) -> bool:
    """True when the paint contrast reaches `VISIBLE_CONTRAST` within `WINDOW_PX` of ``(x, y)`` (pixels)."""
    h, w = contrast.shape
    if not (0 <= x <= w - 1 and 0 <= y <= h - 1):
        return False
    cx, cy = round(x), round(y)
    window = contrast[max(cy - 1, 0) : cy + 2, max(cx - WINDOW_PX, 0) : cx + WINDOW_PX + 1]
    return bool(window.max() >= VISIBLE_CONTRAST)


def paint_visibility(
    lanes: list[list[int]],
    h_samples: list[int],
    contrasts: list[np.ndarray],
    key_from_hist: list[np.ndarray],
) -> list[list[int]]:
    """Bit masks of where the paint of each labelled point of a key frame is visible.

    Args:
        lanes: the key frame's TuSimple lanes (x per h_sample, negative = no point).
        h_samples: the label rows.
        contrasts: paint contrast (`SynthClip.paint_contrast`) of the key frame and the frames before it, key
            frame FIRST: ``contrasts[j]`` is the frame ``j`` frames back, (H, W) uint8.
        key_from_hist: ``key_from_hist[j]`` maps pixels of the frame ``j`` frames back to the key frame's, (3, 3)
            (exact ground homographies; ``key_from_hist[0]`` the identity).

    Returns:
        per lane, per h_sample: `ABSENT` where the label has no point, else a bit mask with bit ``j`` set when
        the paint is visible ``j`` frames back.
    """
    if len(contrasts) != len(key_from_hist):
        raise ValueError(f"expected one homography per frame, got {len(key_from_hist)} for {len(contrasts)} frames")
    hist_from_key = [np.linalg.inv(np.asarray(h, dtype=np.float64)) for h in key_from_hist]
    masks = []
    for lane in lanes:
        points = np.array([[x, y, 1.0] for x, y in zip(lane, h_samples)], dtype=np.float64)
        lane_mask = np.where(np.asarray(lane) < 0, ABSENT, 0).astype(np.int64)
        for j, (contrast, matrix) in enumerate(zip(contrasts, hist_from_key)):
            seen = points @ matrix.T
            for k in np.flatnonzero(lane_mask >= 0):
                if seen[k, 2] > 1e-9 and _visible_at(contrast, seen[k, 0] / seen[k, 2], seen[k, 1] / seen[k, 2]):
                    lane_mask[k] |= 1 << j
        masks.append(lane_mask.tolist())
    return masks


def visibility_class(mask: int, num_frames: int, stride: int = 1) -> VisibilityClass | None:
    """The class of one point (a mask of `paint_visibility`) for a model of ``num_frames`` frames taken every
    ``stride`` frames, key frame last; None for an `ABSENT` point.

    A history frame beyond the mask's reach counts as not showing the paint.
    """
    if num_frames < 1 or stride < 1:
        raise ValueError(f"num_frames and stride must be >= 1, got {num_frames} and {stride}")
    if mask < 0:
        return None
    if mask & 1:
        return "visible"
    if any(mask >> (k * stride) & 1 for k in range(1, num_frames)):
        return "revealed"
    return "hidden"
