"""CULane / ApolloScape text: one ``.lines.txt`` per image, one lane per line (``x1 y1 x2 y2 ...``), images named by
a list file (``/driver_x/y.MP4/00000.jpg``) or found under a folder.

- reading a label (checked) or a prediction (as the C++ tool's ``>>`` reads it): `read_culane_lines`,
  `cpp_stream_doubles`; the folders of a dataset and of predictions: `culane_entries`, `culane_lines_path`,
  `read_culane_folders`, `images_beside`;
- what the C++ tool writes to its ``-o`` file: `cpp_tool_text`.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator, Sequence
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

from stamlane_eval.aggregate import prf
from stamlane_eval.io.files import Inside, LaneFileError, read_file, read_text
from stamlane_eval.io.limits import MAX_IMAGE_POINTS, MAX_LANES

__all__ = [
    "IMAGE_SUFFIXES",
    "cpp_stream_doubles",
    "cpp_tool_text",
    "culane_entries",
    "culane_lines_path",
    "images_beside",
    "read_culane_folders",
    "read_culane_lines",
]

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
"""Images a dataset keeps beside its ``.lines.txt`` (a prediction folder holds none)."""


def read_culane_lines(
    path: str | os.PathLike[str], missing_ok: bool = True, *, prediction: bool = False
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
    if len(lines) > MAX_LANES:  # time: the C++ tool scores any count; MAX_LANES bounds the matching's cubic cost
        raise LaneFileError(
            f"{p}: more than {MAX_LANES} lanes in one image ({len(lines)} lines): past the time budget of the matching"
        )
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
        assert m is not None  # every part of the pattern is optional: it matches at any position
        try:
            v = float(m.group(1))  # the accumulated characters must be one whole number, as strtod's check
        except ValueError:
            return vals  # nothing, or "1e", "-", ".": failbit
        if math.isinf(v):
            return vals  # overflow: libstdc++ stores +-DBL_MAX and sets failbit; the loop ends
        vals.append(v)
        pos = m.end()


def culane_lines_path(root: str | os.PathLike[str], entry: str) -> Path:
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


def culane_entries(gt_dir: str | os.PathLike[str], list_file: str | os.PathLike[str] | None = None) -> list[str]:
    """The images to evaluate: the lines of ``list_file``, or every ``.lines.txt`` under ``gt_dir`` (sorted).

    Raises:
        LaneFileError: unreadable or empty list, missing ``gt_dir``, no annotation found, an entry outside
            ``gt_dir`` or two entries naming one image.
    """
    root = Path(gt_dir)
    if not root.is_dir():
        raise LaneFileError(f"{root}: not a directory")
    if list_file is not None:
        entries = [ln.strip() for ln in read_file(list_file).split("\n") if ln.strip()]
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


def read_culane_folders(
    pred_dir: Path, gt_dir: Path, entries: Sequence[str]
) -> tuple[list[list[np.ndarray]], list[list[np.ndarray]]]:
    """The predicted and annotated lanes of the images ``entries`` names (`culane_entries`), read from the two
    folders as the C++ tool reads them (a missing prediction: no lanes; a missing annotation: an error), nothing
    read outside the folders given, through links either (`Inside`).

    Returns:
        ``(preds, gts)``: per entry, the lanes as ``(N, 2)`` ``(x, y)`` points.

    Raises:
        LaneFileError: naming the file and the problem.
    """
    gt_root, pred_root = gt_dir.resolve(), pred_dir.resolve()
    in_gt, in_pred = Inside(gt_root), Inside(pred_root)
    gts = [read_culane_lines(in_gt(culane_lines_path(gt_root, e)), missing_ok=False) for e in entries]
    preds = [read_culane_lines(in_pred(culane_lines_path(pred_root, e)), prediction=True) for e in entries]
    return preds, gts


def images_beside(root: Path, entries: Sequence[str]) -> int:
    """How many of ``entries`` have an image (`IMAGE_SUFFIXES`) beside their ``.lines.txt`` under ``root``, as in a
    dataset root (looked up, never read)."""
    found = 0
    for entry in entries:
        lines = culane_lines_path(root, entry)
        stem = lines.name[: -len(".lines.txt")]
        found += any(os.path.isfile(lines.parent / (stem + suffix)) for suffix in IMAGE_SUFFIXES)  # no OSError
    return found


def cpp_tool_text(tp: int, fp: int, fn: int) -> str:
    """What the official C++ tool writes per threshold (its -o file without the ``file:`` line; iostream's default
    6 significant digits), 0/0 cases included.

    ``Counter::get_precision`` / ``get_recall`` return -1 where tp + fp (tp + fn) is 0, and evaluate.cpp computes
    ``F = 2 * precision * recall / (precision + recall)`` from those: -1 when both are -1, 0 when one is -1 and
    the other 0 (-0.0 / -1.0), and 0.0 / 0.0 when tp = 0 with fp and fn > 0: x86's default NaN, sign bit set,
    which glibc prints "-nan" (the fixtures' README: "F is then -1 or NaN"; this -nan is glibc's spelling, the
    C++ tool was not run on such a case here).
    """
    p, r, _ = prf(tp, fp, fn)  # tp/double(tp + fp), tp/double(tp + fn)
    precision = -1.0 if tp + fp == 0 else p
    recall = -1.0 if tp + fn == 0 else r
    if precision + recall == 0.0:
        fmeasure = "-nan"  # 0.0 / 0.0 on x86-64 (SSE): the "default NaN", negative
    else:
        fmeasure = f"{2 * precision * recall / (precision + recall):.6g}"
    return f"tp: {tp} fp: {fp} fn: {fn}\nprecision: {precision:.6g}\nrecall: {recall:.6g}\nFmeasure: {fmeasure}\n"
