"""Readers of the lane label formats, each returning lanes as ``(N, 2)`` float arrays in original pixels.

Every reader raises ``DataError`` naming the file (and line) on malformed content, so a dataset can
either stop or skip the sample with a warning (``on_error``). The parsing and the typed checks are the
evaluators' (``stamlane_eval.io``): a file the evaluator refuses is refused here, for the same reason.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
from stamlane_eval import io as eval_io
from stamlane_eval.io import LaneFileError, iter_tusimple, tusimple_points
from stamlane_eval.io.files import name_problem

from stamlane.safety.guard import is_inside
from stamlane.safety.paths import shown

__all__ = [
    "DataError",
    "TuSimpleRecord",
    "history_name",
    "read_culane_lines",
    "read_tusimple_labels",
    "read_vil100_json",
    "resolve_inside",
]


class DataError(LaneFileError):
    """Bad data: a missing or unreadable file, a path outside the data root, malformed labels (a
    ``stamlane_eval.io.LaneFileError``: the same files fail the same way in the evaluators)."""


class TuSimpleRecord(dict[str, Any]):
    """One TuSimple label line: ``raw_file`` (str), ``lanes`` (list of x lists), ``h_samples`` (list of y)."""


def resolve_inside(root: Path, rel: str, source: str) -> Path:
    """``root / rel``, resolved, after checking that it stays inside ``root`` (`stamlane.safety.guard.is_inside`).

    Args:
        root: data root.
        rel: a path relative to the root as written in a label or list file (a leading ``/`` is allowed,
            as in CULane list files).
        source: where ``rel`` was read (file and line), for the error message.

    Raises:
        DataError: when the path leaves the root (``..``, or an absolute path elsewhere) or is a name no file can
            have (a NUL byte, a component over the file system's limit), naming ``source``.
    """
    rel_clean = rel.strip().lstrip("/")
    if not rel_clean:
        raise DataError(f"{source}: empty path")
    # a name no file can have (a NUL byte, a component over the file system's limit) is the file's problem, said
    # with its name: os.stat would raise "embedded null byte" or "[Errno 36] File name too long" without it
    problem = name_problem(os.fsencode(root / rel_clean))
    if problem is not None:
        raise DataError(f"{source}: path {_brief(rel)} {problem}")
    try:
        path = (root / rel_clean).resolve()
    except (OSError, RuntimeError) as err:  # a loop of links (RuntimeError on Python 3.11)
        raise DataError(f"{source}: path {_brief(rel)} cannot be resolved ({type(err).__name__})") from None
    if not is_inside(path, root):
        raise DataError(f"{source}: path {rel!r} is outside the data root {root}")
    return path


def _brief(rel: str) -> str:
    """A path of a label or list file as a short printable line: the label file and the line say where it is."""
    return shown(rel) if len(rel) <= 80 else f"{shown(rel[:40])}…{shown(rel[-30:])} ({len(rel)} characters)"


def read_tusimple_labels(path: Path) -> Iterator[tuple[int, TuSimpleRecord | DataError]]:
    """Parse a TuSimple label file (json-lines) with the evaluator's typed check of every record
    (``stamlane_eval.io.tusimple_record_error``: numbers only, finite, within ``MAX_COORDINATE``, each raw_file once in a file, lanes as long
    as a non-empty ``h_samples``).

    Yields:
        ``(line_number, record)`` per line, or ``(line_number, DataError)`` for a bad line, so the caller
        decides whether to raise or skip.

    Raises:
        DataError: when the file itself cannot be read (or is one JSON document, not json-lines).
    """
    try:
        for number, rec in iter_tusimple(path, "gt"):
            yield number, DataError(str(rec)) if isinstance(rec, LaneFileError) else TuSimpleRecord(rec)
    except LaneFileError as err:
        raise DataError(str(err)) from None


def tusimple_lanes(rec: dict[str, Any]) -> list[np.ndarray]:
    """Lanes of a TuSimple record as ``(N, 2)`` float arrays of ``(x, y)``; ``x < 0`` marks absent points.

    A lane with no point at all (every x is -2) is an absent lane and is dropped here, silently.
    """
    return [lane for lane in tusimple_points(rec["lanes"], rec["h_samples"]) if len(lane)]


def read_culane_lines(path: Path) -> list[np.ndarray]:
    """Read a CULane ``.lines.txt`` with the evaluator's reader (one lane per line, ``x1 y1 x2 y2 ...``, its
    limits and checks); a blank line, a lane of 0 points for the official tool, is no lane here.

    Raises:
        DataError: missing or unreadable file, a non-number, NaN/inf, an odd number of values, too many lanes
            or points.
    """
    try:
        return [lane for lane in eval_io.read_culane_lines(path, missing_ok=False) if len(lane)]
    except LaneFileError as err:
        raise DataError(str(err)) from None


def read_vil100_json(path: Path) -> list[np.ndarray]:
    """Read a VIL-100 annotation ``Json/<video>/<frame>.jpg.json`` (``annotations.lane[*].points``) with the
    evaluator's reader; lanes are returned in ``lane_id`` order.

    Raises:
        DataError: missing file, invalid json, points that are not ``[[x, y], ...]``, limits exceeded.
    """
    try:
        lanes, ids, _size = eval_io.read_vil100_json(path)
    except LaneFileError as err:
        raise DataError(str(err)) from None
    return [lanes[k] for k in sorted(range(len(lanes)), key=lambda k: ids[k])]


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
