"""TuSimple json-lines (the benchmark's ``test_label.json`` and predictions): one object per line, ``raw_file``,
``lanes`` (one x per row, negative where the lane is absent) and ``h_samples`` (ground truth) or ``run_time``
(predictions, milliseconds).

- reading as lane.py reads (`read_tusimple`, `iter_tusimple` for readers that skip bad lines);
- THE check of the format (`check_tusimple`, `tusimple_record_error`), shared by ``stamlane_eval.tusimple``,
  ``stamlane-eval`` and the training datasets;
- the lanes as ``(x, y)`` points for the CULane metric (`tusimple_points`, `tusimple_lanes`,
  `tusimple_lanes_by_image`);
- what lane.py prints (`lane_py_line`).

TuSimple records read as the frames of sequences are `stamlane_eval.io.video`'s.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stamlane_eval.io.files import LaneFileError, gc_paused, image_key, is_json_number, json_float, read_file
from stamlane_eval.io.limits import MAX_COORDINATE, MAX_LANE_POINTS, MAX_LANES, MAX_TUSIMPLE_VALUES

__all__ = [
    "LABEL_RULES",
    "TuSimpleFile",
    "TuSimpleInputError",
    "check_tusimple",
    "duplicate_raw_file",
    "iter_tusimple",
    "lane_py_line",
    "read_tusimple",
    "tusimple_lanes",
    "tusimple_lanes_by_image",
    "tusimple_points",
    "tusimple_record_error",
]


class TuSimpleInputError(ValueError):
    """TuSimple records that cannot be scored: the official script crashes on them, or its numbers would not be
    rates (see docs/evaluators.md, "What is scored and what is refused").

    Attributes:
        message: the problem, without the place.
        source: ``"pred"`` or ``"gt"``: which input is at fault (``None`` when both or neither).
        line: 1-based line (record index + 1) at fault, or ``None``.
    """

    def __init__(self, message: str, source: str | None = None, line: int | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.source = source
        self.line = line

    def __str__(self) -> str:
        where = f"{self.source} line {self.line}: " if self.line is not None else ""
        return where + self.message


def read_tusimple(path: str | os.PathLike[str], *, text: str | None = None) -> list[dict[str, Any]]:
    """Read a TuSimple json-lines file (predictions or ground truth).

    As the official ``lane.py`` (``[json.loads(line) for line in readlines()]``), every line must be one JSON
    object: a blank line, including a blank line at the end of the file, is an error. ``NaN`` and ``Infinity``
    read as numbers, as lane.py's ujson reads them (`check_tusimple` decides where they may stand).

    Args:
        path: the file.
        text: its content when already read.

    Returns:
        The records in file order.

    Raises:
        LaneFileError: unreadable file, invalid JSON (with its line number), a line that is not an object, a
            JSON ``true``/``false`` where a number belongs, or an empty file.
    """
    p = Path(path)
    if text is None:
        text = read_file(p)
    if not text.strip():
        raise LaneFileError(f"{p}: empty file")
    body = text[:-1] if text.endswith("\n") else text
    try:  # fast path: one parse for the whole file (a blank line makes ",," and falls to the slow path)
        with gc_paused():
            records: list[dict[str, Any]] = json.loads("[" + body.replace("\n", ",") + "]")
        if len(records) == body.count("\n") + 1 and all(type(r) is dict for r in records):
            refuse_booleans(records, text, p)
            return records
    except (ValueError, RecursionError):  # RecursionError: nesting too deep; the slow path names the line
        pass
    out = []
    for _, rec in iter_tusimple(p, text=text):  # slow path: find the first bad line
        if isinstance(rec, LaneFileError):
            raise rec
        out.append(rec)
    refuse_booleans(out, text, p)
    return out


def _one_document(text: str) -> bool:
    """Whether ``text`` is ONE JSON value spread over several lines (a pretty-printed file)."""
    try:
        json.loads(text)
    except (ValueError, RecursionError):
        return False
    return text.strip().count("\n") > 0


def iter_tusimple(
    path: str | os.PathLike[str], role: str | None = None, *, text: str | None = None
) -> Iterator[tuple[int, dict[str, Any] | LaneFileError]]:
    """The records of a TuSimple json-lines file one line at a time, for readers that may skip bad ones.

    Args:
        path: the file.
        role: ``"gt"`` or ``"pred"``: also check each record with `tusimple_record_error`; None: only that
            each line is one JSON object.
        text: the file's content when already read.

    Yields:
        ``(line_number, record)``, or ``(line_number, LaneFileError)`` for a bad line (the caller raises or
        skips it). A blank line is an error, as in lane.py.

    Raises:
        LaneFileError: an unreadable file, or one JSON document spread over lines (not json-lines).
    """
    p = Path(path)
    if text is None:
        text = read_file(p)
    lines = text.split("\n")  # lane.py's readlines(): only "\n" ends a line (str.splitlines also splits at U+2028)
    if lines and lines[-1] == "":
        lines.pop()
    for i, line in enumerate(lines, 1):
        if not line.strip():
            yield i, LaneFileError(f"{p}: line {i} is blank (every line must be one JSON object, as lane.py requires)")
            continue
        try:
            rec = json.loads(line)
        except ValueError as e:
            if i == 1 and _one_document(text):
                raise LaneFileError(
                    f"{p}: one JSON document over {text.strip().count(chr(10)) + 1} lines; TuSimple files hold one "
                    f"JSON object per line (json-lines)"
                ) from None
            yield i, LaneFileError(f"{p}: line {i}: invalid JSON ({e})")
            continue
        except RecursionError:
            yield i, LaneFileError(f"{p}: line {i}: JSON nested too deeply")
            continue
        if not isinstance(rec, dict):
            hint = ""
            if i == 1 and isinstance(rec, list) and rec and all(isinstance(r, dict) and "raw_file" in r for r in rec):
                # a list of records on one line: a generator's frame_labels/<clip>.json, which lane.py cannot read either
                hint = (
                    "; this is a list of records (a frame_labels/<clip>.json?): score a clip's frames with "
                    "`stamlane-eval video PRED FRAME_LABELS_FOLDER`, or write one record per line"
                )
            yield i, LaneFileError(f"{p}: line {i}: expected a JSON object, got {type(rec).__name__}{hint}")
            continue
        if role is not None and ("true" in line or "false" in line):
            try:
                refuse_booleans([rec], line, p, first_line=i)
            except LaneFileError as err:
                yield i, err
                continue
        problem = tusimple_record_error(rec, role) if role else None
        yield i, (LaneFileError(f"{p}: line {i}: {problem}") if problem else rec)


def refuse_booleans(
    records: list[dict[str, Any]], text: str, path: Path, first_line: int = 1, unit: str = "line"
) -> None:
    """JSON ``true``/``false`` where a number belongs (lane.py would read them as 1 and 0): refused, a type error.
    Only looked for when the words occur in the text at all (``unit``: how the message names a record)."""
    if "true" not in text and "false" not in text:
        return
    for i, rec in enumerate(records, first_line):
        values = [rec.get("run_time"), *_numbers(rec.get("h_samples"))]
        lanes = rec.get("lanes")
        for lane in lanes if isinstance(lanes, list) else []:
            values += _numbers(lane)
        if any(type(v) is bool for v in values):
            raise LaneFileError(f"{path}: {unit} {i}: a boolean (true/false) where a number belongs")


def _numbers(value: object) -> list[Any]:
    return value if isinstance(value, list) else []


# ------------------------------------------------------------------------------- the TuSimple validator
_FILL = -100.0  # lane.py replaces every negative x by -100 before comparing; padding uses the same value
_KEYS = {
    "gt": (("raw_file", "lanes", "h_samples"), "raw_file or lanes or h_samples not in gt"),
    "pred": (("raw_file", "lanes", "run_time"), "raw_file or lanes or run_time not in some predictions."),
}
_SEQUENCES = (list, tuple, np.ndarray)
_LANE_ERROR = {"pred": "Format of lanes error: ", "gt": ""}  # lane.py's message for a prediction it cannot read
LABEL_RULES = ("pixel", "finite", "lane.py")
"""How `check_tusimple` takes a ground truth's values: ``"pixel"`` finite and within ``MAX_COORDINATE`` (the training
datasets' labels); ``"finite"`` any finite value (the CULane metric and the video readers: the C++ tool draws a far
point clipped); ``"lane.py"`` every value lane.py scores (the TuSimple metric, `tusimple.evaluate`)."""


@dataclass(frozen=True)
class TuSimpleFile:
    """A TuSimple file that passed `check_tusimple`, as arrays.

    Attributes:
        names: ``raw_file`` per record, in file order.
        lanes: ``(L, W)`` float64: every lane of every record in file order, padded with -100 past its length.
        lengths: ``(L,)`` values in each lane.
        counts: ``(n,)`` lanes per record.
        h_samples: ``(n, R)`` float64 rows per record, padded with -100 (gt), or None (pred).
        rows: ``(n,)`` ``len(h_samples)`` (gt), or None.
        run_times: ``(n,)`` milliseconds (pred), or None.
        odd: prediction values that are no pixel coordinate (not finite, or beyond ``MAX_COORDINATE``), which
            are scored as lane.py scores them: ``(count, "line N: lane K has x = V")`` of the first, or None; for a
            ground truth read with ``labels="lane.py"``, its lane and ``h_samples`` values of that kind.
    """

    names: list[str]
    lanes: np.ndarray
    lengths: np.ndarray
    counts: np.ndarray
    h_samples: np.ndarray | None = None
    rows: np.ndarray | None = None
    run_times: np.ndarray | None = None
    odd: tuple[int, str] | None = None


def check_tusimple(records: Sequence[object], role: str, *, labels: str = "pixel") -> TuSimpleFile:
    """THE check of the TuSimple format (docs/evaluators.md, "What is scored and what is refused"), shared by
    ``stamlane_eval.tusimple.evaluate``, ``stamlane-eval`` and the training datasets (per record, through
    `tusimple_record_error`).

    - Types are the format's: objects with the keys lane.py reads, ``raw_file`` a non-empty string, ``lanes`` a
      list of lists of numbers, ``h_samples`` (gt) a list of numbers, ``run_time`` (pred) a number.
    - Sizes are bounded (memory): ``MAX_LANES`` lanes per image, ``MAX_LANE_POINTS`` rows; with
      ``labels="lane.py"`` (lane.py scores any count and length) only the padded arrays, ``MAX_TUSIMPLE_VALUES``.
    - A ground truth has every lane as long as a non-empty ``h_samples`` and each ``raw_file`` once (lane.py
      would sum every line but divide by the unique names: an accuracy above 1). Its values follow ``labels``
      (`LABEL_RULES`): with ``"lane.py"`` every value is taken as lane.py takes it (NaN, -inf: no point on that
      row; 150,000: a far point its angle fit uses) and counted in ``odd``; +inf and a non-finite ``h_samples``
      value are refused by the scoring where lane.py's angle fit raises on them (`stamlane_eval.tusimple`).
    - A prediction's VALUES are free, as in lane.py: a huge, negative, fractional, NaN or infinite x is scored
      as lane.py scores it (NaN and negatives: no point on that row; huge: a miss); ``odd`` counts the values
      that are no pixel coordinate, for one warning. Its lane lengths are checked against the ground truth's
      rows by the evaluator.

    Args:
        records: the parsed lines (dicts), in file order.
        role: ``"gt"`` or ``"pred"``.

    Returns:
        The records as arrays.

    Raises:
        TuSimpleInputError: naming the record (``line``), ``source = role``.
    """
    if role not in _KEYS:
        raise ValueError(f"role must be 'gt' or 'pred', got {role!r}")
    if labels not in LABEL_RULES:
        raise ValueError(f"labels must be one of {LABEL_RULES}, got {labels!r}")
    free = labels == "lane.py"  # lane.py's own sizes: no lane count or length limit, only the padded arrays
    keys, missing_message = _KEYS[role]
    names: list[str] = []
    lanes_of: list[Sequence[Any] | np.ndarray] = []
    extra: list[object] = []  # h_samples (gt) or run_time (pred)
    first: dict[str, int] = {}
    for i, rec in enumerate(records):
        if type(rec) is not dict or keys[0] not in rec or keys[1] not in rec or keys[2] not in rec:
            if not isinstance(rec, dict):
                raise TuSimpleInputError(f"expected a JSON object, got {type(rec).__name__}", role, i + 1)
            raise TuSimpleInputError(f"{missing_message} (has keys {sorted(rec)[:6]}, needs {list(keys)})", role, i + 1)
        name = rec["raw_file"]
        if type(name) is not str or not name.strip():
            raise TuSimpleInputError(f"raw_file must be a non-empty string, got {name!r:.60}", role, i + 1)
        if role == "gt":
            key = image_key(name)  # s1/./2.jpg is s1/2.jpg: one image labelled twice
            if key in first:
                line = first[key]
                also = "" if records[line]["raw_file"] == name else f" as {records[line]['raw_file']!r}"  # type: ignore[index]
                raise TuSimpleInputError(duplicate_raw_file(name, f"line {line + 1}{also}"), role, i + 1)
            first[key] = i
        if not isinstance(rec["lanes"], _SEQUENCES):
            raise TuSimpleInputError(f"lanes must be a list of lists of numbers, got {rec['lanes']!r:.60}", role, i + 1)
        names.append(name)
        lanes_of.append(rec["lanes"])
        extra.append(rec[keys[2]])
    counts = np.fromiter(map(len, lanes_of), dtype=np.int64, count=len(lanes_of))
    if not free and len(counts) and counts.max() > MAX_LANES:
        i = int(np.argmax(counts))
        raise TuSimpleInputError(f"{counts[i]} lanes, more than the limit of {MAX_LANES}", role, i + 1)
    if role == "gt":
        rows = _row_lengths(extra, role, "h_samples", limit=not free)
        h_samples, odd_h = _stack(extra, rows, np.arange(len(extra)), role, "h_samples", labels)
        empty = np.flatnonzero(rows == 0)
        if len(empty):
            raise TuSimpleInputError("h_samples is empty: no row to score", role, int(empty[0]) + 1)
    flat = [lane for lanes in lanes_of for lane in lanes]
    owner = np.repeat(np.arange(len(lanes_of)), counts)
    lengths = _row_lengths(flat, role, "lane", owner, limit=not free)
    lanes, odd = _stack(flat, lengths, owner, role, "lane", labels if role == "gt" else "lane.py")
    if role == "gt":
        bad = np.flatnonzero(lengths != rows[owner])
        if len(bad):
            i = int(owner[bad[0]])
            raise TuSimpleInputError(
                f"{_name('lane', owner, int(bad[0]))} has {lengths[bad[0]]} x values, h_samples has {rows[i]}",
                role,
                i + 1,
            )
        return TuSimpleFile(names, lanes, lengths, counts, h_samples=h_samples, rows=rows, odd=_both(odd, odd_h))
    run_times = np.zeros(len(extra))
    for i, rt in enumerate(extra):
        if type(rt) not in (int, float) or not isinstance(rt, (int, float)):  # exactly int/float: no bool, no numpy
            raise TuSimpleInputError(f"Format of lanes error: run_time must be a number, got {rt!r:.40}", role, i + 1)
        run_times[i] = json_float(rt)
    odd_rt = np.flatnonzero(~np.isfinite(run_times))
    if len(odd_rt):
        first_rt = f"line {odd_rt[0] + 1}: run_time {run_times[odd_rt[0]]!r}"
        odd = _both(odd, (len(odd_rt), first_rt))
    return TuSimpleFile(names, lanes, lengths, counts, run_times=run_times, odd=odd)


def duplicate_raw_file(name: str, first: str) -> str:
    """The one message for a ``raw_file`` named twice in ground truth (evaluator and training datasets)."""
    return (
        f"raw_file {name!r} again (first at {first}): two labels for one image (lane.py would sum both and "
        f"divide by the unique names, an accuracy above 1)"
    )


def _both(a: tuple[int, str] | None, b: tuple[int, str] | None) -> tuple[int, str] | None:
    """Two counts of odd values as one: the sum, and the first one's description."""
    if a is None or b is None:
        return a or b
    return a[0] + b[0], a[1]


def _row_lengths(
    rows: list[object], role: str, kind: str, owner: np.ndarray | None = None, *, limit: bool = True
) -> np.ndarray:
    """Lengths of number lists (each a list/tuple/array), checked against ``MAX_LANE_POINTS`` when ``limit``."""
    sizes: list[int] = []
    for j, row in enumerate(rows):
        if not isinstance(row, _SEQUENCES):
            line = int(owner[j]) + 1 if owner is not None else j + 1
            raise TuSimpleInputError(
                f"{_LANE_ERROR[role]}{_name(kind, owner, j)} must be a list of numbers, got {row!r:.60}", role, line
            )
        sizes.append(len(row))
    lengths = np.array(sizes, dtype=np.int64)
    if limit and len(lengths) and lengths.max() > MAX_LANE_POINTS:
        j = int(np.argmax(lengths))
        line = int(owner[j]) + 1 if owner is not None else j + 1
        raise TuSimpleInputError(f"{kind} of {lengths[j]} values, more than the limit of {MAX_LANE_POINTS}", role, line)
    return lengths


def _stack(
    rows: list[object], lengths: np.ndarray, owner: np.ndarray, role: str, kind: str, values: str
) -> tuple[np.ndarray, tuple[int, str] | None]:
    """Number lists as one ``(len(rows), max length)`` float64 array padded with -100.

    Args:
        rows: the lists.
        lengths: their lengths.
        owner: the record of each list (for messages).
        role: ``"gt"`` or ``"pred"``.
        kind: ``"lane"`` or ``"h_samples"``.
        values: `LABEL_RULES`: refuse values that are no pixel coordinate (``"pixel"``), or not finite
            (``"finite"``); else (``"lane.py"``) count them.

    Returns:
        The array and ``(count, description of the first)`` of the values that are no pixel coordinate.

    Raises:
        TuSimpleInputError: a value ``values`` refuses, or a padded array beyond ``MAX_TUSIMPLE_VALUES``.
    """
    width = int(lengths.max(initial=0))
    if len(rows) * width > MAX_TUSIMPLE_VALUES:  # memory: the file's lanes padded to its longest, as float64
        j = int(np.argmax(lengths))
        raise TuSimpleInputError(
            f"{len(rows)} {kind} lists padded to the longest ({width} values, line {int(owner[j]) + 1}) are more than "
            f"{MAX_TUSIMPLE_VALUES:,} values: too large to score in memory",
            role,
        )
    out = np.full((len(rows), width), _FILL)
    uniq = np.unique(lengths)
    for length in uniq.tolist():
        idx = np.flatnonzero(lengths == length) if len(uniq) > 1 else np.arange(len(rows))
        sub = rows if len(uniq) == 1 else [rows[j] for j in idx.tolist()]
        try:
            arr = np.array(sub)
        except (ValueError, TypeError, OverflowError):
            arr = np.zeros(0, dtype=object)
        if arr.ndim != 2 or arr.dtype.kind not in "iuf":
            arr = np.array([[_number(v, role, kind, owner, j) for v in rows[j]] for j in idx.tolist()])
            arr = arr.reshape(len(idx), length)
        out[idx, :length] = arr
    if out.size == 0:
        return out, None
    valid = np.arange(width)[None, :] < lengths[:, None]
    with np.errstate(invalid="ignore"):
        odd_mask = valid & ~(np.abs(out) <= MAX_COORDINATE)  # NaN fails <=
    if not odd_mask.any():
        return out, None
    j, col = (int(v[0]) for v in np.nonzero(odd_mask))
    where = f"line {owner[j] + 1}: {_name(kind, owner, j)} has {float(out[j, col])!r}"
    if values == "finite":
        odd_mask = valid & ~np.isfinite(out)
        if not odd_mask.any():
            return out, None
        j, col = (int(v[0]) for v in np.nonzero(odd_mask))
    if values != "lane.py":
        rule = "finite" if values == "finite" else f"finite, |v| <= {MAX_COORDINATE:g}"
        raise TuSimpleInputError(
            f"{_name(kind, owner, j)} has {float(out[j, col])!r}: not a pixel coordinate (a label here must be {rule})",
            role,
            int(owner[j]) + 1,
        )
    return out, (int(odd_mask.sum()), where)


def _name(kind: str, owner: np.ndarray | None, j: int) -> str:
    """``"lane K"`` (K counted within its record) or ``"h_samples"``, for messages."""
    if kind == "h_samples" or owner is None:
        return kind
    return f"lane {j - int(np.searchsorted(owner, owner[j]))}"


def _number(v: object, role: str, kind: str, owner: np.ndarray, j: int) -> float:
    if type(v) is float or type(v) is int:
        return json_float(v)
    if isinstance(v, (np.floating, np.integer)) and not isinstance(v, np.bool_):
        return float(v)
    what = "a boolean" if isinstance(v, (bool, np.bool_)) else repr(v)[:40]
    raise TuSimpleInputError(
        f"{_LANE_ERROR[role]}{_name(kind, owner, j)} must be a list of numbers, got {what} in it",
        role,
        int(owner[j]) + 1,
    )


def tusimple_record_error(rec: object, role: str) -> str | None:
    """What is wrong with one TuSimple record, or None: `check_tusimple` on one record (what the training
    datasets apply to every line).

    Args:
        rec: a parsed json line.
        role: ``"gt"`` or ``"pred"``.

    Returns:
        a one-line description, or None for a good record.
    """
    try:
        check_tusimple([rec], role)
    except TuSimpleInputError as e:
        return e.message
    return None


def tusimple_points(lanes: Sequence[Sequence[float]], h_samples: Sequence[float]) -> list[np.ndarray]:
    """TuSimple lanes (one x per row of ``h_samples``, ``x < 0`` where the lane is absent) as ``(N, 2)`` float
    arrays of ``(x, y)`` points, one per lane, in order. A lane absent on every row becomes a lane of 0 points:
    the CULane metric counts it as a lane, as the C++ tool counts an empty line of a ``.lines.txt`` (callers
    that want only visible lanes drop them). The lanes are assumed checked (`tusimple_record_error`)."""
    ys = np.asarray(h_samples, dtype=np.float64)
    points = []
    for lane in lanes:
        xs = np.asarray(lane, dtype=np.float64)
        keep = xs >= 0
        points.append(np.stack([xs[keep], ys[keep]], axis=1))
    return points


def tusimple_lanes(
    records: Sequence[object], path: str | os.PathLike[str], h_samples: dict[str, list[float]] | None = None
) -> tuple[dict[str, list[np.ndarray]], dict[str, list[float]]]:
    """THE typed check of TuSimple-format files scored with the CULane metric (``stamlane-eval culane PRED.json
    GT.json``): the lanes of each ``raw_file`` as ``(x, y)`` points (rows with x < 0 dropped).

    The ground truth (``h_samples`` None) passes `check_tusimple` (types, each ``raw_file`` once, labels finite,
    of any magnitude: ``labels="finite"``).
    A prediction names each ``raw_file`` once, one of the ground truth's, with lanes of JSON numbers (never a
    string nor ``true``/``false``: numpy would read ``[true, 359]`` as ``[1, 359]``), finite, one per row.

    Args:
        records: the parsed json-lines.
        path: the file (for messages).
        h_samples: the ground truth's rows per ``raw_file`` (reading a prediction), or None (the ground truth).

    Returns:
        ``{raw_file: lanes}`` in file order, and ``{raw_file: h_samples}``.

    Raises:
        LaneFileError: naming the file, the line and the problem.
    """
    if h_samples is None:
        try:
            check_tusimple(records, "gt", labels="finite")  # the CULane metric draws a far point clipped
        except TuSimpleInputError as e:
            raise LaneFileError(f"{path}: line {e.line}: {e.message}") from None
        rows = {rec["raw_file"]: rec["h_samples"] for rec in records}  # type: ignore[index]
    else:
        rows = h_samples
    out: dict[str, list[np.ndarray]] = {}
    for i, rec in enumerate(records, 1):
        if not isinstance(rec, dict) or "raw_file" not in rec or not isinstance(rec.get("lanes"), list):
            keys = sorted(rec)[:6] if isinstance(rec, dict) else type(rec).__name__
            raise LaneFileError(f"{path}: line {i}: needs keys raw_file and lanes (a list), has {keys}")
        name = rec["raw_file"]
        h = rows.get(name) if type(name) is str else None
        if h is None:
            raise LaneFileError(f"{path}: line {i}: raw_file {name!r:.80} is not in the ground truth")
        if name in out:  # the C++ tool reads one file per image: a second prediction has no place to be
            raise LaneFileError(f"{path}: line {i}: raw_file {name!r:.80} again: two predictions for one image")
        if len(rec["lanes"]) > MAX_LANES:  # time: the matching's budget, as for CULane text (io.limits)
            raise LaneFileError(f"{path}: line {i}: {len(rec['lanes'])} lanes, more than the limit of {MAX_LANES}")
        for k, lane in enumerate(rec["lanes"]):
            if not (isinstance(lane, list) and len(lane) == len(h) and all(map(is_json_number, lane))):
                raise LaneFileError(
                    f"{path}: line {i}: lane {k} is not {len(h)} JSON numbers (one per h_sample; no string, no "
                    f"true/false)"
                )
            if not all(math.isfinite(json_float(v)) for v in lane):
                raise LaneFileError(f"{path}: line {i}: lane {k} has a non-finite x")
        out[name] = tusimple_points(rec["lanes"], h)
    return out, rows


def tusimple_lanes_by_image(
    pred_records: Sequence[object],
    gt_records: Sequence[object],
    pred_path: str | os.PathLike[str],
    gt_path: str | os.PathLike[str],
) -> tuple[list[str], list[list[np.ndarray]], list[list[np.ndarray]]]:
    """TuSimple prediction and ground-truth files as the CULane metric takes them (``stamlane-eval culane
    PRED.json GT.json``): the images of the ground truth in its order, each with its predicted and annotated lanes
    (`tusimple_lanes`; an image without a prediction has no lanes).

    Returns:
        ``(raw_files, preds, gts)``, per image the lanes as ``(N, 2)`` ``(x, y)`` points.

    Raises:
        LaneFileError: naming the file, the line and the problem (the ground truth is checked first).
    """
    gt_map, rows = tusimple_lanes(gt_records, gt_path)
    pred_map, _ = tusimple_lanes(pred_records, pred_path, rows)
    names = list(gt_map)
    return names, [pred_map.get(name, []) for name in names], [gt_map[name] for name in names]


def lane_py_line(accuracy: float, fp: float, fn: float) -> str:
    """Exactly what the official ``lane.py`` prints: ujson's compact dump of its three-entry list."""
    entries = [
        {"name": "Accuracy", "value": accuracy, "order": "desc"},
        {"name": "FP", "value": fp, "order": "asc"},
        {"name": "FN", "value": fn, "order": "asc"},
    ]
    return json.dumps(entries, separators=(",", ":"))
