"""Readers for the benchmark file formats, with errors that name the file, the line and the problem.

- TuSimple: json-lines, one object per line (``raw_file``, ``lanes``, ``h_samples`` / ``run_time``).
- CULane / ApolloScape: one ``.lines.txt`` per image, one lane per line, ``x1 y1 x2 y2 ...``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

__all__ = [
    "MAX_COORDINATE",
    "MAX_IMAGE_SIDE",
    "MAX_LANES",
    "MAX_LANE_POINTS",
    "MAX_LANE_WIDTH",
    "LaneFileError",
    "culane_entries",
    "culane_lines_path",
    "iter_tusimple",
    "read_culane_lines",
    "read_tusimple",
    "read_vil100_json",
    "tusimple_points",
    "tusimple_record_error",
    "video_frames",
]


MAX_IMAGE_SIDE = 16384
"""Largest image side (px) accepted from a label file or ``--size``: the CULane metric draws every lane into a mask of
the image's size, so a declared 200000x200000 frame would ask for tens of GiB."""
MAX_LANES = 64
"""Most lanes in one image: the CULane matching grows with the cube of the lane count (1,500 lanes: a minute)."""
MAX_LANE_POINTS = 10000
"""Most points in one lane (a CULane lane of 1M points took 3.4 GB to rasterise)."""
MAX_LANE_WIDTH = 1024
"""Widest lane line (px) the CULane metric may draw."""
MAX_COORDINATE = 100_000.0
"""Largest absolute pixel coordinate accepted in a label or prediction (6x ``MAX_IMAGE_SIDE``): a 1e12 is a bug
in whatever wrote the file, not a lane (the official tools score it as a far-off point; we refuse it)."""


class LaneFileError(ValueError):
    """An input file that cannot be evaluated; the message names the file and the problem."""


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name}")


def read_tusimple(path: str | os.PathLike) -> list[dict]:
    """Read a TuSimple json-lines file (predictions or ground truth).

    As the official ``lane.py`` (``[json.loads(line) for line in readlines()]``), every line must be one JSON
    object: a blank line, including a blank line at the end of the file, is an error.

    Args:
        path: the file.

    Returns:
        The records in file order.

    Raises:
        LaneFileError: unreadable file, invalid JSON (with its line number), a line that is not an object,
            NaN/Infinity literals, or an empty file.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise LaneFileError(f"{p}: cannot read: {e}") from None
    if not text.strip():
        raise LaneFileError(f"{p}: empty file")
    body = text[:-1] if text.endswith("\n") else text
    try:  # fast path: one parse for the whole file (a blank line makes ",," and falls to the slow path)
        records = json.loads("[" + body.replace("\n", ",") + "]", parse_constant=_reject_constant)
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
        try:
            text = p.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as e:
            raise LaneFileError(f"{p}: cannot read: {e}") from None
    for i, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            yield i, LaneFileError(f"{p}: line {i} is blank (every line must be one JSON object, as lane.py requires)")
            continue
        try:
            rec = json.loads(line, parse_constant=_reject_constant)
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
        problem = tusimple_record_error(rec, role) if role else None
        yield i, (LaneFileError(f"{p}: line {i}: {problem}") if problem else rec)


def _refuse_booleans(records: list[dict], text: str, path: Path) -> None:
    """JSON ``true``/``false`` where a number belongs (lane.py would read them as 1 and 0): refused. Only
    looked for when the words occur in the file at all."""
    if "true" not in text and "false" not in text:
        return
    for i, rec in enumerate(records, 1):
        values = [rec.get("run_time"), *_numbers(rec.get("h_samples"))]
        lanes = rec.get("lanes")
        for lane in lanes if isinstance(lanes, list) else []:
            values += _numbers(lane)
        if any(type(v) is bool for v in values):
            raise LaneFileError(f"{path}: line {i}: a boolean (true/false) where a number belongs")


def _numbers(value: object) -> list:
    return value if isinstance(value, list) else []


def _number_list_error(values: object, what: str) -> str | None:
    if not isinstance(values, list):
        return f"{what} must be a list of numbers, got {values!r:.60}"
    for v in values:
        if type(v) not in (int, float):
            return f"{what} must be a list of numbers, got {v!r:.40} in it"
        if not math.isfinite(v) or abs(v) > MAX_COORDINATE:
            return f"{what} has {v!r}: not a pixel coordinate (finite, |v| <= {MAX_COORDINATE:g})"
    return None


def tusimple_record_error(rec: object, role: str) -> str | None:
    """What is wrong with one TuSimple record, or None: the one typed check of the format that the datasets use
    per record and that ``stamlane_eval.tusimple.evaluate`` applies (vectorised) to whole files.

    Args:
        rec: a parsed json line.
        role: ``"gt"`` (``raw_file``, ``lanes``, ``h_samples`` required; every lane as long as ``h_samples``,
            which is not empty) or ``"pred"`` (``raw_file``, ``lanes``; ``run_time`` a number when present;
            lanes as long as ``h_samples`` when the record has them).

    Returns:
        a one-line description naming the key, or None for a good record.
    """
    if role not in ("gt", "pred"):
        raise ValueError(f"role must be 'gt' or 'pred', got {role!r}")
    if not isinstance(rec, dict):
        return f"expected a JSON object, got {type(rec).__name__}"
    needed = ("raw_file", "lanes", "h_samples") if role == "gt" else ("raw_file", "lanes")
    missing = [k for k in needed if k not in rec]
    if missing:
        return f"missing key(s) {missing} (has {sorted(rec)[:6]})"
    if not isinstance(rec["raw_file"], str) or not rec["raw_file"].strip():
        return f"raw_file must be a non-empty string, got {rec['raw_file']!r:.60}"
    lanes = rec["lanes"]
    if not isinstance(lanes, list):
        return f"lanes must be a list of lists, got {lanes!r:.60}"
    if len(lanes) > MAX_LANES:
        return f"{len(lanes)} lanes, more than the limit of {MAX_LANES}"
    rows = rec.get("h_samples")
    if rows is not None or role == "gt":
        problem = _number_list_error(rows, "h_samples")
        if problem:
            return problem
        if not rows:
            return "h_samples is empty: no row to score"
    if role == "pred" and "run_time" in rec:
        rt = rec["run_time"]
        if type(rt) not in (int, float) or not math.isfinite(rt):
            return f"run_time must be a finite number, got {rt!r:.40}"
    for k, lane in enumerate(lanes):
        problem = _number_list_error(lane, f"lane {k}")
        if problem:
            return problem
        if rows is not None and len(lane) != len(rows):
            return f"lane {k} has {len(lane)} x values, h_samples has {len(rows)}"
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


def read_culane_lines(path: str | os.PathLike, missing_ok: bool = True) -> list[np.ndarray]:
    """Read one CULane ``.lines.txt`` file.

    As the official C++ tool, every line is a lane, a blank line included (a lane with 0 points); a missing
    file is an image without lanes when ``missing_ok``.

    Args:
        path: the file.
        missing_ok: return ``[]`` for a missing file instead of raising.

    Returns:
        Per lane, an ``(N, 2)`` float64 array of ``(x, y)`` points in file order.

    Raises:
        LaneFileError: unreadable file, a non-number, NaN/inf, or an odd number of coordinates on a line.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        if missing_ok:
            return []
        raise LaneFileError(f"{p}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise LaneFileError(f"{p}: cannot read: {e}") from None
    lanes = []
    for i, line in enumerate(text.splitlines(), 1):
        fields = line.split()
        try:
            vals = [float(v) for v in fields]
        except ValueError:
            raise LaneFileError(f"{p}: line {i}: not a number in {line.strip()[:60]!r}") from None
        if len(vals) % 2:
            raise LaneFileError(f"{p}: line {i}: odd number of coordinates ({len(vals)}); expected x1 y1 x2 y2 ...")
        if not all(math.isfinite(v) for v in vals):
            raise LaneFileError(f"{p}: line {i}: non-finite coordinate (nan/inf)")
        if len(vals) // 2 > MAX_LANE_POINTS:
            raise LaneFileError(f"{p}: line {i}: {len(vals) // 2} points, more than the limit of {MAX_LANE_POINTS}")
        lanes.append(np.array(vals, dtype=np.float64).reshape(-1, 2))
        if len(lanes) > MAX_LANES:
            raise LaneFileError(f"{p}: more than {MAX_LANES} lanes in one image")
    return lanes


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
    parts = PurePosixPath(rel.replace("\\", "/")).parts
    if ".." in parts or PureWindowsPath(rel).drive or not parts:
        raise LaneFileError(f"list entry {entry.strip()!r} leaves the folder {root} (no '..', no drive, not empty)")
    stem = rel[: rel.rfind(".")] if "." in Path(rel).name else rel
    if stem.endswith(".lines"):
        stem = stem[: -len(".lines")]
    return Path(root) / (stem + ".lines.txt")


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
        try:
            entries = [ln.strip() for ln in Path(list_file).read_text(encoding="utf-8").splitlines() if ln.strip()]
        except (OSError, UnicodeDecodeError) as e:
            raise LaneFileError(f"{list_file}: cannot read: {e}") from None
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
    """Read one VIL-100 frame annotation (``Json/<video>/<frame>.jpg.json``).

    Returns:
        lanes (``(N, 2)`` float ``(x, y)`` arrays), their ``lane_id``s, and the image ``(H, W)`` from ``info``
        (None when absent).

    Raises:
        LaneFileError: unreadable file, invalid JSON, or a missing/odd ``annotations.lane`` entry.
    """
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"), parse_constant=_reject_constant)
    except (OSError, UnicodeDecodeError) as e:
        raise LaneFileError(f"{p}: cannot read: {e}") from None
    except ValueError as e:
        raise LaneFileError(f"{p}: invalid JSON ({e})") from None
    except RecursionError:
        raise LaneFileError(f"{p}: JSON nested too deeply") from None
    try:
        entries = data["annotations"]["lane"]
        info = data.get("info", {})
    except (KeyError, TypeError):
        raise LaneFileError(f"{p}: no annotations.lane list (VIL-100 format expected)") from None
    if not isinstance(entries, list):
        raise LaneFileError(f"{p}: annotations.lane must be a list, got {type(entries).__name__}")
    lanes, ids = [], []
    for k, lane in enumerate(entries):
        try:
            pts = np.asarray(lane["points"], dtype=np.float64).reshape(-1, 2)
            lane_id = int(lane.get("lane_id", k))
        except (KeyError, TypeError, ValueError):
            raise LaneFileError(f"{p}: lane {k}: needs points [[x, y], ...] and an integer lane_id") from None
        if not np.isfinite(pts).all():
            raise LaneFileError(f"{p}: lane {k}: non-finite coordinate")
        lanes.append(pts)
        ids.append(lane_id)
    if len(set(ids)) != len(ids):
        raise LaneFileError(f"{p}: duplicate lane_id in {ids}")
    size = None
    if isinstance(info, dict) and "width" in info and "height" in info:
        try:
            size = (int(info["height"]), int(info["width"]))
        except (TypeError, ValueError):
            raise LaneFileError(f"{p}: info.width/height must be integers") from None
        if not (0 < size[0] <= MAX_IMAGE_SIDE and 0 < size[1] <= MAX_IMAGE_SIDE):
            raise LaneFileError(f"{p}: image size {size[1]}x{size[0]} (WxH) outside 1..{MAX_IMAGE_SIDE} px per side")
    if len(lanes) > MAX_LANES or any(len(lane) > MAX_LANE_POINTS for lane in lanes):
        raise LaneFileError(f"{p}: more than {MAX_LANES} lanes or {MAX_LANE_POINTS} points in a lane")
    return lanes, ids, size


def video_frames(gt_dir: str | os.PathLike) -> tuple[str, dict[str, list[tuple[str, Path]]]]:
    """The sequences and frames of an annotated video set, in name order.

    Two layouts: VIL-100 (``GT/Json/<video>/<frame>.jpg.json``) or CULane-style text
    (``GT/<video>/<frame>.lines.txt``).

    Returns:
        ``("vil100" | "lines", {sequence: [(frame_stem, annotation_path), ...]})``; the prediction of a frame is
        ``PRED/<sequence>/<frame_stem>.lines.txt``.

    Raises:
        LaneFileError: no such folder, or no annotation found.
    """
    root = Path(gt_dir)
    if not root.is_dir():
        raise LaneFileError(f"{root}: not a directory")
    seqs: dict[str, list[tuple[str, Path]]] = {}
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
            seqs.setdefault(seq, []).append((stem, Path(dirpath) / f))
    if not seqs:
        raise LaneFileError(f"{root}: no annotation found (expected Json/<video>/*.json or <video>/*.lines.txt)")
    return kind, seqs
