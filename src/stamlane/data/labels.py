"""Readers of the lane label formats, each returning lanes as ``(N, 2)`` float arrays in original pixels.

Every reader raises ``DataError`` naming the file (and line) on malformed content, so a dataset can
either stop or skip the sample with a warning (``on_error``).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path, PurePosixPath

import numpy as np

__all__ = [
    "DataError",
    "TuSimpleRecord",
    "history_name",
    "read_culane_lines",
    "read_tusimple_labels",
    "read_vil100_json",
    "resolve_inside",
]


class DataError(ValueError):
    """Bad data: a missing or unreadable file, a path outside the data root, malformed labels."""


class TuSimpleRecord(dict):
    """One TuSimple label line: ``raw_file`` (str), ``lanes`` (list of x lists), ``h_samples`` (list of y)."""


def resolve_inside(root: Path, rel: str, source: str) -> Path:
    """``root / rel`` after checking that it stays inside ``root``.

    Args:
        root: data root.
        rel: a path relative to the root as written in a label or list file (a leading ``/`` is allowed,
            as in CULane list files).
        source: where ``rel`` was read (file and line), for the error message.

    Raises:
        DataError: when the path leaves the root (``..``, or an absolute path elsewhere).
    """
    rel_clean = rel.strip().lstrip("/")
    if not rel_clean:
        raise DataError(f"{source}: empty path")
    path = (root / rel_clean).resolve()
    root_r = root.resolve()
    if path != root_r and root_r not in path.parents:
        raise DataError(f"{source}: path {rel!r} is outside the data root {root}")
    return path


def read_tusimple_labels(path: Path) -> Iterator[tuple[int, TuSimpleRecord | DataError]]:
    """Parse a TuSimple label file (json-lines).

    Yields:
        ``(line_number, record)`` per non-empty line, or ``(line_number, DataError)`` for a bad line
        (invalid json, missing key, a lane whose length differs from ``h_samples``), so the caller
        decides whether to raise or skip.

    Raises:
        DataError: when the file itself cannot be read.
    """
    try:
        text = path.read_text()
    except OSError as err:
        raise DataError(f"cannot read label file {path}: {err}") from err
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        where = f"{path}:{number}"
        try:
            rec = json.loads(line)
        except json.JSONDecodeError as err:
            yield number, DataError(f"{where}: invalid json ({err.msg})")
            continue
        missing = [k for k in ("raw_file", "lanes", "h_samples") if k not in rec]
        if missing:
            yield number, DataError(f"{where}: missing key(s) {missing}")
            continue
        n = len(rec["h_samples"])
        bad = [i for i, lane in enumerate(rec["lanes"]) if len(lane) != n]
        if bad:
            lengths = [len(rec["lanes"][i]) for i in bad]
            yield (
                number,
                DataError(
                    f"{where}: lane(s) {bad} have {lengths} x values but h_samples has {n} (mismatched lane lengths)"
                ),
            )
            continue
        yield number, TuSimpleRecord(rec)


def tusimple_lanes(rec: dict) -> list[np.ndarray]:
    """Lanes of a TuSimple record as ``(N, 2)`` float arrays of ``(x, y)``; ``x < 0`` marks absent points.

    A lane with no point at all (every x is -2) is an absent lane and is dropped here, silently.
    """
    ys = np.asarray(rec["h_samples"], dtype=np.float64)
    lanes = []
    for xs in rec["lanes"]:
        xs = np.asarray(xs, dtype=np.float64)
        keep = xs >= 0
        if not keep.any():
            continue
        lanes.append(np.stack([xs[keep], ys[keep]], axis=1))
    return lanes


def read_culane_lines(path: Path) -> list[np.ndarray]:
    """Read a CULane ``.lines.txt``: one lane per line, ``x1 y1 x2 y2 ...``.

    Raises:
        DataError: missing or unreadable file, a non-number, or an odd number of values on a line.
    """
    try:
        text = path.read_text()
    except OSError as err:
        raise DataError(f"cannot read lane file {path}: {err}") from err
    lanes = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            vals = [float(v) for v in line.split()]
        except ValueError as err:
            raise DataError(f"{path}:{number}: not a number ({err})") from err
        if len(vals) % 2:
            raise DataError(f"{path}:{number}: odd number of values ({len(vals)}); expected x y pairs")
        lanes.append(np.asarray(vals, dtype=np.float64).reshape(-1, 2))
    return lanes


def read_vil100_json(path: Path) -> list[np.ndarray]:
    """Read a VIL-100 annotation ``Json/<video>/<frame>.jpg.json`` (``annotations.lane[*].points``).

    Lanes are returned in ``lane_id`` order.

    Raises:
        DataError: missing file, invalid json, or points that are not ``[[x, y], ...]``.
    """
    try:
        data = json.loads(path.read_text())
    except OSError as err:
        raise DataError(f"cannot read annotation {path}: {err}") from err
    except json.JSONDecodeError as err:
        raise DataError(f"{path}: invalid json ({err.msg})") from err
    try:
        items = data["annotations"]["lane"]
    except (KeyError, TypeError) as err:
        raise DataError(f"{path}: no annotations.lane list") from err
    lanes = []
    for i, item in enumerate(sorted(items, key=lambda it: it.get("lane_id", 0))):
        pts = np.asarray(item.get("points", []), dtype=np.float64)
        if pts.size and (pts.ndim != 2 or pts.shape[1] != 2):
            raise DataError(f"{path}: lane {i} points have shape {pts.shape}; expected (N, 2)")
        lanes.append(pts.reshape(-1, 2))
    return lanes


_NUMBERED = re.compile(r"^(.*?)(\d+)$")


def history_name(rel: str, back: int) -> str | None:
    """Name of the frame ``back`` numbers before ``rel`` by its trailing frame number.

    ``clips/a/20.jpg`` -> ``clips/a/17.jpg`` for ``back = 3``; zero padding is kept
    (``00030.jpg`` -> ``00000.jpg``). Returns None when the name has no trailing number or the number
    would go below 0.
    """
    p = PurePosixPath(rel)
    suffix = "".join(p.suffixes[-1:])
    stem = p.name[: len(p.name) - len(suffix)] if suffix else p.name
    m = _NUMBERED.match(stem)
    if not m:
        return None
    prefix, digits = m.groups()
    n = int(digits) - back
    if n < 0:
        return None
    width = len(digits) if digits.startswith("0") and len(digits) > 1 else 0
    return str(p.with_name(f"{prefix}{n:0{width}d}{suffix}"))
