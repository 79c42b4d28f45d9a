"""VIL-100 json, one file per frame (``Json/<video>/<frame>.jpg.json``): ``annotations.lane`` (``points`` and
``lane_id`` per lane) and the image size in ``info``; THE typed check of the format, `read_vil100_json`. The
frames of a VIL-100 set, grouped into sequences, are `stamlane_eval.io.video`'s."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from stamlane_eval.io.files import LaneFileError, is_json_number, read_file
from stamlane_eval.io.limits import MAX_IMAGE_POINTS, MAX_IMAGE_SIDE, MAX_LANES

__all__ = ["read_vil100_json"]


def read_vil100_json(path: str | os.PathLike[str]) -> tuple[list[np.ndarray], list[int], tuple[int, int] | None]:
    """Read one VIL-100 frame annotation (``Json/<video>/<frame>.jpg.json``): THE typed check of the format.

    Types are the format's and nothing else is read as a number: ``points`` a list of ``[x, y]`` pairs of JSON
    numbers (a string, ``true``/``false`` or ``null`` is refused: Python's ``float(True)`` would read 1), finite
    (the JSON of the format holds no NaN; a far point, x = 150,000, is drawn clipped, as MMA-Net's C++ tool draws
    it); ``lane_id`` an integer; ``info.width`` / ``info.height``
    integers (``1920`` or ``1920.0``, not ``"1920"`` nor ``true``) in ``1..MAX_IMAGE_SIDE``.

    Returns:
        lanes (``(N, 2)`` float ``(x, y)`` arrays), their ``lane_id``s, and the image ``(H, W)`` from ``info``
        (None when absent).

    Raises:
        LaneFileError: unreadable file, invalid JSON, a missing/odd ``annotations.lane`` entry or a value of the
            wrong type, naming the lane and the value.
    """
    p = Path(path)
    text = read_file(p)
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except ValueError as e:
        raise LaneFileError(f"{p}: invalid JSON ({e})") from None
    except RecursionError:
        raise LaneFileError(f"{p}: JSON nested too deeply") from None
    try:
        entries = data["annotations"]["lane"]
        info = data.get("info", {})
    except (KeyError, TypeError, AttributeError):
        raise LaneFileError(f"{p}: no annotations.lane list (VIL-100 format expected)") from None
    if not isinstance(entries, list):
        raise LaneFileError(f"{p}: annotations.lane must be a list, got {type(entries).__name__}")
    if len(entries) > MAX_LANES:  # time: the C++ tool's matching (io.limits)
        raise LaneFileError(f"{p}: {len(entries)} lanes, more than the limit of {MAX_LANES}")
    lanes, ids = [], []
    points = 0
    for k, lane in enumerate(entries):
        if not isinstance(lane, dict) or "points" not in lane:
            raise LaneFileError(f"{p}: lane {k}: needs points [[x, y], ...] and an integer lane_id")
        lanes.append(_vil100_points(lane["points"], p, k))
        points += len(lanes[-1])
        if points > MAX_IMAGE_POINTS:  # memory, per image as for CULane text: no limit per lane
            raise LaneFileError(
                f"{p}: more than {MAX_IMAGE_POINTS} points in the lanes of one image (the memory budget of one image)"
            )
        lane_id = lane.get("lane_id", k)
        if type(lane_id) is not int:
            raise LaneFileError(f"{p}: lane {k}: lane_id must be an integer, got {lane_id!r:.40}")
        ids.append(lane_id)
    if len(set(ids)) != len(ids):
        raise LaneFileError(f"{p}: duplicate lane_id in {ids}")
    size = None
    if isinstance(info, dict) and "width" in info and "height" in info:
        size = (_vil100_side(info["height"], "height", p), _vil100_side(info["width"], "width", p))
        if not (0 < size[0] <= MAX_IMAGE_SIDE and 0 < size[1] <= MAX_IMAGE_SIDE):
            raise LaneFileError(f"{p}: image size {size[1]}x{size[0]} (WxH) outside 1..{MAX_IMAGE_SIDE} px per side")
    return lanes, ids, size


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name}")


def _vil100_points(points: object, path: Path, k: int) -> np.ndarray:
    """``[[x, y], ...]`` of JSON numbers as an ``(N, 2)`` float64 array, checked one value at a time."""
    if not isinstance(points, list):
        raise LaneFileError(f"{path}: lane {k}: points must be a list of [x, y] pairs, got {points!r:.40}")
    if len(points) > MAX_IMAGE_POINTS:  # the per-image budget, checked before a lane is converted
        raise LaneFileError(f"{path}: lane {k}: {len(points)} points, more than the limit of {MAX_IMAGE_POINTS}")
    for pt in points:
        if not (isinstance(pt, list) and len(pt) == 2 and is_json_number(pt[0]) and is_json_number(pt[1])):
            what = "a boolean" if isinstance(pt, list) and any(type(v) is bool for v in pt) else repr(pt)[:40]
            raise LaneFileError(f"{path}: lane {k}: a point must be [x, y], two JSON numbers, got {what}")
    try:
        arr = np.array(points, dtype=np.float64).reshape(-1, 2)
    except OverflowError:  # an integer beyond the float range
        arr = np.full((1, 2), np.inf)
    if not np.isfinite(arr).all():  # only an integer beyond the float range gets here (the parser refuses NaN)
        raise LaneFileError(f"{path}: lane {k}: a coordinate beyond the float range (a label must be finite)")
    return arr


def _vil100_side(v: object, name: str, path: Path) -> int:
    """``info.width`` / ``info.height``: an integer, or a float with an integer value (``1920.0``)."""
    if type(v) is int:
        return v
    if type(v) is float and v.is_integer():
        return int(v)
    raise LaneFileError(f"{path}: info.{name} must be an integer number of pixels, got {v!r:.40}")
