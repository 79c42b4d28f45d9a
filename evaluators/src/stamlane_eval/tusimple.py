"""TuSimple lane metric, number for number equal to the official ``evaluate/lane.py``.

Reference: TuSimple/tusimple-benchmark @ d1f5ef1b, ``evaluate/lane.py`` (``LaneEval.bench`` per image,
``LaneEval.bench_one_submit`` for a submission). Every quirk of that script is kept and commented where it
happens. The computation is vectorised over images (one code path: :func:`evaluate_image` is
:func:`evaluate_batch` on one image), the files are checked by ``stamlane_eval.io.check_tusimple`` (the one
check of the format) and the totals folded by ``stamlane_eval.aggregate`` (shared with the torchmetrics class),
so the per-image numbers, the dataset numbers, the CLI and the torchmetrics class cannot drift apart.

What is scored and what is refused (docs/evaluators.md): every input lane.py scores to a rate is scored to
lane.py's number, a prediction's huge, negative, fractional or non-finite x included, and a ground truth's too
(x = 150,000, NaN, -inf: as lane.py takes them), any lane count and length within the memory budgets
(``stamlane_eval.io.MAX_TUSIMPLE_VALUES``, ``MAX_COMPARED_CELLS``); where lane.py crashes, or
its numbers would not be rates (a ground truth naming an image twice; totals outside [0, 1], refused by
:func:`check_rates`, which the command line applies), the input is refused with a `TuSimpleInputError`.

A TuSimple lane is a list of x values, one per ``h_samples`` row; negative values (``-2``) mean "no lane on
this row". Coordinates are original-image pixels (1280x720 for TuSimple).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from stamlane_eval.aggregate import TuSimpleSums, paper_f1, prf, tusimple_compute, tusimple_update
from stamlane_eval.io.limits import MAX_COMPARED_CELLS
from stamlane_eval.io.tusimple import TuSimpleFile, TuSimpleInputError, check_tusimple

__all__ = [
    "ABSENT",
    "EXTRA_PRED_LANES",
    "MAX_RUN_TIME_MS",
    "MAX_SCORED_LANES",
    "PIXEL_THRESH",
    "POINT_THRESH",
    "RATE_TOLERANCE",
    "TuSimpleImageResult",
    "TuSimpleInputError",
    "TuSimpleResult",
    "check_rates",
    "evaluate",
    "evaluate_batch",
    "evaluate_image",
    "lanes_to_xs",
    "late_count",
    "late_message",
    "paper_f1",
    "prf",
]

PIXEL_THRESH = 20.0  # px; divided by cos(gt lane angle) (lane.py: LaneEval.pixel_thresh)
POINT_THRESH = 0.85  # fraction of rows within the threshold for a gt lane to count as matched (pt_thresh)
MAX_RUN_TIME_MS = 200.0  # run_time above this scores the image (acc 0, fp 0, fn 1)
EXTRA_PRED_LANES = 2  # more than len(gt) + 2 predicted lanes scores the image (acc 0, fp 0, fn 1)
MAX_SCORED_LANES = 4  # images with more gt lanes drop their worst lane (see _bench)
ABSENT = -2.0  # the benchmark's "no lane on this row" value
BLOCK_CELLS = 1 << 22  # pred x gt x row comparisons per vectorised block (~100 MB of temporaries at most)
RATE_TOLERANCE = 1e-9  # a total may pass [0, 1] by float rounding (1.0000000000000002), not by more
_NEGATIVE_FILL = -100.0  # lane.py replaces every negative value in pred and gt by -100 before comparing


@dataclass(frozen=True)
class TuSimpleImageResult:
    """Official per-image numbers plus the lane counts behind them.

    Attributes:
        acc: ``LaneEval.bench`` accuracy (may exceed 1 for > 4 gt lanes, as in the official tool).
        fp: ``LaneEval.bench`` FP rate (may be negative: no one-to-one matching).
        fn: ``LaneEval.bench`` FN rate.
        matched: gt lanes whose best prediction reaches ``POINT_THRESH`` (0 on an early return).
        n_pred: predicted lanes in the image.
        n_gt: ground-truth lanes in the image.
        early_return: the run_time / too-many-lanes rule fired (acc 0, fp 0, fn 1).
    """

    acc: float
    fp: float
    fn: float
    matched: int
    n_pred: int
    n_gt: int
    early_return: bool = False


@dataclass(frozen=True)
class TuSimpleResult:
    """Dataset numbers.

    ``accuracy``, ``fp``, ``fn`` are the official ones (sums in file order divided by the number of unique
    gt ``raw_file``s). ``f1`` is the paper's F1, the harmonic mean of ``1 - fp`` and ``1 - fn``.
    ``lane_precision``/``lane_recall``/``lane_f1`` are a different, count-based metric: matched gt lanes
    (``lane_tp``) over all predicted lanes / all gt lanes, with the official (not one-to-one) matching;
    do not confuse them with the paper's F1. ``late_images`` counts the images whose ``run_time`` exceeds
    ``MAX_RUN_TIME_MS``: scored as missed by the benchmark's rule (lane.py), or on their lanes without it.
    """

    accuracy: float
    fp: float
    fn: float
    f1: float
    images: int
    lane_tp: int
    lane_fp: int
    lane_fn: int
    lane_precision: float
    lane_recall: float
    lane_f1: float
    per_image: list[TuSimpleImageResult] = field(default_factory=list, repr=False)
    late_images: int = 0

    def as_dict(self) -> dict[str, float | int]:
        """The flat numbers (no per-image list), as the CLI's ``--json`` prints them."""
        return {
            "accuracy": self.accuracy,
            "fp": self.fp,
            "fn": self.fn,
            "f1": self.f1,
            "images": self.images,
            "lane_tp": self.lane_tp,
            "lane_fp": self.lane_fp,
            "lane_fn": self.lane_fn,
            "lane_precision": self.lane_precision,
            "lane_recall": self.lane_recall,
            "lane_f1": self.lane_f1,
            "late_images": self.late_images,
        }


def _bench(
    pred_flat: np.ndarray,
    n_pred: np.ndarray,
    gt_flat: np.ndarray,
    gt_drawn: np.ndarray,
    n_gt: np.ndarray,
    ys: np.ndarray,
    n_rows: np.ndarray,
    early: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``LaneEval.bench`` vectorised over n images.

    Args:
        pred_flat: ``(Lp, R)`` every predicted lane of the n images, image after image, padded with -100.
        n_pred: ``(n,)`` predicted lanes per image.
        gt_flat: ``(Lg, R)`` the gt lanes, ``gt_drawn[i]`` of them for image i (0 for early-returned images).
        gt_drawn: ``(n,)`` gt lanes present in ``gt_flat`` per image.
        n_gt: ``(n,)`` gt lanes per image.
        ys: ``(n, R)`` h_samples, padded.
        n_rows: ``(n,)`` len(h_samples).
        early: ``(n,)`` the run_time / too-many-lanes rule fired.

    Returns:
        acc, fp, fn (float64) and matched gt lanes (int64), each ``(n,)``.
    """
    n, r_max = len(n_rows), ys.shape[1]
    p_max, g_max = max(int(n_pred.max(initial=0)), 1), max(int(gt_drawn.max(initial=0)), 1)
    pred = np.full((n, p_max, r_max), _NEGATIVE_FILL)
    gt = np.full((n, g_max, r_max), _NEGATIVE_FILL)
    for flat, counts, dst in ((pred_flat, n_pred, pred), (gt_flat, gt_drawn, gt)):
        img = np.repeat(np.arange(n), counts)
        slot = np.arange(len(flat)) - np.repeat(np.cumsum(counts) - counts, counts)
        dst[img, slot] = flat
    row_ok = np.arange(r_max)[None, :] < n_rows[:, None]  # (n, R)
    pred_ok = np.arange(p_max)[None, :] < n_pred[:, None]  # (n, P)
    gt_ok = np.arange(g_max)[None, :] < gt_drawn[:, None]  # (n, G)

    # Gt lane angle (LaneEval.get_angle): least-squares x = k*y + b over the rows with x >= 0 (sklearn
    # LinearRegression, centred); theta = 0 with fewer than 2 such rows.
    on = (gt >= 0) & row_ok[:, None, :]
    cnt, yc, xc = _centred(gt, np.broadcast_to(ys[:, None, :], gt.shape), on)
    with np.errstate(over="ignore", invalid="ignore"):
        den = (yc * yc).sum(-1)
        k = (yc * xc).sum(-1) / np.where(den > 0, den, 1.0)
        # a far gt x (1e308) overflows the products that lstsq never forms: the same slope with x scaled down
        scale = np.maximum(np.abs(xc).max(-1, initial=0.0), 1.0)
        k_scaled = (yc * (xc / scale[..., None])).sum(-1) / np.where(den > 0, den, 1.0) * scale
        k = np.where(np.isfinite(k), k, k_scaled)
    k = np.where(cnt > 1, k, 0.0)
    theta = np.where(cnt > 1, np.arctan(k), 0.0)
    thresh = PIXEL_THRESH / np.cos(theta)  # (n, G)

    # LaneEval.line_accuracy: every negative value in pred or gt becomes -100 (so rows absent in both
    # count as hits), strict <, divided by len(gt) = all rows.
    pred = np.where(pred >= 0, pred, _NEGATIVE_FILL)
    gt = np.where(gt >= 0, gt, _NEGATIVE_FILL)
    accs = np.empty((n, p_max, g_max))  # (n, P, G)
    g_step = max(1, BLOCK_CELLS // (n * p_max * r_max))  # memory: a few gt lanes at a time for a large image
    for g0 in range(0, g_max, g_step):
        sl = slice(g0, g0 + g_step)
        hits = np.abs(pred[:, :, None, :] - gt[:, None, sl, :]) < thresh[:, None, sl, None]  # (n, P, g, R)
        hits &= row_ok[:, None, None, :]
        accs[:, :, sl] = hits.sum(-1) / n_rows[:, None, None]
    accs = np.where(pred_ok[:, :, None], accs, -np.inf)
    max_acc = np.where(n_pred[:, None] > 0, accs.max(1), 0.0)  # (n, G); 0 when there is no prediction
    max_acc = np.where(gt_ok, max_acc, 0.0)

    # Quirk: each gt lane takes its best prediction; no one-to-one assignment, so one prediction can match
    # several gt lanes and FP = len(pred) - matched can be negative.
    matched = ((max_acc >= POINT_THRESH) & gt_ok).sum(-1)
    fn = (n_gt - matched).astype(np.float64)
    fp = (n_pred - matched).astype(np.float64)
    # Quirk: with more than 4 gt lanes, one miss is forgiven and the worst lane dropped from the sum.
    many = n_gt > MAX_SCORED_LANES
    fn = np.where(many & (fn > 0), fn - 1.0, fn)
    s = np.zeros(n)
    for j in range(g_max):  # plain left-to-right sum as Python's sum() does, to match to the last bit
        s = s + max_acc[:, j]
    worst = np.where(gt_ok, max_acc, np.inf).min(-1)
    s = np.where(many, s - worst, s)
    denom = np.maximum(np.minimum(MAX_SCORED_LANES, n_gt), 1).astype(np.float64)
    acc = s / denom
    fp = np.where(n_pred > 0, fp / np.maximum(n_pred, 1), 0.0)
    fn = fn / denom
    # Quirk: run_time > 200 or > len(gt) + 2 predictions -> (0, 0, 1), nothing else looked at.
    acc = np.where(early, 0.0, acc)
    fp = np.where(early, 0.0, fp)
    fn = np.where(early, 1.0, fn)
    matched = np.where(early, 0, matched)
    return acc, fp, fn, matched


def _centred(xs: np.ndarray, ys: np.ndarray, on: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sklearn LinearRegression's centring of the rows ``on`` of lanes ``xs`` (``(..., R)``) with row y ``ys``
    (same shape): the row count, and y and x minus their means over those rows (0 off them), as float64."""
    cnt = on.sum(-1)
    safe = np.maximum(cnt, 1)
    with np.errstate(over="ignore", invalid="ignore"):
        ym = np.where(on, ys, 0.0).sum(-1) / safe
        xm = np.where(on, xs, 0.0).sum(-1) / safe
        yc = np.where(on, ys - ym[..., None], 0.0)
        xc = np.where(on, xs - xm[..., None], 0.0)
    return cnt, yc, xc


def evaluate_batch(
    preds: Sequence[object],
    gts: Sequence[object],
    h_samples: Sequence[Sequence[float]],
    run_times: Sequence[float] | None = None,
    chunk: int = 512,
) -> list[TuSimpleImageResult]:
    """Score many images at once (vectorised ``LaneEval.bench``).

    Args:
        preds: per image, predicted lanes: a list of x lists (or a float ``(P, R)`` array), one x per row.
        gts: per image, ground-truth lanes, same form ``(G, R)``.
        h_samples: per image, the ``R`` row y values.
        run_times: per image, run time in ms (default 0).
        chunk: at most this many images per vectorised block (fewer when they have many lanes and rows:
            ``BLOCK_CELLS`` bounds the memory).

    Returns:
        One :class:`TuSimpleImageResult` per image.

    Raises:
        TuSimpleInputError: as :func:`evaluate` (``stamlane_eval.io.check_tusimple``); ``line`` is the 1-based
            position of the image in the batch.
    """
    n = len(preds)
    if len(gts) != n or len(h_samples) != n:
        raise ValueError(f"got {n} preds, {len(gts)} gts and {len(h_samples)} h_samples lists; they must match")
    rt = [0.0] * n if run_times is None else [float(v) for v in run_times]
    if len(rt) != n:
        raise ValueError(f"expected {n} run_times, got {len(rt)}")
    if n == 0:
        return []
    names = [str(i) for i in range(n)]
    gt_records = [{"raw_file": k, "lanes": g, "h_samples": h} for k, g, h in zip(names, gts, h_samples)]
    gt = check_tusimple(gt_records, "gt", labels="lane.py")
    pred = check_tusimple(
        [{"raw_file": k, "lanes": p, "run_time": t} for k, p, t in zip(names, preds, rt)], "pred", labels="lane.py"
    )
    return _score(pred, gt, np.arange(n), pred.run_times, chunk)


def _pad(lanes: np.ndarray, width: int) -> np.ndarray:
    """``(L, w)`` lanes padded with -100 to ``(L, width)``."""
    if lanes.shape[1] == width:
        return lanes
    return np.pad(lanes[:, :width], ((0, 0), (0, max(width - lanes.shape[1], 0))), constant_values=_NEGATIVE_FILL)


def _score(
    pred: TuSimpleFile, gt: TuSimpleFile, take: np.ndarray, run_times: np.ndarray | None, chunk: int = 512
) -> list[TuSimpleImageResult]:
    """``LaneEval.bench`` of every prediction record against gt record ``take[i]``.

    Raises:
        TuSimpleInputError: lane.py's 'Format of lanes error.': a predicted lane not as long as the image's
            ``h_samples``, or a gt lane whose angle fit raises (`_unfit_gt`); an image over ``MAX_COMPARED_CELLS``.
    """
    assert gt.rows is not None and gt.h_samples is not None  # a ground truth's TuSimpleFile has both
    n = len(take)
    n_rows = gt.rows[take]
    n_pred, n_gt = pred.counts, gt.counts[take]
    owner = np.repeat(np.arange(n), n_pred)
    bad = np.flatnonzero(pred.lengths != n_rows[owner])
    if len(bad):
        i = int(owner[bad[0]])
        raise TuSimpleInputError(
            f"Format of lanes error: a pred lane has {pred.lengths[bad[0]]} values, h_samples has {n_rows[i]}",
            "pred",
            i + 1,
        )
    r_max = gt.h_samples.shape[1]
    pred_flat, gt_flat, ys = _pad(pred.lanes, r_max), _pad(gt.lanes, r_max), gt.h_samples[take]
    rt = np.zeros(n) if run_times is None else run_times
    # Quirk (order of checks): the lane lengths are checked first, for every image; then the run_time / count rule
    early = (rt > MAX_RUN_TIME_MS) | (n_gt + EXTRA_PRED_LANES < n_pred)
    unfit = _unfit_gt(gt)[take] & ~early  # lane.py fits the angle of an image's gt lanes only past the early return
    if unfit.any():
        i = int(np.argmax(unfit))
        raise TuSimpleInputError(
            "Format of lanes error: a gt lane has x = +inf, or a non-finite h_samples value, on a row it is on: "
            "lane.py's angle fit (LinearRegression) raises on it",
            "gt",
            int(take[i]) + 1,
        )
    # Images scored (0, 0, 1) by the early return compare nothing: lane.py returns before looking at their lanes.
    cmp_pred, cmp_gt = np.where(early, 0, n_pred), np.where(early, 0, n_gt)
    cells = cmp_pred * cmp_gt * n_rows
    if len(cells) and cells.max() > MAX_COMPARED_CELLS:  # time: lane.py compares every pair of lanes row by row
        i = int(np.argmax(cells))
        raise TuSimpleInputError(
            f"{n_pred[i]} predicted x {n_gt[i]} gt lanes x {n_rows[i]} rows: more than {MAX_COMPARED_CELLS:,} "
            f"comparisons in one image, past the time budget",
            "pred",
            i + 1,
        )
    # Images with the same lane counts are scored together, so that no block pads lanes it does not have.
    p_start = np.cumsum(n_pred) - n_pred
    g_start = (np.cumsum(gt.counts) - gt.counts)[take]
    acc, fp, fn = np.zeros(n), np.zeros(n), np.zeros(n)
    matched = np.zeros(n, dtype=np.int64)
    order = np.lexsort((cmp_gt, cmp_pred))
    key = cmp_pred[order] * (int(cmp_gt.max()) + 1) + cmp_gt[order]
    bounds = np.flatnonzero(np.diff(key)) + 1
    for group in np.split(order, bounds):
        # images per block: at most `chunk`, and few enough that the (images, P, G, R) comparison stays small
        block = max(int(cmp_pred[group[0]]), 1) * max(int(cmp_gt[group[0]]), 1) * r_max
        step = max(1, min(chunk, BLOCK_CELLS // block))
        for s in range(0, len(group), step):
            ids = group[s : s + step]
            res = _bench(
                pred_flat[_lane_index(p_start[ids], cmp_pred[ids])],
                cmp_pred[ids],
                gt_flat[_lane_index(g_start[ids], cmp_gt[ids])],
                cmp_gt[ids],
                n_gt[ids],
                ys[ids],
                n_rows[ids],
                early[ids],
            )
            acc[ids], fp[ids], fn[ids], matched[ids] = res
    return list(
        map(
            TuSimpleImageResult,
            acc.tolist(),
            fp.tolist(),
            fn.tolist(),
            matched.tolist(),
            n_pred.tolist(),
            n_gt.tolist(),
            early.tolist(),
        )
    )


def _unfit_gt(gt: TuSimpleFile) -> np.ndarray:
    """``(n,)``: the gt records with a lane whose angle lane.py cannot fit. ``get_angle`` fits the rows with
    ``x >= 0`` (NaN and -inf are not; +inf is) when there are two or more, and sklearn's LinearRegression raises on
    an infinite x or a non-finite row y among them (an x beyond the float range, 10**400, is lane.py's
    OverflowError: ``json_float`` reads it +inf), and scipy's lstsq on a mean or a centred value that overflows
    (two x of 1.7e308). A lone +inf row is not fitted (theta 0) and is scored, a miss."""
    assert gt.rows is not None and gt.h_samples is not None
    owner = np.repeat(np.arange(len(gt.counts)), gt.counts)
    if len(owner) == 0:
        return np.zeros(len(gt.counts), dtype=bool)
    r = gt.h_samples.shape[1]
    lanes = _pad(gt.lanes, r)
    ys = gt.h_samples[owner]
    with np.errstate(invalid="ignore"):
        on = (lanes >= 0) & (np.arange(r)[None, :] < gt.rows[owner][:, None])
    cnt, yc, xc = _centred(lanes, ys, on)
    bad = on & ~(np.isfinite(lanes) & np.isfinite(ys) & np.isfinite(yc) & np.isfinite(xc))
    lane_unfit = (cnt > 1) & bad.any(1)
    return np.bincount(owner, weights=lane_unfit, minlength=len(gt.counts)) > 0


def _lane_index(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Indices of the lanes of some images in a flat lane array (``starts``/``counts`` per image)."""
    return np.repeat(starts - (np.cumsum(counts) - counts), counts) + np.arange(int(counts.sum()))


def evaluate_image(
    preds: object, target: object, h_samples: Sequence[float], run_time: float = 0.0
) -> TuSimpleImageResult:
    """Score one image exactly as ``LaneEval.bench(pred, gt, y_samples, running_time)``.

    Args:
        preds: predicted lanes, a list of x lists (``-2`` = absent) or a float ``(P, R)`` array.
        target: ground-truth lanes, same form ``(G, R)``.
        h_samples: the ``R`` row y values.
        run_time: milliseconds spent on the image (> 200 scores the image as missed).

    Returns:
        The official acc/fp/fn plus lane counts.
    """
    return evaluate_batch([preds], [target], [h_samples], [run_time])[0]


def evaluate(
    preds: Sequence[Mapping[str, Any]], gts: Sequence[Mapping[str, Any]], time_limit: bool = True
) -> TuSimpleResult:
    """Score a submission exactly as ``LaneEval.bench_one_submit`` (records as read from the json-lines files).

    Args:
        preds: prediction records ``{"raw_file", "lanes", "run_time"}`` in file order.
        gts: ground-truth records ``{"raw_file", "lanes", "h_samples"}`` in file order.
        time_limit: apply the benchmark's rule that an image whose ``run_time`` exceeds 200 ms is missed
            (lane.py always does). False scores every image on its lanes alone, for comparing models whose
            run times were measured on a busy or slow machine; ``run_time`` is still required and checked.

    Returns:
        Official accuracy/FP/FN (summed in prediction order, divided by the number of images), the paper's F1,
        lane-count precision/recall/F1, the per-image results in prediction order and ``late_images``, the
        images over 200 ms (no warning here: the command line and the torchmetrics class warn, each naming its
        own switch).

    Raises:
        TuSimpleInputError: where lane.py raises, where its numbers would mean nothing (a gt naming an image
            twice, no image), where a file breaks the format's types (``stamlane_eval.io.check_tusimple``), and
            past the memory budgets (``MAX_TUSIMPLE_VALUES``, ``MAX_COMPARED_CELLS``). Totals outside [0, 1] are returned as lane.py computes them;
            :func:`check_rates` refuses them, as the command line does.

    Warns:
        UserWarning: once, when prediction or ground-truth values are no pixel coordinate (not finite, or beyond
            ``stamlane_eval.io.MAX_COORDINATE``): they are scored as lane.py scores them.
    """
    if len(gts) == 0 and len(preds) == 0:
        raise TuSimpleInputError("both files are empty: nothing to evaluate (lane.py divides 0 by 0)")
    if len(gts) != len(preds):
        raise TuSimpleInputError(
            f"We do not get the predictions of all the test tasks: {len(preds)} predictions for {len(gts)} gt images"
        )
    gt = check_tusimple(gts, "gt", labels="lane.py")
    pred = check_tusimple(preds, "pred", labels="lane.py")
    index = {name: i for i, name in enumerate(gt.names)}
    take = np.empty(len(preds), dtype=np.int64)
    seen = np.zeros(len(gts), dtype=bool)
    for i, name in enumerate(pred.names):
        j = index.get(name)
        if j is None:
            raise TuSimpleInputError(
                f"Some raw_file from your predictions do not exist in the test tasks: {name!r}", "pred", i + 1
            )
        if seen[j]:  # lane.py would score the image twice and another gt image never
            raise TuSimpleInputError(f"duplicate prediction for raw_file {name!r}", "pred", i + 1)
        seen[j] = True
        take[i] = j
    if pred.odd or gt.odd:  # one warning line for both files
        said = [f"{o[0]} {what} value(s)" for o, what in ((pred.odd, "prediction"), (gt.odd, "ground-truth")) if o]
        first = (pred.odd or gt.odd)[1]  # type: ignore[index]
        warnings.warn(
            f"{' and '.join(said)} are no pixel coordinate ({first}): scored as lane.py scores them "
            f"(a negative or NaN x: no point on that row; a huge one: a miss, and a huge gt x steepens its lane's "
            f"angle fit; run_time NaN: within the limit)",
            stacklevel=2,
        )
    per_image = _score(pred, gt, take, pred.run_times if time_limit else None)
    return replace(_result(per_image), late_images=late_count(pred.run_times))


def late_count(run_times: Sequence[float] | np.ndarray | None) -> int:
    """How many images the benchmark's time rule scores as missed: ``run_time > MAX_RUN_TIME_MS`` (a NaN is
    within the limit, as ``NaN > 200`` is false in lane.py)."""
    if run_times is None:
        return 0
    return int(np.count_nonzero(np.asarray(run_times, dtype=np.float64) > MAX_RUN_TIME_MS))


def late_message(late: int, images: int, switch: str) -> str:
    """The one line that says the 200 ms rule scored ``late`` of ``images`` images as missed, and names the
    ``switch`` that scores them on their lanes (``--no-time-limit``, ``time_limit=False``, ...)."""
    return (
        f"{late} of {images} images have a run_time over {MAX_RUN_TIME_MS:g} ms and are scored as missed, as "
        f"lane.py does; {switch} scores them on their lanes"
    )


def check_rates(result: TuSimpleResult) -> None:
    """Refuse totals that are not rates, as ``stamlane-eval tusimple`` does (docs/evaluators.md): lane.py's
    accuracy, FP and FN outside [0, 1] beyond float rounding (`RATE_TOLERANCE`). :func:`evaluate` itself returns
    lane.py's numbers whatever they are, as the torchmetrics class does: a run that logs them does not stop.

    Raises:
        TuSimpleInputError: naming the number and why lane.py's arithmetic gave it.
    """
    for name, why in (
        ("accuracy", f"images with more than {MAX_SCORED_LANES + 1} gt lanes count for more than one image"),
        ("fn", f"images with more than {MAX_SCORED_LANES + 1} gt lanes count for more than one image"),
        ("fp", "one predicted lane matching several gt lanes (lane.py matches no one-to-one) counts below 0"),
    ):
        value = getattr(result, name)
        if not -RATE_TOLERANCE <= value <= 1.0 + RATE_TOLERANCE:
            raise TuSimpleInputError(f"lane.py's {name} would be {value!r}, not a rate in [0, 1]: {why}")


def _result(per_image: list[TuSimpleImageResult]) -> TuSimpleResult:
    """The dataset numbers (`stamlane_eval.aggregate`)."""
    sums = tusimple_update(TuSimpleSums(), per_image)
    vals = tusimple_compute(sums)
    return TuSimpleResult(
        accuracy=vals["accuracy"],
        fp=vals["fp"],
        fn=vals["fn"],
        f1=vals["f1"],
        images=sums.images,
        lane_tp=sums.lane_tp,
        lane_fp=sums.lane_pred - sums.lane_tp,
        lane_fn=sums.lane_gt - sums.lane_tp,
        lane_precision=vals["lane_precision"],
        lane_recall=vals["lane_recall"],
        lane_f1=vals["lane_f1"],
        per_image=per_image,
    )


def lanes_to_xs(lanes: Sequence[np.ndarray], h_samples: Sequence[float]) -> list[list[float]]:
    """Polylines to TuSimple x lists, so that any lane model can be scored with the TuSimple metric.

    Args:
        lanes: per lane, an ``(N, 2)`` float array of ``(x, y)`` points in original pixels, any order.
        h_samples: the ``R`` row y values of the benchmark.

    Returns:
        Per lane, ``R`` x values: linear interpolation at each row inside the lane's y range, ``-2`` outside.
    """
    h = np.asarray(h_samples, dtype=np.float64)
    out = []
    for lane in lanes:
        pts = np.asarray(lane, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 0:
            out.append([ABSENT] * len(h))
            continue
        order = np.argsort(pts[:, 1], kind="stable")
        x, y = pts[order, 0], pts[order, 1]
        xs = np.interp(h, y, x)
        inside = (h >= y[0]) & (h <= y[-1])
        out.append(np.where(inside, xs, ABSENT).tolist())
    return out
