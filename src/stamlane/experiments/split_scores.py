"""Score a predictions file against the labels of a split: totals and per-image quantities of every metric.

As ``stamlane-eval tusimple --no-time-limit`` (the benchmark's 200 ms rule measures the machine's load, not the
model: images over it are counted as ``late``) and as ``stamlane-eval culane PRED GT --size WxH --width W`` with
the protocol's 30-px line scaled to the frame width (`iou_width`). Where a synthetic set has paint-visibility masks
(``visibility/<split>.json``, generator format 5, `stamlane.synth.visibility`), also the **recall per visibility
class** of a model of ``num_frames`` frames: every labelled key-frame point is ``visible`` (its paint shows in the
key frame), ``revealed`` (hidden in the key frame, shown by one of the model's history frames at exact alignment)
or ``hidden``; a point is recalled when the predicted lane that TuSimple's ``lane.py`` matches to its annotated lane
(the one with the most rows within the angle-scaled 20-px threshold) is within that threshold on the point's row. A
model that reads its history recalls more ``revealed`` points than one that does not; ``visible`` points are the
single frame's job.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
from stamlane_eval.tusimple import PIXEL_THRESH

from stamlane.experiments.metrics import REPORTED
from stamlane.predict.image_score import iou_width
from stamlane.safety.guard import write_atomic
from stamlane.synth.layout import VISIBILITY_DIR
from stamlane.synth.visibility import VISIBILITY_CLASSES, visibility_class

__all__ = [
    "PER_CLIP",
    "PER_IMAGE",
    "SCORING",
    "class_counts",
    "clip_of",
    "image_size",
    "point_hits",
    "read_per_clip",
    "read_per_image",
    "read_visibility",
    "score_split",
    "score_temporal",
]

PER_IMAGE = "per_image.jsonl"
PER_CLIP = "per_clip.jsonl"
SCORING = "no-time-limit+culane+classes"
"""How `score_split` scores (kept in each run's record): a run scored otherwise is scored again from its saved
predictions (``no-time-limit+iou``: before the recall per visibility class; ``no-time-limit``: TuSimple F1
only)."""


def image_size(root: Path, split: str) -> tuple[int, int]:
    """(H, W) of the frames of a split: a synthetic set's (its ``dataset.json``), or the size of the split's first
    labelled frame (a TuSimple-layout set of real frames), read only inside ``root``.

    Raises:
        ValueError: one line naming the file: a ``dataset.json`` without ``config.height`` / ``config.width``
            (integers in ``1..MAX_IMAGE_SIDE``), a first frame outside ``root`` (``..``) or no readable image.
    """
    from stamlane_eval.io import check_image_size, read_tusimple

    from stamlane.data.labels import resolve_inside
    from stamlane.safety.guard import read_input
    from stamlane.safety.images import read_image

    info = root / "dataset.json"
    if info.is_file():
        try:
            config = json.loads(read_input(info, 1 << 20, "dataset.json"))["config"]
            height, width = config["height"], config["width"]
            if type(height) is not int or type(width) is not int:
                raise TypeError(f"config.height / config.width {height!r:.20} / {width!r:.20} are not integers")
            return check_image_size((height, width))
        except (KeyError, TypeError, ValueError) as err:  # GuardError and JSON's errors are ValueErrors
            why = f"no key {err}" if isinstance(err, KeyError) else str(err)[:120]
            raise ValueError(f"{info}: no frame size (config.height and config.width): {why}") from None
    labels = read_tusimple(root / f"{split}.json")
    frame = resolve_inside(root, labels[0]["raw_file"], f"{root / f'{split}.json'}: line 1") if labels else None
    image = read_image(frame) if frame is not None else None
    if image is None:
        raise ValueError(f"{root / f'{split}.json'}: its first frame {frame} is no readable image")
    return image.shape[0], image.shape[1]


def clip_of(raw_file: str) -> str:
    """The clip of a key frame: its folder (``clips/test-0007/20.jpg`` -> ``clips/test-0007``)."""
    return raw_file.rsplit("/", 1)[0]


def score_split(pred_dir: Path, root: Path, split: str, num_frames: int) -> dict[str, Any]:
    """Score ``pred_dir/predictions.json`` against ``root/<split>.json``; write ``pred_dir/per_image.jsonl``.

    Args:
        pred_dir: a predictions folder (``predictions.json``: TuSimple json-lines).
        root: the data root.
        split: the label file's stem.
        num_frames: the model's clip length (which history frames the visibility classes count).

    Returns:
        the totals: ``accuracy``, ``fp``, ``fn``, ``f1``, ``images``, ``late`` (TuSimple) and per metric key of
        `REPORTED` its value on the whole split (class recalls only where the set has visibility masks), and
        ``iou_width``.
    """
    from stamlane_eval import culane
    from stamlane_eval.culane import IOU_THRESHOLDS
    from stamlane_eval.io import read_tusimple, tusimple_points
    from stamlane_eval.tusimple import MAX_RUN_TIME_MS, evaluate

    labels = root / f"{split}.json"
    preds, gts = read_tusimple(pred_dir / "predictions.json"), read_tusimple(labels)
    result = evaluate(preds, gts, time_limit=False)
    by_name = {p["raw_file"]: (p, r) for p, r in zip(preds, result.per_image)}
    size = image_size(root, split)
    width = iou_width(size)
    iou = culane.evaluate(
        [tusimple_points(by_name[gt["raw_file"]][0]["lanes"], gt["h_samples"]) for gt in gts],
        [tusimple_points(gt["lanes"], gt["h_samples"]) for gt in gts],
        IOU_THRESHOLDS,
        width,
        size,
    )
    visibility = read_visibility(root, split)
    rows = []
    for gt, counts in zip(gts, iou.per_image):
        pred, r = by_name[gt["raw_file"]]
        row = {"raw_file": gt["raw_file"], "clip": clip_of(gt["raw_file"]), **asdict(r)}
        row["culane"] = {f"{t:g}": list(counts.counts[t]) for t in IOU_THRESHOLDS}
        if visibility is not None:
            hits = point_hits(pred["lanes"], gt["lanes"], gt["h_samples"])
            row["classes"] = class_counts(hits, visibility[gt["raw_file"]], num_frames)
        rows.append(row)
    write_atomic(pred_dir / PER_IMAGE, "".join(json.dumps(row) + "\n" for row in rows))
    totals = {k: result.as_dict()[k] for k in ("accuracy", "fp", "fn", "f1", "images")}
    totals["late"] = sum(p["run_time"] > MAX_RUN_TIME_MS for p in preds)
    for m in REPORTED:
        values = [m.columns(row) for row in rows]
        if values and all(v is not None for v in values):
            totals[m.key] = m.statistic(np.mean(np.array(values, dtype=np.float64), axis=0))
    totals["iou_width"] = width
    return totals


def read_per_image(pred_dir: Path) -> tuple[dict[str, np.ndarray], list[str]]:
    """Per metric key, the per-image quantities (N, k) of a scored split (metrics the rows lack are left out),
    and each image's clip, in label order."""
    rows = [json.loads(line) for line in (pred_dir / PER_IMAGE).read_text().splitlines()]
    found = {}
    for m in REPORTED:
        values = [m.columns(row) for row in rows]
        if values and all(v is not None for v in values):
            found[m.key] = np.array(values, dtype=np.float64)
    return found, [row["clip"] for row in rows]


def score_temporal(pred_dir: Path, root: Path, split: str) -> dict[str, Any]:
    """Score the frame-after-frame predictions ``pred_dir/predictions.json`` of the clips of ``root/<split>.json``
    (every frame of each clip, oldest first) with RVLD's temporal stability (`stamlane_eval.temporal`, the VIL-100
    protocol at the frames' size); write ``pred_dir/per_clip.jsonl`` (each clip's ``(Ns, Nj, Nm)`` per IoU
    threshold).

    Returns:
        ``clips``, ``frames`` and per temporal metric key (``temporal_rs@0.5``, ...) its value on the whole split.
    """
    from stamlane_eval import temporal
    from stamlane_eval.io import read_tusimple, tusimple_points
    from stamlane_eval.video import Frame

    from stamlane.experiments.metrics import TEMPORAL_STABILITY

    preds = {p["raw_file"]: p for p in read_tusimple(pred_dir / "predictions.json")}
    sequences: dict[str, list[Any]] = {}
    for gt in read_tusimple(root / f"{split}.json"):
        pred = preds[gt["raw_file"]]
        frame = Frame(tusimple_points(pred["lanes"], gt["h_samples"]), tusimple_points(gt["lanes"], gt["h_samples"]))
        sequences.setdefault(clip_of(gt["raw_file"]), []).append(frame)
    result = temporal.evaluate(sequences, temporal.TEMPORAL_IOU_THRESHOLDS, image_size(root, split))
    rows = [
        {
            "clip": clip,
            "frames": len(frames),
            "temporal": {f"{t:g}": [seq.counts[t].ns, seq.counts[t].nj, seq.counts[t].nm] for t in seq.counts},
        }
        for (clip, frames), seq in zip(sequences.items(), result.per_sequence)
    ]
    write_atomic(pred_dir / PER_CLIP, "".join(json.dumps(row) + "\n" for row in rows))
    totals: dict[str, Any] = {"clips": len(rows), "frames": sum(r["frames"] for r in rows)}
    for m in TEMPORAL_STABILITY:
        totals[m.key] = m.statistic(np.mean(np.array([m.columns(r) for r in rows], dtype=np.float64), axis=0))
    return totals


def read_per_clip(pred_dir: Path) -> tuple[dict[str, np.ndarray], list[str]]:
    """Per temporal metric key, the per-clip ``(Ns, Nj, Nm)`` (N, 3) of a scored split, and the clips."""
    from stamlane.experiments.metrics import TEMPORAL_STABILITY

    rows = [json.loads(line) for line in (pred_dir / PER_CLIP).read_text().splitlines()]
    return {m.key: np.array([m.columns(r) for r in rows], dtype=np.float64) for m in TEMPORAL_STABILITY}, [
        r["clip"] for r in rows
    ]


def read_visibility(root: Path, split: str) -> dict[str, list[list[int]]] | None:
    """``raw_file`` -> per lane, per h_sample visibility mask, from ``<root>/visibility/<split>.json``; None for a set
    without one (format 4 and older, or a split without visibility)."""
    path = Path(root) / VISIBILITY_DIR / f"{split}.json"
    if not path.is_file():
        return None
    found = {}
    for line in path.read_text().splitlines():
        record = json.loads(line)
        found[record["raw_file"]] = record["visibility"]
    return found


def _threshold(gt: np.ndarray, ys: np.ndarray) -> float:
    """lane.py's per-lane pixel threshold: 20 px / cos(angle of the least-squares x = k y + b through its points)."""
    on = gt >= 0
    if on.sum() < 2:
        return PIXEL_THRESH
    k = np.polyfit(ys[on], gt[on], 1)[0]
    threshold: float = PIXEL_THRESH / np.cos(np.arctan(k))
    return threshold


def point_hits(
    pred: Sequence[Sequence[float]], gt: Sequence[Sequence[float]], h_samples: Sequence[float]
) -> list[list[bool]]:
    """Whether each labelled point of an image is recalled (see the module docstring).

    Args:
        pred: predicted lanes as TuSimple x lists (negative = no point), (P, R).
        gt: annotated lanes, (G, R).
        h_samples: the R rows.

    Returns:
        per annotated lane, per row: True where the lane's best-matching prediction is within the threshold there
        (False on rows without a label point too: read them with the visibility mask, which marks those absent).
    """
    ys = np.asarray(h_samples, dtype=np.float64)
    preds = np.where(np.asarray(pred, dtype=np.float64) >= 0, np.asarray(pred, dtype=np.float64), -100.0)
    preds = preds.reshape(len(pred), len(ys))
    hits = []
    for lane in gt:
        g = np.asarray(lane, dtype=np.float64)
        if len(preds) == 0:
            hits.append([False] * len(ys))
            continue
        thresh = _threshold(g, ys)
        close = np.abs(preds - np.where(g >= 0, g, -100.0)[None, :]) < thresh  # (P, R), lane.py's comparison
        best = int(np.argmax(close.mean(axis=1)))
        hits.append([bool(c and x >= 0) for c, x in zip(close[best], g)])
    return hits


def class_counts(hits: list[list[bool]], masks: list[list[int]], num_frames: int, stride: int = 1) -> list[float]:
    """Per-image quantities of the class recall: ``[recalled, points]`` of each class of `VISIBILITY_CLASSES` in
    turn (6 numbers), for a model of ``num_frames`` frames at ``stride``."""
    counts = np.zeros((len(VISIBILITY_CLASSES), 2))
    for lane_hits, lane_masks in zip(hits, masks):
        for hit, mask in zip(lane_hits, lane_masks):
            cls = visibility_class(mask, num_frames, stride)
            if cls is not None:
                counts[VISIBILITY_CLASSES.index(cls)] += (float(hit), 1.0)
    per_class: list[float] = counts.ravel().tolist()
    return per_class
