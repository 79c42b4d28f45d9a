"""Every metric's aggregation, written once (the torchmetrics pattern of shared update/compute helpers).

``tusimple.evaluate``, ``culane.evaluate``, the CLI and the torchmetrics classes (so the Lightning callback) all
fold their per-image results with these functions, so they cannot drift: the same images give the same numbers
to the last bit, whichever way they are scored. The sums are plain numbers; the torchmetrics classes keep them as
states summed across processes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Protocol

__all__ = [
    "TuSimpleSums",
    "culane_update",
    "paper_f1",
    "prf",
    "tusimple_compute",
    "tusimple_update",
]


class _TuSimpleImage(Protocol):
    acc: float
    fp: float
    fn: float
    matched: int
    n_pred: int
    n_gt: int


class _CULaneImage(Protocol):
    counts: dict[float, tuple[int, int, int]]


@dataclass(frozen=True)
class TuSimpleSums:
    """What the TuSimple numbers are computed from: per-image values summed over images.

    Attributes:
        acc: sum of the images' ``LaneEval.bench`` accuracies (likewise ``fp``, ``fn``).
        images: images summed (lane.py divides by the unique gt names: the same, duplicates being refused).
        lane_tp: gt lanes matched; ``lane_pred``/``lane_gt``: predicted / gt lanes.
    """

    acc: float = 0.0
    fp: float = 0.0
    fn: float = 0.0
    images: int = 0
    lane_tp: int = 0
    lane_pred: int = 0
    lane_gt: int = 0


def tusimple_update(sums: TuSimpleSums, per_image: Iterable[_TuSimpleImage]) -> TuSimpleSums:
    """Add images to the sums one at a time, left to right: lane.py's plain float sums, equal to the last bit
    whether the images come in one call or many."""
    acc, fp, fn = sums.acc, sums.fp, sums.fn
    images, tp, n_pred, n_gt = sums.images, sums.lane_tp, sums.lane_pred, sums.lane_gt
    for r in per_image:
        acc += r.acc
        fp += r.fp
        fn += r.fn
        images += 1
        tp += r.matched
        n_pred += r.n_pred
        n_gt += r.n_gt
    return TuSimpleSums(acc, fp, fn, images, tp, n_pred, n_gt)


def tusimple_compute(sums: TuSimpleSums) -> dict[str, float]:
    """The TuSimple numbers from the sums.

    Returns:
        ``accuracy``, ``fp``, ``fn`` (lane.py's: the sums over the images), ``f1`` (the paper's, `paper_f1`),
        ``lane_precision``, ``lane_recall``, ``lane_f1`` (count-based, `prf` of the lane counts); all 0 for
        no image.
    """
    n = max(sums.images, 1)
    acc, fp, fn = sums.acc / n, sums.fp / n, sums.fn / n
    lp, lr, lf = prf(sums.lane_tp, sums.lane_pred - sums.lane_tp, sums.lane_gt - sums.lane_tp)
    return {
        "accuracy": acc,
        "fp": fp,
        "fn": fn,
        "f1": paper_f1(fp, fn),
        "lane_precision": lp,
        "lane_recall": lr,
        "lane_f1": lf,
    }


def culane_update(
    sums: Sequence[tuple[int, int, int]], per_image: Iterable[_CULaneImage], iou_thresholds: Sequence[float]
) -> list[tuple[int, int, int]]:
    """Add images' ``(tp, fp, fn)`` per IoU threshold to ``sums`` (one triple per threshold, in order)."""
    out = [list(s) for s in sums]
    for r in per_image:
        for k, t in enumerate(iou_thresholds):
            c = r.counts[t]
            out[k][0] += c[0]
            out[k][1] += c[1]
            out[k][2] += c[2]
    return [(tp, fp, fn) for tp, fp, fn in out]


def prf(tp: int, fp: int, fn: int) -> tuple[float, float, float]:
    """Precision TP/(TP+FP), recall TP/(TP+FN), F1 2PR/(P+R); each 0 where its denominator is 0 (lanedet's
    ``eval_predictions``; the C++ tool prints -1 there, and ``stamlane-eval`` refuses such input)."""
    p = tp / (tp + fp) if tp + fp > 0 else 0.0
    r = tp / (tp + fn) if tp + fn > 0 else 0.0
    f = 2 * p * r / (p + r) if p + r > 0 else 0.0
    return p, r, f


def paper_f1(fp: float, fn: float) -> float:
    """The paper's F1: harmonic mean of ``1 - fp`` and ``1 - fn`` (F1 96.81 from FP 0.0339, FN 0.0299)."""
    a, b = 1.0 - fp, 1.0 - fn
    return 2.0 * a * b / (a + b) if a + b != 0 else 0.0
