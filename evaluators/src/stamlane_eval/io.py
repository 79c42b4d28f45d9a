"""Readers for the benchmark file formats, with errors that name the file, the line and the problem.

- TuSimple: json-lines, one object per line (``raw_file``, ``lanes``, ``h_samples`` / ``run_time``).
- CULane / ApolloScape: one ``.lines.txt`` per image, one lane per line, ``x1 y1 x2 y2 ...``.
- Video: VIL-100 json per frame, CULane text per frame, or TuSimple records grouped into sequences by the folder
  of ``raw_file`` (`read_tusimple_frames`).
"""

from __future__ import annotations

import gc
import json
import math
import os
import re
import stat
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

__all__ = [
    "MAX_COORDINATE",
    "MAX_DRAWN_PIXELS",
    "MAX_FILE_BYTES",
    "MAX_IMAGE_POINTS",
    "MAX_IMAGE_SIDE",
    "MAX_LANES",
    "MAX_LANE_POINTS",
    "MAX_LANE_WIDTH",
    "TUSIMPLE_SUFFIXES",
    "CanvasBudget",
    "Inside",
    "LaneFileError",
    "TuSimpleFile",
    "TuSimpleFrames",
    "TuSimpleInputError",
    "check_image_size",
    "check_tusimple",
    "cpp_stream_doubles",
    "culane_entries",
    "culane_lines_path",
    "duplicate_raw_file",
    "inside",
    "iter_tusimple",
    "read_culane_lines",
    "read_text",
    "read_tusimple",
    "read_tusimple_frames",
    "read_vil100_json",
    "tusimple_frame_key",
    "tusimple_lanes",
    "tusimple_points",
    "tusimple_record_error",
    "video_frames",
]


MAX_IMAGE_SIDE = 16384
"""Largest image side (px) accepted from a label file or ``--size``: the CULane metric draws every lane into a mask of
the image's size, so a declared 200000x200000 frame would ask for tens of GiB."""
MAX_DRAWN_PIXELS = 1 << 30
"""Most pixels of canvases the lanes of one image (CULane, video) or one frame (temporal) are drawn on (1 GiB of
uint8): each lane is drawn into a canvas cropped to it, never larger than the image; `CanvasBudget` counts them
before each canvas is allocated."""
MAX_LANES = 64
"""Most lanes in one image: the CULane matching grows with the cube of the lane count (1,500 lanes: a minute)."""
MAX_LANE_POINTS = 10000
"""Most points (rows) in one TuSimple or VIL-100 lane. CULane text has no limit per lane: ``MAX_IMAGE_POINTS``."""
MAX_IMAGE_POINTS = 100_000
"""Most points in the lanes of one CULane/ApolloScape ``.lines.txt`` (the memory budget of one image, not a limit
per lane): the C++ metric resamples a lane at 50 points per segment, about 3 KB per input point while it is
resampled (measured: one lane of 100,000 points, ``stamlane-eval culane``, peaks at 0.33 GB in 3.6 s); the C++
tool's own inputs hold a few hundred points per image."""
MAX_LANE_WIDTH = 1024
"""Widest lane line (px) the CULane metric may draw."""
MAX_COORDINATE = 100_000.0
"""Largest absolute pixel coordinate of a LABEL (6x ``MAX_IMAGE_SIDE``): a ground truth beyond it is refused. Not a
limit on predictions: lane.py scores a prediction's 1e9 as a miss, and so do we (with one warning line)."""
MAX_FILE_BYTES = 512 << 20
"""Largest input text file (512 MiB): TuSimple's 2,782 test predictions take 4 MiB, and parsed json-lines cost about
9x their size in memory."""


def check_image_size(size: object) -> tuple[int, int]:
    """THE check of an image size that canvases are sized by (``--size``, ``--sizes``, a label's ``info``, the
    Python API): ``(H, W)``, two integers in ``1..MAX_IMAGE_SIDE``.

    Raises:
        ValueError: naming the size.
    """
    try:
        h, w = (int(v) for v in size)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ValueError(f"size must be the image (H, W), two integers, got {size!r:.60}") from None
    if not (0 < h <= MAX_IMAGE_SIDE and 0 < w <= MAX_IMAGE_SIDE):
        raise ValueError(f"size must be the image (H, W) with sides in 1..{MAX_IMAGE_SIDE}, got {size!r:.60}")
    return h, w


class CanvasBudget:
    """The pixels the lanes of one image may still be drawn on (``MAX_DRAWN_PIXELS``), taken before each canvas is
    allocated: the CULane, video and temporal metrics refuse the same input at the same point.

    Args:
        size: the image ``(H, W)`` (for the message).
    """

    def __init__(self, size: tuple[int, int]) -> None:
        self.size = size
        self.left = MAX_DRAWN_PIXELS

    def take(self, h: int, w: int) -> None:
        """Count an ``(h, w)`` canvas about to be allocated.

        Raises:
            ValueError: past the budget, before anything is allocated.
        """
        self.left -= h * w
        if self.left < 0:
            raise ValueError(
                f"the lanes of this image cover more than {MAX_DRAWN_PIXELS >> 20} Mpx of {self.size[1]}x{self.size[0]} "
                f"canvases: too large to draw in memory (fewer or shorter lanes, or a smaller --size)"
            )


class LaneFileError(ValueError):
    """An input file that cannot be evaluated; the message names the file and the problem."""


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


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name}")


def read_text(path: str | os.PathLike, limit: int = MAX_FILE_BYTES, universal_newlines: bool = True) -> str:
    """The text of a regular file of at most ``limit`` bytes; with ``universal_newlines`` "\\r\\n" and "\\r" read
    as "\\n", as ``open(path).read()`` (lane.py's reading).

    A FIFO, a device (``/dev/zero``), a socket or a directory is refused at once, never read: reading one would
    wait for a writer or never end.

    Raises:
        FileNotFoundError: no such file (callers that treat a missing file as empty catch it).
        LaneFileError: anything else that cannot be read: not a regular file, larger than ``limit``, not UTF-8.
    """
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK)  # O_NONBLOCK: a FIFO opens without waiting for a writer
    except FileNotFoundError:
        raise
    except OSError as e:
        raise LaneFileError(f"{p}: cannot read: {e.strerror}") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = "a directory" if stat.S_ISDIR(mode) else "a FIFO, device or socket"
            raise LaneFileError(f"{p}: cannot read: {kind}, not a regular file")
        chunks, size = [], 0
        while size <= limit:  # os.read, not a file object: 4,000 small files read 20 ms faster
            chunk = os.read(fd, min(limit + 1 - size, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        data = b"".join(chunks)
    finally:
        os.close(fd)
    if len(data) > limit:
        raise LaneFileError(f"{p}: larger than the limit of {limit >> 20} MiB")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise LaneFileError(f"{p}: cannot read: not UTF-8 text ({e.reason} at byte {e.start})") from None
    if universal_newlines and "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text


def _read(path: str | os.PathLike) -> str:
    try:
        return read_text(path)
    except FileNotFoundError as e:
        raise LaneFileError(f"{path}: cannot read: {e.strerror}") from None


def read_tusimple(path: str | os.PathLike, *, text: str | None = None) -> list[dict]:
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
        text = _read(p)
    if not text.strip():
        raise LaneFileError(f"{p}: empty file")
    body = text[:-1] if text.endswith("\n") else text
    try:  # fast path: one parse for the whole file (a blank line makes ",," and falls to the slow path)
        with _gc_paused():
            records = json.loads("[" + body.replace("\n", ",") + "]")
        if len(records) == body.count("\n") + 1 and all(type(r) is dict for r in records):
            _refuse_booleans(records, text, p)
            return records
    except (ValueError, RecursionError):  # RecursionError: nesting too deep; the slow path names the line
        pass
    out = []
    for _, rec in iter_tusimple(p, text=text):  # slow path: find the first bad line
        if isinstance(rec, LaneFileError):
            raise rec
        out.append(rec)
    _refuse_booleans(out, text, p)
    return out


@contextmanager
def _gc_paused() -> Iterator[None]:
    """The cyclic garbage collector off while JSON builds its (acyclic) lists: it would walk them again and again
    as they pile up, a third of the time of reading a TuSimple file."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _one_document(text: str) -> bool:
    """Whether ``text`` is ONE JSON value spread over several lines (a pretty-printed file)."""
    try:
        json.loads(text)
    except (ValueError, RecursionError):
        return False
    return text.strip().count("\n") > 0


def iter_tusimple(
    path: str | os.PathLike, role: str | None = None, *, text: str | None = None
) -> Iterator[tuple[int, dict | LaneFileError]]:
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
        text = _read(p)
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
            yield i, LaneFileError(f"{p}: line {i}: expected a JSON object, got {type(rec).__name__}")
            continue
        if role is not None and ("true" in line or "false" in line):
            try:
                _refuse_booleans([rec], line, p, first_line=i)
            except LaneFileError as err:
                yield i, err
                continue
        problem = tusimple_record_error(rec, role) if role else None
        yield i, (LaneFileError(f"{p}: line {i}: {problem}") if problem else rec)


def _refuse_booleans(records: list[dict], text: str, path: Path, first_line: int = 1, unit: str = "line") -> None:
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


def _numbers(value: object) -> list:
    return value if isinstance(value, list) else []


# ------------------------------------------------------------------------------- the TuSimple validator
_FILL = -100.0  # lane.py replaces every negative x by -100 before comparing; padding uses the same value
_KEYS = {
    "gt": (("raw_file", "lanes", "h_samples"), "raw_file or lanes or h_samples not in gt"),
    "pred": (("raw_file", "lanes", "run_time"), "raw_file or lanes or run_time not in some predictions."),
}
_SEQUENCES = (list, tuple, np.ndarray)
_LANE_ERROR = {"pred": "Format of lanes error: ", "gt": ""}  # lane.py's message for a prediction it cannot read


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
            are scored as lane.py scores them: ``(count, "line N: lane K has x = V")`` of the first, or None.
    """

    names: list[str]
    lanes: np.ndarray
    lengths: np.ndarray
    counts: np.ndarray
    h_samples: np.ndarray | None = None
    rows: np.ndarray | None = None
    run_times: np.ndarray | None = None
    odd: tuple[int, str] | None = None


def check_tusimple(records: Sequence[object], role: str) -> TuSimpleFile:
    """THE check of the TuSimple format (docs/evaluators.md, "What is scored and what is refused"), shared by
    ``stamlane_eval.tusimple.evaluate``, ``stamlane-eval`` and the training datasets (per record, through
    `tusimple_record_error`).

    - Types are the format's: objects with the keys lane.py reads, ``raw_file`` a non-empty string, ``lanes`` a
      list of lists of numbers, ``h_samples`` (gt) a list of numbers, ``run_time`` (pred) a number.
    - Sizes are bounded (memory): ``MAX_LANES`` lanes per image, ``MAX_LANE_POINTS`` rows.
    - A ground truth is a label: finite pixel coordinates (``|v| <= MAX_COORDINATE``), every lane as long as a
      non-empty ``h_samples``, and each ``raw_file`` once (lane.py would sum every line but divide by the
      unique names: an accuracy above 1).
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
    keys, missing_message = _KEYS[role]
    names: list[str] = []
    lanes_of: list[object] = []
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
            if name in first:
                raise TuSimpleInputError(duplicate_raw_file(name, f"line {first[name] + 1}"), role, i + 1)
            first[name] = i
        if not isinstance(rec["lanes"], _SEQUENCES):
            raise TuSimpleInputError(f"lanes must be a list of lists of numbers, got {rec['lanes']!r:.60}", role, i + 1)
        names.append(name)
        lanes_of.append(rec["lanes"])
        extra.append(rec[keys[2]])
    counts = np.fromiter(map(len, lanes_of), dtype=np.int64, count=len(lanes_of))
    if len(counts) and counts.max() > MAX_LANES:
        i = int(np.argmax(counts))
        raise TuSimpleInputError(f"{counts[i]} lanes, more than the limit of {MAX_LANES}", role, i + 1)
    if role == "gt":
        rows = _row_lengths(extra, role, "h_samples")
        h_samples, _ = _stack(extra, rows, np.arange(len(extra)), role, "h_samples", finite=True)
        empty = np.flatnonzero(rows == 0)
        if len(empty):
            raise TuSimpleInputError("h_samples is empty: no row to score", role, int(empty[0]) + 1)
    flat = [lane for lanes in lanes_of for lane in lanes]
    owner = np.repeat(np.arange(len(lanes_of)), counts)
    lengths = _row_lengths(flat, role, "lane", owner)
    lanes, odd = _stack(flat, lengths, owner, role, "lane", finite=role == "gt")
    if role == "gt":
        bad = np.flatnonzero(lengths != rows[owner])
        if len(bad):
            i = int(owner[bad[0]])
            raise TuSimpleInputError(
                f"{_name('lane', owner, int(bad[0]))} has {lengths[bad[0]]} x values, h_samples has {rows[i]}",
                role,
                i + 1,
            )
        return TuSimpleFile(names, lanes, lengths, counts, h_samples=h_samples, rows=rows)
    run_times = np.zeros(len(extra))
    for i, rt in enumerate(extra):
        if type(rt) not in (int, float):
            raise TuSimpleInputError(f"Format of lanes error: run_time must be a number, got {rt!r:.40}", role, i + 1)
        run_times[i] = _to_float(rt)
    odd_rt = np.flatnonzero(~np.isfinite(run_times))
    if len(odd_rt):
        first_rt = f"line {odd_rt[0] + 1}: run_time {run_times[odd_rt[0]]!r}"
        odd = (len(odd_rt) + (odd[0] if odd else 0), odd[1] if odd else first_rt)
    return TuSimpleFile(names, lanes, lengths, counts, run_times=run_times, odd=odd)


def duplicate_raw_file(name: str, first: str) -> str:
    """The one message for a ``raw_file`` named twice in ground truth (evaluator and training datasets)."""
    return (
        f"raw_file {name!r} again (first at {first}): two labels for one image (lane.py would sum both and "
        f"divide by the unique names, an accuracy above 1)"
    )


def _row_lengths(rows: list[object], role: str, kind: str, owner: np.ndarray | None = None) -> np.ndarray:
    """Lengths of number lists (each a list/tuple/array), checked against ``MAX_LANE_POINTS``."""
    for j, row in enumerate(rows):
        if not isinstance(row, _SEQUENCES):
            line = int(owner[j]) + 1 if owner is not None else j + 1
            raise TuSimpleInputError(
                f"{_LANE_ERROR[role]}{_name(kind, owner, j)} must be a list of numbers, got {row!r:.60}", role, line
            )
    lengths = np.fromiter(map(len, rows), dtype=np.int64, count=len(rows))
    if len(lengths) and lengths.max() > MAX_LANE_POINTS:
        j = int(np.argmax(lengths))
        line = int(owner[j]) + 1 if owner is not None else j + 1
        raise TuSimpleInputError(f"{kind} of {lengths[j]} values, more than the limit of {MAX_LANE_POINTS}", role, line)
    return lengths


def _to_float(v: int | float) -> float:
    """A JSON number as float64; an integer beyond the float range becomes +-inf (lane.py compares the exact
    integer: the same outcome, a miss or an absent row)."""
    try:
        return float(v)
    except OverflowError:
        return math.inf if v > 0 else -math.inf


def _stack(
    rows: list[object], lengths: np.ndarray, owner: np.ndarray, role: str, kind: str, finite: bool
) -> tuple[np.ndarray, tuple[int, str] | None]:
    """Number lists as one ``(len(rows), max length)`` float64 array padded with -100.

    Args:
        rows: the lists.
        lengths: their lengths.
        owner: the record of each list (for messages).
        role: ``"gt"`` or ``"pred"``.
        kind: ``"lane"`` or ``"h_samples"``.
        finite: refuse values that are no pixel coordinate (labels); else count them.

    Returns:
        The array and ``(count, description of the first)`` of the values that are no pixel coordinate.
    """
    width = int(lengths.max(initial=0))
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
    if finite:
        raise TuSimpleInputError(
            f"{_name(kind, owner, j)} has {float(out[j, col])!r}: not a pixel coordinate (a label must be finite, "
            f"|v| <= {MAX_COORDINATE:g})",
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
        return _to_float(v)
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


def tusimple_points(lanes: list, h_samples: list) -> list[np.ndarray]:
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
    records: Sequence[object], path: str | os.PathLike, h_samples: dict[str, list] | None = None
) -> tuple[dict[str, list[np.ndarray]], dict[str, list]]:
    """THE typed check of TuSimple-format files scored with the CULane metric (``stamlane-eval culane PRED.json
    GT.json``): the lanes of each ``raw_file`` as ``(x, y)`` points (rows with x < 0 dropped).

    The ground truth (``h_samples`` None) passes `check_tusimple` (types, each ``raw_file`` once, labels finite).
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
            check_tusimple(records, "gt")
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
        for k, lane in enumerate(rec["lanes"]):
            if not (isinstance(lane, list) and len(lane) == len(h) and all(map(_is_number, lane))):
                raise LaneFileError(
                    f"{path}: line {i}: lane {k} is not {len(h)} JSON numbers (one per h_sample; no string, no "
                    f"true/false)"
                )
            if not all(math.isfinite(_to_float(v)) for v in lane):
                raise LaneFileError(f"{path}: line {i}: lane {k} has a non-finite x")
        out[name] = tusimple_points(rec["lanes"], h)
    return out, rows


def read_culane_lines(
    path: str | os.PathLike, missing_ok: bool = True, *, prediction: bool = False
) -> list[np.ndarray]:
    """Read one CULane ``.lines.txt`` file.

    As the official C++ tool, every line is a lane, a blank line included (a lane with 0 points); a missing
    file is an image without lanes when ``missing_ok``.

    A prediction (``prediction=True``) is read as the C++ tool reads it (`cpp_stream_doubles`): a line's numbers
    up to the first token ``>>`` cannot read (``nan``, ``inf``, a word, ``1e400``), pairs only. A label is
    checked: only numbers, finite, an even count. Either way ``MAX_LANES`` lanes and ``MAX_IMAGE_POINTS``
    points per file (memory; no limit per lane).

    Args:
        path: the file.
        missing_ok: return ``[]`` for a missing file instead of raising.
        prediction: read as the C++ tool reads a prediction, instead of checking a label.

    Returns:
        Per lane, an ``(N, 2)`` float64 array of ``(x, y)`` points in file order.

    Raises:
        LaneFileError: unreadable file, too many lanes or points; a label with a non-number, NaN/inf, or an odd
            number of coordinates on a line.
    """
    p = Path(path)
    try:
        text = read_text(p, universal_newlines=False)
    except FileNotFoundError:
        if missing_ok:
            return []
        raise LaneFileError(f"{p}: no such file") from None
    lanes = []
    points = 0
    lines = text.split("\n")  # as the C++ getline: only "\n" ends a line; "\r" is whitespace inside one
    if lines[-1] == "":
        lines.pop()
    if len(lines) > MAX_LANES:
        raise LaneFileError(f"{p}: more than {MAX_LANES} lanes in one image ({len(lines)} lines)")
    for i, line in enumerate(lines, 1):
        raw = line.encode()
        vals = _plain_numbers(raw)
        if vals is None and prediction:
            vals = cpp_stream_doubles(raw)
        elif vals is None:
            raise LaneFileError(
                f"{p}: line {i}: not a finite number in {line.strip()[:60]!r} (a label holds numbers only; the C++ "
                f"tool would silently stop reading the line there)"
            )
        if len(vals) % 2:
            if not prediction:
                raise LaneFileError(f"{p}: line {i}: odd number of coordinates ({len(vals)}); expected x1 y1 x2 y2 ...")
            vals = vals[:-1]  # while (ss >> x >> y): an x without its y is never pushed
        points += len(vals) // 2
        if points > MAX_IMAGE_POINTS:
            raise LaneFileError(
                f"{p}: more than {MAX_IMAGE_POINTS} points in the lanes of one image (the memory budget of one image)"
            )
        lanes.append(np.array(vals, dtype=np.float64).reshape(-1, 2))
    return lanes


_PLAIN_TEXT = re.compile(rb"[0-9eE+\-. \t\v\f\r]*")
# What libstdc++'s num_get accumulates for one ``>> double`` after skipping C-locale white space: a sign, digits
# with at most one decimal point, then an exponent only after a digit ("1e" is accumulated, then refused whole).
_CPP_DOUBLE = re.compile(rb"[ \t\n\v\f\r]*([+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]*)?|\.)?)")


def _plain_numbers(raw: bytes) -> list[float] | None:
    """The numbers of a line made only of finite decimal numbers and blanks (what well-formed files hold), or
    None: there every token is a whole C++ ``>>`` read, so both readings agree. Python's ``float`` also reads
    ``1_000``, ``nan`` and ``inf``, which the character set keeps out, and 1e400 as inf, refused here."""
    if not _PLAIN_TEXT.fullmatch(raw):
        return None
    try:
        vals = list(map(float, raw.split()))  # C isspace: the ASCII blanks only, as the C++ ">>" skips them
    except ValueError:
        return None
    return vals if all(map(math.isfinite, vals)) else None


def cpp_stream_doubles(raw: bytes) -> list[float]:
    """The numbers ``while (ss >> x >> y)`` reads from one line in the official C++ tool (``read_lane_file`` of
    evaluate.cpp; libstdc++, C locale): every number up to the first read that fails.

    Quirks kept (each is what libstdc++'s ``num_get`` does, read from its source; the C++ tool was not run on them
    here): a read fails on a token that does not start like a number, so ``nan``, ``inf``, ``-nan`` and any word
    end the lane there, silently, the points before it kept; a read stops at the first character that cannot
    continue a number and the next read starts there (``20x`` is 20 then a failure, ``1-2`` is 1 then -2); a
    value beyond the double range (``1e400``) fails (strtod's overflow sets failbit), one below it reads as 0 or a
    denormal, as ``float`` does. The caller drops a last x without its y.

    Args:
        raw: one line, without its ``"\n"``.

    Returns:
        The values read, in order (finite).
    """
    vals: list[float] = []
    pos = 0
    while True:
        m = _CPP_DOUBLE.match(raw, pos)
        try:
            v = float(m.group(1))  # the accumulated characters must be one whole number, as strtod's check
        except ValueError:
            return vals  # nothing, or "1e", "-", ".": failbit
        if math.isinf(v):
            return vals  # overflow: libstdc++ stores +-DBL_MAX and sets failbit; the loop ends
        vals.append(v)
        pos = m.end()


def culane_lines_path(root: str | os.PathLike, entry: str) -> Path:
    """The ``.lines.txt`` of a list entry: ``/driver_x/y.MP4/00000.jpg`` -> ``root/driver_x/y.MP4/00000.lines.txt``.

    Raises:
        LaneFileError: an entry that would leave ``root`` (``..`` components, a drive); a list file is data and
            never names a file outside the folder it indexes.
    """
    if "\x00" in entry:
        raise LaneFileError(
            f"list entry {entry.strip()[:60]!r} holds a NUL byte: not a path (is the list a text file?)"
        )
    rel = entry.strip().lstrip("/")  # CULane lists write paths from the dataset root with a leading slash
    if "\\" not in rel and ":" not in rel:  # the common case, a plain a/b/c.jpg, without pathlib (same result)
        comps = rel.split("/")
        if "" not in comps and "." not in comps and ".." not in comps:
            stem = rel[: rel.rfind(".")] if "." in comps[-1] else rel
            if stem.endswith(".lines"):
                stem = stem[: -len(".lines")]
            return Path(root) / (stem + ".lines.txt")
    parts = PurePosixPath(rel.replace("\\", "/")).parts
    if ".." in parts or PureWindowsPath(rel).drive or not parts:
        raise LaneFileError(f"list entry {entry.strip()!r} leaves the folder {root} (no '..', no drive, not empty)")
    stem = rel[: rel.rfind(".")] if "." in Path(rel).name else rel
    if stem.endswith(".lines"):
        stem = stem[: -len(".lines")]
    return Path(root) / (stem + ".lines.txt")


def inside(path: Path, root: Path) -> Path:
    """``path`` after checking that, symlinks resolved, it lies in ``root``: a link in a prediction or annotation
    folder never makes the evaluator read (and quote in an error) a file elsewhere.

    Raises:
        LaneFileError: naming the link and where it leads.
    """
    real = path.resolve()
    if not real.is_relative_to(root.resolve()):
        raise LaneFileError(f"{path}: a link to {real}, outside the folder {root}")
    return path


class Inside:
    """:func:`inside` for many files under one ``root``: the root and each folder resolved once (a file that is not
    a link resolves to its resolved folder + its name), the file itself checked with one ``lstat``."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.real_root = root.resolve()
        self.folders: dict[Path, Path] = {}

    def __call__(self, path: Path) -> Path:
        name = path.name
        if name in ("", ".", "..") or os.path.islink(path):
            real = path.resolve()
        else:
            folder = self.folders.get(path.parent)
            if folder is None:
                folder = self.folders[path.parent] = path.parent.resolve()
            real = folder / name
        if not real.is_relative_to(self.real_root):
            raise LaneFileError(f"{path}: a link to {real}, outside the folder {self.root}")
        return path


def culane_entries(gt_dir: str | os.PathLike, list_file: str | os.PathLike | None = None) -> list[str]:
    """The images to evaluate: the lines of ``list_file``, or every ``.lines.txt`` under ``gt_dir`` (sorted).

    Raises:
        LaneFileError: unreadable or empty list, missing ``gt_dir``, no annotation found, an entry outside
            ``gt_dir`` or two entries naming one image.
    """
    root = Path(gt_dir)
    if not root.is_dir():
        raise LaneFileError(f"{root}: not a directory")
    if list_file is not None:
        entries = [ln.strip() for ln in _read(list_file).split("\n") if ln.strip()]
        if not entries:
            raise LaneFileError(f"{list_file}: empty list")
        first: dict[Path, int] = {}
        for i, entry in enumerate(entries):  # the C++ tool would score such an image twice
            path = culane_lines_path(root, entry)
            if path in first:
                raise LaneFileError(
                    f"{list_file}: entries {first[path] + 1} and {i + 1} name the same image ({entry.strip()!r}): "
                    f"two results for one image"
                )
            first[path] = i
        return entries
    entries = sorted("/" + str(q.relative_to(root).as_posix()) for q in _walk_lines(root))
    if not entries:
        raise LaneFileError(f"{root}: no .lines.txt file found")
    return entries


def _walk_lines(root: Path) -> Iterator[Path]:
    for dirpath, _, files in os.walk(root):
        for f in files:
            if f.endswith(".lines.txt"):
                yield Path(dirpath) / f


def read_vil100_json(path: str | os.PathLike) -> tuple[list[np.ndarray], list[int], tuple[int, int] | None]:
    """Read one VIL-100 frame annotation (``Json/<video>/<frame>.jpg.json``): THE typed check of the format.

    Types are the format's and nothing else is read as a number: ``points`` a list of ``[x, y]`` pairs of JSON
    numbers (a string, ``true``/``false`` or ``null`` is refused: Python's ``float(True)`` would read 1), each
    ``|v| <= MAX_COORDINATE`` and finite (a label); ``lane_id`` an integer; ``info.width`` / ``info.height``
    integers (``1920`` or ``1920.0``, not ``"1920"`` nor ``true``) in ``1..MAX_IMAGE_SIDE``.

    Returns:
        lanes (``(N, 2)`` float ``(x, y)`` arrays), their ``lane_id``s, and the image ``(H, W)`` from ``info``
        (None when absent).

    Raises:
        LaneFileError: unreadable file, invalid JSON, a missing/odd ``annotations.lane`` entry or a value of the
            wrong type, naming the lane and the value.
    """
    p = Path(path)
    text = _read(p)
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
    if len(entries) > MAX_LANES:
        raise LaneFileError(f"{p}: {len(entries)} lanes, more than the limit of {MAX_LANES}")
    lanes, ids = [], []
    for k, lane in enumerate(entries):
        if not isinstance(lane, dict) or "points" not in lane:
            raise LaneFileError(f"{p}: lane {k}: needs points [[x, y], ...] and an integer lane_id")
        lanes.append(_vil100_points(lane["points"], p, k))
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


def _is_number(v: object) -> bool:
    """A JSON number: ``int`` or ``float``, never ``bool`` (a subclass of int) nor a string."""
    return type(v) is int or type(v) is float


def _vil100_points(points: object, path: Path, k: int) -> np.ndarray:
    """``[[x, y], ...]`` of JSON numbers as an ``(N, 2)`` float64 array, checked one value at a time."""
    if not isinstance(points, list):
        raise LaneFileError(f"{path}: lane {k}: points must be a list of [x, y] pairs, got {points!r:.40}")
    if len(points) > MAX_LANE_POINTS:
        raise LaneFileError(f"{path}: lane {k}: {len(points)} points, more than the limit of {MAX_LANE_POINTS}")
    for pt in points:
        if not (isinstance(pt, list) and len(pt) == 2 and _is_number(pt[0]) and _is_number(pt[1])):
            what = "a boolean" if isinstance(pt, list) and any(type(v) is bool for v in pt) else repr(pt)[:40]
            raise LaneFileError(f"{path}: lane {k}: a point must be [x, y], two JSON numbers, got {what}")
    try:
        arr = np.array(points, dtype=np.float64).reshape(-1, 2)
    except OverflowError:  # an integer beyond the float range
        arr = np.full((1, 2), np.inf)
    if not (np.abs(arr) <= MAX_COORDINATE).all():
        raise LaneFileError(
            f"{path}: lane {k}: a coordinate that is no pixel of an image (a label must be finite, "
            f"|v| <= {MAX_COORDINATE:g})"
        )
    return arr


def _vil100_side(v: object, name: str, path: Path) -> int:
    """``info.width`` / ``info.height``: an integer, or a float with an integer value (``1920.0``)."""
    if type(v) is int:
        return v
    if type(v) is float and v.is_integer():
        return int(v)
    raise LaneFileError(f"{path}: info.{name} must be an integer number of pixels, got {v!r:.40}")


def video_frames(gt_dir: str | os.PathLike) -> tuple[str, dict[str, list[tuple[str, Path]]]]:
    """The sequences and frames of an annotated video set, in name order.

    Two layouts: VIL-100 (``GT/Json/<video>/<frame>.jpg.json``) or CULane-style text
    (``GT/<video>/<frame>.lines.txt``).

    Returns:
        ``("vil100" | "lines", {sequence: [(frame_stem, annotation_path), ...]})``; the prediction of a frame is
        ``PRED/<sequence>/<frame_stem>.lines.txt``.

    Raises:
        LaneFileError: no such folder, no annotation found, or one frame labelled twice (``00001.jpg.json`` and
            ``00001.png.json``: both would be scored, against the one prediction of the frame).
    """
    root = Path(gt_dir)
    if not root.is_dir():
        raise LaneFileError(f"{root}: not a directory")
    seqs: dict[str, list[tuple[str, Path]]] = {}
    seen: dict[tuple[str, str], Path] = {}  # (sequence, frame) -> its label file
    if (root / "Json").is_dir():
        kind, base, suffix = "vil100", root / "Json", ".json"
    else:
        kind, base, suffix = "lines", root, ".lines.txt"
    for dirpath, _, files in sorted(os.walk(base)):
        for f in sorted(files):
            if not f.endswith(suffix):
                continue
            stem = f[: -len(suffix)]
            stem = stem[: stem.rfind(".")] if kind == "vil100" and "." in stem else stem  # 00000.jpg -> 00000
            seq = Path(dirpath).relative_to(base).as_posix()
            path = Path(dirpath) / f
            first = seen.setdefault((seq, stem), path)
            if first != path:
                raise LaneFileError(
                    f"{path}: frame {seq}/{stem} is labelled twice (also by {first.name}): two labels for one frame"
                )
            seqs.setdefault(seq, []).append((stem, path))
    if not seqs:
        raise LaneFileError(
            f"{root}: no annotation found (expected Json/<video>/*.json, <video>/*.lines.txt, or TuSimple records: "
            f"*.json files in the folder, or a json-lines file)"
        )
    return kind, seqs


# ------------------------------------------------------------------------- TuSimple records as video frames
TUSIMPLE_SUFFIXES = (".json", ".jsonl")
"""Files of a folder that `read_tusimple_frames` reads (``frame_labels/<clip>.json``, ``predictions.json``)."""


@dataclass(frozen=True)
class TuSimpleFrames:
    """TuSimple records as the frames of sequences: the sequence of a frame is the folder of its ``raw_file``
    (``clips/0530/20.jpg``: sequence ``clips/0530``, frame ``20``).

    Attributes:
        sequences: per sequence (in name order, as the folders of CULane text), its frame names in the order of
            the records, files of a folder in name order: time order as written (``1 .. 12``, not ``1, 10 ..``).
        lanes: per ``(sequence, frame)``, the lanes as ``(N, 2)`` float64 ``(x, y)`` points in original pixels,
            rows with x < 0 dropped (a lane absent on every row: 0 points, as an empty line of a ``.lines.txt``).
        rows: per ``(sequence, frame)``, its ``h_samples``.
        timed: records that carry a ``run_time`` (predictions do, labels never: a sign of swapped inputs).
    """

    sequences: dict[str, list[str]]
    lanes: dict[tuple[str, str], list[np.ndarray]]
    rows: dict[tuple[str, str], list]
    timed: int = 0


def tusimple_frame_key(raw_file: str) -> tuple[str, str] | None:
    """``(sequence, frame)`` of a ``raw_file``: its folder and its name without the extension; None where it names
    no folder."""
    seq, _, name = raw_file.replace("\\", "/").rpartition("/")
    seq = seq.strip("/")
    stem = name[: name.rfind(".")] if "." in name else name
    return (seq, stem) if seq and stem else None


def _tusimple_file_records(path: Path) -> tuple[list[dict], str]:
    """The records of one file: json-lines (``predictions.json``, ``challenging-frames.json``) or one JSON list of
    objects (the generator's ``frame_labels/<clip>.json``), and how a message names a record."""
    text = _read(path)
    if not text.lstrip().startswith("["):
        return read_tusimple(path, text=text), "line"
    try:
        with _gc_paused():
            data = json.loads(text)
    except ValueError:
        return read_tusimple(path, text=text), "line"  # a json-lines file of arrays: its own message per line
    except RecursionError:
        raise LaneFileError(f"{path}: JSON nested too deeply") from None
    if not isinstance(data, list) or not data:
        raise LaneFileError(f"{path}: expected a non-empty JSON list of TuSimple records, or json-lines")
    for i, rec in enumerate(data, 1):
        if type(rec) is not dict:
            raise LaneFileError(f"{path}: record {i}: expected a JSON object, got {type(rec).__name__}")
    _refuse_booleans(data, text, path, unit="record")
    return data, "record"


def _tusimple_files(path: Path) -> list[Path]:
    """A file, or the ``TUSIMPLE_SUFFIXES`` files directly in a folder, in name order."""
    if not path.is_dir():
        return [path]
    files = sorted(q for q in path.iterdir() if q.name.endswith(TUSIMPLE_SUFFIXES) and not q.name.startswith("."))
    if not files:
        raise LaneFileError(f"{path}: no .json or .jsonl file in the folder (TuSimple records expected)")
    return files


def read_tusimple_frames(
    path: str | os.PathLike, role: str, rows: dict[tuple[str, str], list] | None = None
) -> TuSimpleFrames:
    """THE typed reader of TuSimple records scored as video frames (``stamlane-eval video``): a json-lines file,
    a file holding one JSON list of records, or a folder of such files (``.json``/``.jsonl`` directly in it, in
    name order; a file that is a link to outside the folder is refused).

    A ground truth (``role="gt"``) passes `check_tusimple` file by file (types, finite labels, every lane as long
    as ``h_samples``); a frame is labelled once across all files. A prediction (``role="pred"``) has ``raw_file``
    and ``lanes``, lanes of JSON numbers (no string, no ``true``/``false``), finite, one per row of its own
    ``h_samples`` or, without them, of the ground truth's frame (``rows``); a frame is predicted once. A
    prediction of a frame the ground truth lacks is left out, as a ``.lines.txt`` of such a frame is; so is its
    checking when it has no ``h_samples`` of its own.

    Args:
        path: the file or folder.
        role: ``"gt"`` or ``"pred"``.
        rows: the ground truth's ``h_samples`` per ``(sequence, frame)`` when it is TuSimple (reading a
            prediction), or None.

    Returns:
        The frames, grouped by sequence.

    Raises:
        LaneFileError: naming the file, the line (or record) and the problem.
    """
    if role not in ("gt", "pred"):
        raise ValueError(f"role must be 'gt' or 'pred', got {role!r}")
    root = Path(path)
    sequences: dict[str, list[str]] = {}
    lanes: dict[tuple[str, str], list[np.ndarray]] = {}
    out_rows: dict[tuple[str, str], list] = {}
    first: dict[tuple[str, str], str] = {}
    timed = 0
    for file in _tusimple_files(root):
        if file is not root:
            inside(file, root)
        records, unit = _tusimple_file_records(file)
        if role == "gt":
            try:
                check_tusimple(records, "gt")
            except TuSimpleInputError as e:
                raise LaneFileError(f"{file}: {unit} {e.line}: {e.message}") from None
        timed += sum("run_time" in rec for rec in records)
        for i, rec in enumerate(records, 1):
            where = f"{file}: {unit} {i}"
            name = rec.get("raw_file")
            if type(name) is not str or not isinstance(rec.get("lanes"), list):
                raise LaneFileError(f"{where}: needs raw_file (a string) and lanes (a list), has {sorted(rec)[:6]}")
            key = tusimple_frame_key(name)
            if key is None:
                raise LaneFileError(
                    f"{where}: raw_file {name!r:.80} names no folder: the folder of raw_file is the sequence "
                    f"(clips/<clip>/<frame>.jpg)"
                )
            h = rec.get("h_samples")
            if role == "pred":
                if h is None and rows is not None and key not in rows:
                    continue  # a frame the ground truth lacks: not scored
                h = _frame_rows(h, rows, key, where)
                _check_pred_lanes(rec["lanes"], len(h), where)
            if key in first:
                what = "labelled" if role == "gt" else "predicted"
                raise LaneFileError(f"{where}: frame {key[0]}/{key[1]} is {what} twice (also at {first[key]})")
            first[key] = where
            sequences.setdefault(key[0], []).append(key[1])
            lanes[key] = tusimple_points(rec["lanes"], h)
            out_rows[key] = h
    return TuSimpleFrames(dict(sorted(sequences.items())), lanes, out_rows, timed)


def _frame_rows(h: object, rows: dict[tuple[str, str], list] | None, key: tuple[str, str], where: str) -> list:
    """A prediction's rows: its own ``h_samples`` (a list of finite JSON numbers, at most ``MAX_LANE_POINTS``), or
    the ground truth's frame's."""
    if h is None:
        h = None if rows is None else rows.get(key)
        if h is None:
            raise LaneFileError(
                f"{where}: no h_samples, and the ground truth has none for this frame (give predictions with "
                f"h_samples, as stamlane predict writes them, or TuSimple ground truth)"
            )
        return h
    if not (isinstance(h, list) and len(h) <= MAX_LANE_POINTS and all(map(_is_number, h))):
        raise LaneFileError(f"{where}: h_samples must be a list of at most {MAX_LANE_POINTS} JSON numbers")
    if not all(math.isfinite(_to_float(v)) and abs(v) <= MAX_COORDINATE for v in h):
        raise LaneFileError(f"{where}: h_samples holds a value that is no pixel row (|y| <= {MAX_COORDINATE:g})")
    return h


def _check_pred_lanes(pred_lanes: list, rows: int, where: str) -> None:
    """A prediction's lanes: at most ``MAX_LANES``, each ``rows`` finite JSON numbers."""
    if len(pred_lanes) > MAX_LANES:
        raise LaneFileError(f"{where}: {len(pred_lanes)} lanes, more than the limit of {MAX_LANES}")
    for k, lane in enumerate(pred_lanes):
        if not (isinstance(lane, list) and len(lane) == rows and all(map(_is_number, lane))):
            raise LaneFileError(
                f"{where}: lane {k} is not {rows} JSON numbers (one per h_sample; no string, no true/false)"
            )
        if not all(math.isfinite(_to_float(v)) for v in lane):
            raise LaneFileError(f"{where}: lane {k} has a non-finite x")
