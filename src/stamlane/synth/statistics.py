"""What a rendered clip offers a detector that reads its history: the numbers ``dataset.json`` records.

`clip_statistics` counts the key-frame points an occluder hides and those an aligned history frame shows;
`key_frame_visibility` gives, per labelled key-frame point, the frames where its paint is visible
(`stamlane.synth.visibility`); `visibility_shares` sums those masks into the share of points per class.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stamlane.synth.clip import SynthClip
from stamlane.synth.layout import FIRST_KEY
from stamlane.synth.visibility import VISIBILITY_CLASSES, paint_visibility, visibility_class

__all__ = ["clip_statistics", "key_frame_visibility", "visibility_shares"]


def clip_statistics(clip: SynthClip, num_frames: int = 4, stride: int = 1) -> dict[str, float]:
    """What a clip offers the fusion of its last ``num_frames`` frames.

    Returns:
        ``key_points``: labelled key-frame points; ``hidden``: of those hidden by a vehicle;
        ``revealed``: hidden ones visible in at least one ground-aligned history frame;
        ``unaligned_shift``: mean |x| difference (px) of a lane point between the oldest history frame
        and the key frame without alignment (what pre-alignment repairs).
    """
    key = len(clip.frames) - 1
    hist = [key - stride * k for k in range(1, num_frames) if key - stride * k >= 0]
    h, w = clip.vehicle_masks[key].shape
    hidden = revealed = points = 0
    for lane, occ in zip(clip.labels[key], clip.occluded[key]):
        for x, y, o in zip(lane, clip.h_samples, occ):
            if x < 0:
                continue
            points += 1
            if not o:
                continue
            hidden += 1
            for j in hist:
                p = np.linalg.inv(clip.key_from_hist(key, j)) @ np.array([x, y, 1.0])
                u, v = p[:2] / p[2]
                if 0 <= u < w and 0 <= v < h and clip.vehicle_masks[j][int(v), int(u)] == 0:
                    revealed += 1
                    break
    shift, count = 0.0, 0
    if hist:
        old = hist[-1]
        for lk in clip.labels[key]:
            best = None
            for lo in clip.labels[old]:
                both = [(a, b) for a, b in zip(lk, lo) if a >= 0 and b >= 0]
                if both:
                    d = float(np.mean([abs(a - b) for a, b in both]))
                    best = d if best is None else min(best, d)
            if best is not None:
                shift += best
                count += 1
    return {"key_points": points, "hidden": hidden, "revealed": revealed, "unaligned_shift": shift / max(count, 1)}


def key_frame_visibility(clip: SynthClip, key: int, reach: int = FIRST_KEY) -> list[list[int]]:
    """`stamlane.synth.visibility.paint_visibility` of key frame ``key`` (0-based) of a clip rendered with
    ``paint_contrast``, over the key frame and up to ``reach`` frames before it."""
    if clip.paint_contrast is None:
        raise ValueError("the clip was rendered without paint_contrast")
    back = range(min(reach, key) + 1)
    return paint_visibility(
        clip.labels[key],
        clip.h_samples,
        [clip.paint_contrast[key - j] for j in back],
        [clip.key_from_hist(key, key - j) for j in back],
    )


def visibility_shares(records: list[dict[str, Any]], num_frames: int = 4) -> dict[str, float]:
    """The share of labelled key-frame points in each visibility class for ``num_frames`` frames at stride 1.

    Args:
        records: visibility records, one per key frame (``raw_file``, ``visibility``: `key_frame_visibility`), as
            ``visibility/<split>.json`` holds them.
        num_frames: frames of the model (the key frame and ``num_frames - 1`` before it).

    Returns:
        ``{"<class>_fraction": share}`` for every class of `stamlane.synth.visibility.VISIBILITY_CLASSES`.
    """
    counts = dict.fromkeys(VISIBILITY_CLASSES, 0)
    for record in records:
        for lane in record["visibility"]:
            for mask in lane:
                cls = visibility_class(mask, num_frames)
                if cls is not None:
                    counts[cls] += 1
    total = max(sum(counts.values()), 1)
    return {f"{cls}_fraction": n / total for cls, n in counts.items()}
