"""Score a predictions file against the labels of a split: totals and per-image quantities of every metric.

As ``stamlane-eval tusimple --no-time-limit`` (the benchmark's 200 ms rule measures the machine's load, not the
model: images over it are counted as ``late``) and as ``stamlane-eval culane PRED GT --size WxH --width W`` with
the protocol's 30-px line scaled to the frame width (`iou_width`); where the set has paint-visibility masks, the
recall per visibility class of a model of ``num_frames`` frames (`stamlane.experiments.history`).
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from stamlane.experiments.history import class_counts, point_hits, read_visibility
from stamlane.experiments.metrics import METRICS
from stamlane.experiments.store import write_atomic

__all__ = [
    "PER_CLIP",
    "PER_IMAGE",
    "SCORING",
    "clip_of",
    "image_size",
    "iou_width",
    "read_per_clip",
    "read_per_image",
    "score_split",
    "score_temporal",
]

PER_IMAGE = "per_image.jsonl"
PER_CLIP = "per_clip.jsonl"
SCORING = "no-time-limit+culane+classes"
"""How `score_split` scores (kept in each run's record): a run scored otherwise is scored again from its saved
predictions (``no-time-limit+iou``: before the recall per visibility class; ``no-time-limit``: TuSimple F1
only)."""


def iou_width(size: tuple[int, int]) -> int:
    """The CULane metric's line thickness for images of ``size`` (H, W): the protocol's 30 px on CULane's
    1640-px-wide frames, scaled with the image width (12 px at 640), so that a lane covers the same fraction of
    the image as in the benchmark."""
    from stamlane_eval.culane import CULANE_SIZE, LANE_WIDTH

    return max(1, round(LANE_WIDTH * size[1] / CULANE_SIZE[1]))


def image_size(root: Path) -> tuple[int, int]:
    """(H, W) of a synthetic set's frames, from its ``dataset.json``."""
    info = root / "dataset.json"
    if not info.is_file():
        raise FileNotFoundError(f"{root}: no dataset.json (experiments score synthetic sets, which have one)")
    config = json.loads(info.read_text())["config"]
    return int(config["height"]), int(config["width"])


def clip_of(raw_file: str) -> str:
    """The clip of a key frame: its folder (``clips/test-0007/20.jpg`` -> ``clips/test-0007``)."""
    return raw_file.rsplit("/", 1)[0]


def score_split(pred_dir: Path, root: Path, split: str, num_frames: int) -> dict:
    """Score ``pred_dir/predictions.json`` against ``root/<split>.json``; write ``pred_dir/per_image.jsonl``.

    Args:
        pred_dir: a predictions folder (``predictions.json``: TuSimple json-lines).
        root: the data root.
        split: the label file's stem.
        num_frames: the model's clip length (which history frames the visibility classes count).

    Returns:
        the totals: ``accuracy``, ``fp``, ``fn``, ``f1``, ``images``, ``late`` (TuSimple) and per metric key of
        `METRICS` its value on the whole split (class recalls only where the set has visibility masks), and
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
    size = image_size(root)
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
    for m in METRICS:
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
    for m in METRICS:
        values = [m.columns(row) for row in rows]
        if values and all(v is not None for v in values):
            found[m.key] = np.array(values, dtype=np.float64)
    return found, [row["clip"] for row in rows]


def score_temporal(pred_dir: Path, root: Path, split: str) -> dict:
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

    from stamlane.experiments.metrics import TEMPORAL

    preds = {p["raw_file"]: p for p in read_tusimple(pred_dir / "predictions.json")}
    sequences: dict[str, list] = {}
    for gt in read_tusimple(root / f"{split}.json"):
        pred = preds[gt["raw_file"]]
        frame = Frame(tusimple_points(pred["lanes"], gt["h_samples"]), tusimple_points(gt["lanes"], gt["h_samples"]))
        sequences.setdefault(clip_of(gt["raw_file"]), []).append(frame)
    result = temporal.evaluate(sequences, temporal.TEMPORAL_IOU_THRESHOLDS, image_size(root))
    rows = [
        {
            "clip": clip,
            "frames": len(frames),
            "temporal": {f"{t:g}": [seq.counts[t].ns, seq.counts[t].nj, seq.counts[t].nm] for t in seq.counts},
        }
        for (clip, frames), seq in zip(sequences.items(), result.per_sequence)
    ]
    write_atomic(pred_dir / PER_CLIP, "".join(json.dumps(row) + "\n" for row in rows))
    totals: dict = {"clips": len(rows), "frames": sum(r["frames"] for r in rows)}
    for m in TEMPORAL:
        totals[m.key] = m.statistic(np.mean(np.array([m.columns(r) for r in rows], dtype=np.float64), axis=0))
    return totals


def read_per_clip(pred_dir: Path) -> tuple[dict[str, np.ndarray], list[str]]:
    """Per temporal metric key, the per-clip ``(Ns, Nj, Nm)`` (N, 3) of a scored split, and the clips."""
    from stamlane.experiments.metrics import TEMPORAL

    rows = [json.loads(line) for line in (pred_dir / PER_CLIP).read_text().splitlines()]
    return {m.key: np.array([m.columns(r) for r in rows], dtype=np.float64) for m in TEMPORAL}, [
        r["clip"] for r in rows
    ]
