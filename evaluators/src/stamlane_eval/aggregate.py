"""Every metric's aggregation, each formula written once (the torchmetrics pattern of shared update/compute helpers).

- TuSimple: `TuSimpleSums`, `tusimple_update` (lane.py's float sums in file order), `tusimple_compute`
  (`paper_f1`, and `prf` of the lane counts);
- CULane / ApolloScape, the video F and RVLD's temporal stability: `count_update` sums count triples per IoU
  threshold (``(tp, fp, fn)`` or ``(Ns, Nj, Nm)``); `prf` makes precision, recall and F1 of ``(tp, fp, fn)``,
  `stability_rates` Rs, Rj and Rm of ``(Ns, Nj, Nm)``;
- the video mIoU: `sequence_miou` (a sequence's frames), `dataset_miou` (MMA-Net's mean of the sequences' printed
  values).

The functions (``tusimple.evaluate``, ``culane.evaluate``, ``video.evaluate``, ``temporal.evaluate``), the command
line, the torchmetrics classes (so the Lightning callback) and the bootstrap statistics of `stamlane_eval.stats`
all fold their per-image results with these, so they cannot drift: the same images give the same numbers to the
last bit, whichever way they are scored. The sums are plain numbers; the torchmetrics classes keep them as states
summed across processes.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

__all__ = [
    "MMA_NET_DIGITS",
    "TuSimpleSums",
    "count_update",
    "dataset_miou",
    "paper_f1",
    "prf",
    "sequence_miou",
    "stability_rates",
    "tusimple_compute",
    "tusimple_update",
]

MMA_NET_DIGITS = 6
"""MMA-Net's evaluate.cpp writes each video's mIoU with iostream's default 6 significant digits, and
evaluate_iou.py averages those printed values over the videos (`dataset_miou`)."""


class _TuSimpleImage(Protocol):
    @property
    def acc(self) -> float: ...
    @property
    def fp(self) -> float: ...
    @property
    def fn(self) -> float: ...
    @property
    def matched(self) -> int: ...
    @property
    def n_pred(self) -> int: ...
    @property
    def n_gt(self) -> int: ...


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


def count_update(
    sums: Sequence[tuple[int, int, int]],
    counts: Iterable[Mapping[float, Sequence[int]]],
    thresholds: Sequence[float],
) -> list[tuple[int, int, int]]:
    """Add count triples to ``sums``, per threshold.

    Args:
        sums: one triple per threshold, in the order of ``thresholds``.
        counts: per image, frame pair or sequence, threshold -> its triple: ``(tp, fp, fn)`` (CULane, the video F:
            a result's ``counts``) or ``(Ns, Nj, Nm)`` (temporal: a pair's counts).
        thresholds: the thresholds to add.

    Returns:
        The new sums, one triple per threshold.
    """
    out = [list(s) for s in sums]
    for c in counts:
        for k, t in enumerate(thresholds):
            triple = c[t]
            out[k][0] += triple[0]
            out[k][1] += triple[1]
            out[k][2] += triple[2]
    return [(a, b, c) for a, b, c in out]


def prf(tp: float, fp: float, fn: float) -> tuple[float, float, float]:
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


def stability_rates(ns: float, nj: float, nm: float) -> tuple[float, float, float]:
    """RVLD's Rs, Rj, Rm: the shares of Stable, Jump and Missing in ``Ns + Nj + Nm`` (``evaluate_temporal.py``:
    ``float(total_ns) / (total_ns + total_nj + total_nm)``); NaN where nothing was counted (the script divides by
    zero). Sums or their means per sequence give the same shares."""
    total = float(ns + nj + nm)
    if not total:
        return math.nan, math.nan, math.nan
    return float(ns) / total, float(nj) / total, float(nm) / total


def sequence_miou(frame_mious: Sequence[float]) -> float | None:
    """A sequence's mIoU as MMA-Net's evaluate.cpp computes it: the frames' values summed in order, divided by the
    frames (``iou += get<5>(result)``, then ``/ filelists.size()``); None for no frame."""
    return sum(frame_mious) / len(frame_mious) if frame_mious else None


def dataset_miou(sequence_mious: Sequence[float]) -> float:
    """MMA-Net's "all scenes miou": each sequence's mIoU as its C++ tool prints it, averaged over sequences.

    Returns:
        0.0 for no sequence (MMA-Net divides by zero there).
    """
    if not sequence_mious:
        return 0.0
    printed = [float(f"{m:.{MMA_NET_DIGITS}g}") for m in sequence_mious]  # read_helper parses the printed text
    return sum(printed) / len(printed)  # MIOU += float(v['miou']); MIOU / len(res.items())
