"""What history can reveal, and what a model recovers of it, on synthetic sets with paint visibility.

Two measurements on the labels of a split with ``visibility/<split>.json`` (generator format 5,
`stamlane.synth.visibility`):

- **recall per visibility class** of a model's predictions: every labelled key-frame point is ``visible`` (its
  paint shows in the key frame), ``revealed`` (hidden in the key frame, shown by one of the model's history
  frames at exact alignment) or ``hidden``; a point is recalled when the predicted lane that TuSimple's
  ``lane.py`` matches to its annotated lane (the one with the most rows within the angle-scaled 20-px threshold)
  is within that threshold on the point's row. A model that reads its history recalls more ``revealed`` points
  than one that does not; ``visible`` points are the single frame's job.
- **the oracle headroom** of a split (a property of the data, not of a model): TuSimple F1 of lanes fitted, with
  the demo's post-processing fit (`stamlane.postprocess.fit_curve` and `sample_lanes`), to the labelled points
  visible in the key frame, and to those visible in the key frame or its aligned history. Their difference is
  what perfect use of ``num_frames`` aligned frames can add over a perfect detector of the key frame's paint:
  where it is about 0 (the fitted lines bridge the gaps anyway), no model can show the paper's effect.

Both give per-image quantities (columns) so that intervals over clips come from the same bootstrap as every F1.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from stamlane_eval.tusimple import PIXEL_THRESH

from stamlane.postprocess import PostprocessConfig, fit_curve, sample_lanes
from stamlane.synth.generator import VISIBILITY_DIR
from stamlane.synth.visibility import VISIBILITY_CLASSES, visibility_class

__all__ = [
    "class_counts",
    "oracle_predictions",
    "point_hits",
    "read_visibility",
    "recall_of_counts",
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
    return PIXEL_THRESH / np.cos(np.arctan(k))


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
    return counts.ravel().tolist()


def recall_of_counts(means: np.ndarray, cls: str) -> float:
    """The recall of class ``cls`` from the means of `class_counts` columns (nan where the class has no point)."""
    i = VISIBILITY_CLASSES.index(cls)
    points = float(means[2 * i + 1])
    return float(means[2 * i]) / points if points > 0 else float("nan")


def _fitted(points: list[np.ndarray], config: PostprocessConfig, h_samples: Sequence[int], size: tuple[int, int]):
    curves = [c for c in (fit_curve(p, config) for p in points if len(p) >= 2) if c is not None]
    return sample_lanes(curves, config, h_samples, size)


def oracle_predictions(
    gts: Sequence[Mapping],
    visibility: Mapping[str, list[list[int]]],
    num_frames: int,
    config: PostprocessConfig,
    size: tuple[int, int],
    stride: int = 1,
) -> tuple[list[dict], list[dict]]:
    """TuSimple prediction records of the two oracles of the module docstring.

    Args:
        gts: TuSimple label records (``raw_file``, ``lanes``, ``h_samples``) of the key frames.
        visibility: `read_visibility` of the same split.
        num_frames: T of the multi-frame oracle (history frames ``stride``, ``2 stride``, ... back).
        config: the post-processing whose fit the oracles use (the demo model's: ``degree``, ``extend``).
        size: ``(H, W)`` of the frames.
        stride: frames between the clip's frames.

    Returns:
        ``(key_frame_oracle, history_oracle)``: per key frame, ``raw_file``, ``lanes`` (x at ``h_samples``,
        -2 = none), ``h_samples`` and ``run_time`` 0: lanes fitted to the points visible in the key frame, and to
        the points visible in the key frame or one of its ``num_frames - 1`` aligned history frames.
    """
    from stamlane_eval.tusimple import lanes_to_xs

    wanted = {"key": ("visible",), "history": ("visible", "revealed")}
    found: dict[str, list[dict]] = {name: [] for name in wanted}
    for gt in gts:
        masks = visibility.get(gt["raw_file"])
        if masks is None:
            raise KeyError(f"no visibility for {gt['raw_file']}")
        h_samples = gt["h_samples"]
        for name, classes in wanted.items():
            points = [
                np.array(
                    [
                        (x, y)
                        for x, y, m in zip(lane, h_samples, lane_masks)
                        if x >= 0 and visibility_class(m, num_frames, stride) in classes
                    ],
                    dtype=np.float64,
                ).reshape(-1, 2)
                for lane, lane_masks in zip(gt["lanes"], masks)
            ]
            lanes = _fitted(points, config, h_samples, size)
            found[name].append(
                {
                    "raw_file": gt["raw_file"],
                    "lanes": lanes_to_xs(lanes, h_samples),
                    "h_samples": h_samples,
                    "run_time": 0,
                }
            )
    return found["key"], found["history"]
