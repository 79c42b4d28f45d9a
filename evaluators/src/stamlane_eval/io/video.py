"""Annotated video: the frames of sequences, in any of three formats, as the video metrics take them (`Frame`).

- VIL-100 (``GT/Json/<video>/<frame>.jpg.json``, `stamlane_eval.io.vil100`) or CULane text per frame
  (``GT/<video>/<frame>.lines.txt``, `stamlane_eval.io.culane`): `video_frames` finds the frames, `listed_frames`
  takes them from a list in its order;
- TuSimple records, grouped into sequences by the folder of ``raw_file`` (`read_tusimple_frames`);
- `read_video` reads predictions and ground truth in any mix of the three into `Frame` s, with the image sizes of
  ``--size``, ``--sizes`` (`read_sizes`) or the labels.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from stamlane_eval.cli_tools import parse_wxh
from stamlane_eval.io.culane import culane_entries, culane_lines_path, read_culane_lines
from stamlane_eval.io.files import (
    LaneFileError,
    gc_paused,
    image_key,
    inside,
    is_json_number,
    json_float,
    read_file,
    read_text,
)
from stamlane_eval.io.limits import MAX_IMAGE_SIDE, MAX_LANE_POINTS, MAX_LANES
from stamlane_eval.io.tusimple import (
    TuSimpleInputError,
    check_tusimple,
    read_tusimple,
    refuse_booleans,
    tusimple_points,
)
from stamlane_eval.io.vil100 import read_vil100_json

__all__ = [
    "TUSIMPLE_SUFFIXES",
    "Frame",
    "TuSimpleFrames",
    "VideoInput",
    "is_tusimple_input",
    "listed_frames",
    "read_sizes",
    "read_tusimple_frames",
    "read_video",
    "tusimple_frame_key",
    "video_frames",
]


@dataclass(frozen=True)
class Frame:
    """One annotated frame, as `read_video` gives it and :func:`stamlane_eval.video.evaluate_sequence` and
    :func:`stamlane_eval.temporal.evaluate_sequence` take it.

    Attributes:
        preds: predicted lanes, each ``(N, 2)`` ``(x, y)`` in original pixels.
        target: annotated lanes, same form.
        pred_ids: identity of each predicted lane (default: its position).
        target_ids: identity of each annotated lane (default: its position; VIL-100: ``lane_id``).
        size: image ``(H, W)``; None for the size given to the metric.
    """

    preds: Sequence[np.ndarray]
    target: Sequence[np.ndarray]
    pred_ids: Sequence[int] | None = None
    target_ids: Sequence[int] | None = None
    size: tuple[int, int] | None = None


def video_frames(gt_dir: str | os.PathLike[str]) -> tuple[str, dict[str, list[tuple[str, Path]]]]:
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
    rows: dict[tuple[str, str], list[float]]
    timed: int = 0


def tusimple_frame_key(raw_file: str) -> tuple[str, str] | None:
    """``(sequence, frame)`` of a ``raw_file``: its folder and its name without the extension, the name normalised
    once (`image_key`: ``s1/./2.jpg`` is frame ``2`` of ``s1``); None where it names no folder."""
    seq, _, name = image_key(raw_file.replace("\\", "/")).rpartition("/")
    seq = seq.strip("/")
    stem = name[: name.rfind(".")] if "." in name else name
    return (seq, stem) if seq and stem else None


def _tusimple_file_records(path: Path) -> tuple[list[dict[str, Any]], str]:
    """The records of one file: json-lines (``predictions.json``, ``challenging-frames.json``) or one JSON list of
    objects (the generator's ``frame_labels/<clip>.json``), and how a message names a record."""
    text = read_file(path)
    if not text.lstrip().startswith("["):
        return read_tusimple(path, text=text), "line"
    try:
        with gc_paused():
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
    refuse_booleans(data, text, path, unit="record")
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
    path: str | os.PathLike[str], role: str, rows: dict[tuple[str, str], list[float]] | None = None
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
    out_rows: dict[tuple[str, str], list[float]] = {}
    first: dict[tuple[str, str], str] = {}
    timed = 0
    for file in _tusimple_files(root):
        if file is not root:
            inside(file, root)
        records, unit = _tusimple_file_records(file)
        if role == "gt":
            try:
                check_tusimple(records, "gt", labels="finite")  # the C++ metric draws a far point clipped
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
            h: list[float]
            if role == "pred":
                if rec.get("h_samples") is None and rows is not None and key not in rows:
                    continue  # a frame the ground truth lacks: not scored
                h = _frame_rows(rec.get("h_samples"), rows, key, where)
                _check_pred_lanes(rec["lanes"], len(h), where)
            else:
                h = rec["h_samples"]  # a list of numbers: check_tusimple passed
            if key in first:
                what = "labelled" if role == "gt" else "predicted"
                raise LaneFileError(f"{where}: frame {key[0]}/{key[1]} is {what} twice (also at {first[key]})")
            first[key] = where
            sequences.setdefault(key[0], []).append(key[1])
            lanes[key] = tusimple_points(rec["lanes"], h)
            out_rows[key] = h
    return TuSimpleFrames(dict(sorted(sequences.items())), lanes, out_rows, timed)


def _frame_rows(
    h: object, rows: dict[tuple[str, str], list[float]] | None, key: tuple[str, str], where: str
) -> list[float]:
    """A prediction's rows: its own ``h_samples`` (a list of finite JSON numbers, at most ``MAX_LANE_POINTS``), or
    the ground truth's frame's."""
    if h is None:
        gt_rows = None if rows is None else rows.get(key)
        if gt_rows is None:
            raise LaneFileError(
                f"{where}: no h_samples, and the ground truth has none for this frame (give predictions with "
                f"h_samples, as stamlane predict writes them, or TuSimple ground truth)"
            )
        return gt_rows
    if not (isinstance(h, list) and len(h) <= MAX_LANE_POINTS and all(map(is_json_number, h))):
        raise LaneFileError(f"{where}: h_samples must be a list of at most {MAX_LANE_POINTS} JSON numbers")
    if not all(math.isfinite(json_float(v)) for v in h):  # a far row is drawn clipped by the C++ tool: scored
        raise LaneFileError(f"{where}: h_samples holds a value that is not finite")
    return h


def _check_pred_lanes(pred_lanes: list[object], rows: int, where: str) -> None:
    """A prediction's lanes: at most ``MAX_LANES``, each ``rows`` finite JSON numbers."""
    if len(pred_lanes) > MAX_LANES:
        raise LaneFileError(f"{where}: {len(pred_lanes)} lanes, more than the limit of {MAX_LANES}")
    for k, lane in enumerate(pred_lanes):
        if not (isinstance(lane, list) and len(lane) == rows and all(map(is_json_number, lane))):
            raise LaneFileError(
                f"{where}: lane {k} is not {rows} JSON numbers (one per h_sample; no string, no true/false)"
            )
        if not all(math.isfinite(json_float(v)) for v in lane):
            raise LaneFileError(f"{where}: lane {k} has a non-finite x")


# ------------------------------------------------------------------------------ lists, sizes, whole sets
def listed_frames(gt: Path, list_file: Path, kind: str) -> dict[str, list[tuple[str, Path]]]:
    """The frames a list names, in its order: ``{sequence: [(frame_stem, annotation_path), ...]}``.

    An entry is ``<sequence>/<frame>`` (an extension and a leading ``/`` or ``/JPEGImages/``, as in VIL-100's
    ``data/test.txt``, are allowed); the sequence is everything before the last ``/``. A sequence's frames must
    be listed together: RVLD's script pairs list neighbours by position.

    Args:
        gt: the ground truth (a folder, or a TuSimple file whose folder the list is read against).
        list_file: the list.
        kind: the layout of ``gt`` (`video_frames`' ``"vil100"`` or ``"lines"``, or ``"tusimple"``).

    Raises:
        LaneFileError: naming the list, the line and the problem.
    """
    seqs: dict[str, list[tuple[str, Path]]] = {}
    first: dict[tuple[str, str], int] = {}  # (sequence, frame) -> the line that named it
    last = None
    for i, entry in enumerate(culane_entries(gt if gt.is_dir() else gt.parent, list_file), 1):
        rel = image_key(entry.strip()).lstrip("/")  # s1/./2.jpg is s1/2.jpg: one frame
        rel = rel[len("JPEGImages/") :] if rel.startswith("JPEGImages/") else rel  # evaluate_iou.py drops it too
        if "/" not in rel:
            raise LaneFileError(f"{list_file}: line {i}: {entry!r} names no sequence (expected <sequence>/<frame>)")
        seq, name = rel.rsplit("/", 1)
        stem = name[: name.rfind(".")] if "." in name else name
        if first.setdefault((seq, stem), i) != i:  # "/JPEGImages/v/1.jpg" and "v/1.png" name one frame
            raise LaneFileError(
                f"{list_file}: lines {first[seq, stem]} and {i} name the same frame {seq}/{stem}: it would be "
                f"scored twice"
            )
        if seq in seqs and seq != last:
            raise LaneFileError(
                f"{list_file}: line {i}: sequence {seq!r} resumes after other sequences; list each sequence's "
                f"frames together, in time order"
            )
        path = gt / "Json" / seq / f"{stem}.jpg.json" if kind == "vil100" else culane_lines_path(gt, rel)
        seqs.setdefault(seq, []).append((stem, path))
        last = seq
    return seqs


def read_sizes(path: Path | None) -> dict[str, tuple[int, int]]:
    """``--sizes FILE``: ``{"<sequence>" or "<sequence>/<frame>": "WxH"}`` as ``(H, W)``; ``{}`` for None.

    Raises:
        LaneFileError: naming the file (and the key) and the problem.
    """
    if path is None:
        return {}
    text = read_text(path)  # a FIFO or a device: refused unread
    try:
        data = json.loads(text)
    except ValueError as e:
        raise LaneFileError(f"{path}: cannot read a JSON object: {e}") from None
    except RecursionError:
        raise LaneFileError(f"{path}: JSON nested too deeply") from None
    if not isinstance(data, dict):
        raise LaneFileError(f'{path}: expected a JSON object {{sequence: "WxH"}}, got {type(data).__name__}')
    out = {}
    for key, text in data.items():
        try:
            out[key] = parse_wxh(text if isinstance(text, str) else repr(text), MAX_IMAGE_SIDE)
        except argparse.ArgumentTypeError as e:
            raise LaneFileError(f"{path}: {key!r}: {e}") from None
    return out


def is_tusimple_input(path: Path) -> bool:
    """Whether `read_video` reads ``path`` as TuSimple records (`read_tusimple_frames`): a file, or a folder with
    ``.json`` / ``.jsonl`` files directly in it and neither a VIL-100 ``Json/`` folder nor any ``.lines.txt``
    under it."""
    if path.is_file():
        return True
    if not path.is_dir() or (path / "Json").is_dir():
        return False
    try:
        if not any(q.name.endswith(TUSIMPLE_SUFFIXES) for q in path.iterdir()):
            return False
    except OSError:
        return False
    return not any(any(f.endswith(".lines.txt") for f in files) for _, _, files in os.walk(path))


@dataclass(frozen=True)
class VideoInput:
    """What `read_video` read.

    Attributes:
        sequences: per sequence, its frames in time order (a frame without a prediction: no predicted lanes).
        predicted: frames that have a prediction (0: most likely a wrong folder or layout, not a model).
        tusimple_pred: the predictions are TuSimple records (else ``.lines.txt`` files).
    """

    sequences: dict[str, list[Frame]]
    predicted: int
    tusimple_pred: bool

    @property
    def frames(self) -> int:
        return sum(len(f) for f in self.sequences.values())


def read_video(
    pred: Path,
    gt: Path,
    *,
    list_file: Path | None = None,
    sizes: Path | None = None,
    size: tuple[int, int] | None = None,
    need_size: bool = True,
    as_given: bool = False,
) -> VideoInput:
    """The frames of ``gt`` (or of ``list_file``) with their predictions, in any mix of the formats: ground truth
    in the VIL-100 layout, as CULane text per frame or as TuSimple records; predictions as
    ``PRED/<sequence>/<frame>.lines.txt`` or TuSimple records. Nothing is read outside the folders given, through
    links either.

    Args:
        pred: the predictions (a folder, or TuSimple records: `is_tusimple_input`).
        gt: the ground truth.
        list_file: frames in time order (`listed_frames`), or None for every frame in name order.
        sizes: ``--sizes`` (`read_sizes`): per sequence or frame, its image size.
        size: the image ``(H, W)`` of every frame, where ``sizes`` gives none (a VIL-100 label's ``info``: last).
        need_size: refuse a frame without an image size.
        as_given: read TuSimple files that look swapped (``run_time`` in GT, none in PRED) as given.

    Raises:
        LaneFileError: naming the file and the problem.
    """
    pred_tusimple = is_tusimple_input(pred)
    if not pred_tusimple and not pred.is_dir():
        raise LaneFileError(f"{pred}: not a directory, nor a TuSimple json-lines file")
    sizes_of = read_sizes(sizes)
    gt_frames = None
    if is_tusimple_input(gt):
        gt_frames = read_tusimple_frames(gt, "gt")
        kind = "tusimple"
        layout = {seq: [(stem, gt) for stem in stems] for seq, stems in gt_frames.sequences.items()}
    else:
        kind, layout = video_frames(gt)
    if list_file is not None:
        layout = listed_frames(gt, list_file, kind)
    pred_frames = None
    if pred_tusimple:
        pred_frames = read_tusimple_frames(pred, "pred", None if gt_frames is None else gt_frames.rows)
        if gt_frames is not None and gt_frames.timed and not pred_frames.timed and not as_given:
            raise LaneFileError(
                f"{pred} has no run_time (a label file?) and {gt} has one (a prediction file?): the files "
                f"look swapped; the order is stamlane-eval video PRED GT (--as-given scores them as given)"
            )
    sequences: dict[str, list[Frame]] = {}
    predicted = 0
    for seq, frames in layout.items():
        out = []
        for stem, path in frames:
            if gt_frames is not None:
                lanes, ids, frame_size = gt_frames.lanes.get((seq, stem)), None, None
                if lanes is None:
                    raise LaneFileError(f"{list_file}: frame {seq}/{stem} is not in {gt}")
            else:
                inside(path, gt)  # nothing read outside the folders given, through links either
                if kind == "vil100":
                    lanes, ids, frame_size = read_vil100_json(path)
                else:
                    lanes, ids, frame_size = read_culane_lines(path, missing_ok=False), None, None
            frame_size = sizes_of.get(f"{seq}/{stem}") or sizes_of.get(seq) or size or frame_size
            if frame_size is None and need_size:
                where = path if gt_frames is None else f"{gt}: frame {seq}/{stem}"  # TuSimple: no size at all
                raise LaneFileError(f"{where}: no image size: give --size WxH (or --sizes FILE)")
            if pred_frames is not None:
                preds = pred_frames.lanes.get((seq, stem))
                predicted += preds is not None
                preds = preds or []
            else:
                pred_path = pred / seq / f"{stem}.lines.txt"
                found = pred_path.exists()
                predicted += found
                preds = read_culane_lines(inside(pred_path, pred) if found else pred_path, prediction=True)
            out.append(Frame(preds, lanes, target_ids=ids, size=frame_size))
        sequences[seq] = out
    return VideoInput(sequences, predicted, pred_frames is not None)
