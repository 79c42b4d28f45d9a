"""TuSimple lane metric, number for number equal to the official ``evaluate/lane.py``.

Reference: TuSimple/tusimple-benchmark @ d1f5ef1b, ``evaluate/lane.py`` (``LaneEval.bench`` per image,
``LaneEval.bench_one_submit`` for a submission). Every quirk of that script is kept and commented where it
happens. The computation is vectorised over images (one code path: :func:`evaluate_image` is
:func:`evaluate_batch` on one image), so the per-image numbers, the dataset numbers, the CLI and the
torchmetrics class cannot drift apart.

A TuSimple lane is a list of x values, one per ``h_samples`` row; negative values (``-2``) mean "no lane on
this row". Coordinates are original-image pixels (1280x720 for TuSimple).
"""

from __future__ import annotations

import math
import warnings
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from stamlane_eval.io import MAX_COORDINATE

__all__ = [
    "ABSENT",
    "EXTRA_PRED_LANES",
    "MAX_RUN_TIME_MS",
    "MAX_SCORED_LANES",
    "PIXEL_THRESH",
    "POINT_THRESH",
    "TuSimpleImageResult",
    "TuSimpleInputError",
    "TuSimpleResult",
    "evaluate",
    "evaluate_batch",
    "evaluate_image",
    "lanes_to_xs",
    "paper_f1",
    "prf",
]

PIXEL_THRESH = 20.0  # px; divided by cos(gt lane angle) (lane.py: LaneEval.pixel_thresh)
POINT_THRESH = 0.85  # fraction of rows within the threshold for a gt lane to count as matched (pt_thresh)
MAX_RUN_TIME_MS = 200.0  # run_time above this scores the image (acc 0, fp 0, fn 1)
EXTRA_PRED_LANES = 2  # more than len(gt) + 2 predicted lanes scores the image (acc 0, fp 0, fn 1)
MAX_SCORED_LANES = 4  # images with more gt lanes drop their worst lane (see _bench)
ABSENT = -2.0  # the benchmark's "no lane on this row" value
_NEGATIVE_FILL = -100.0  # lane.py replaces every negative value in pred and gt by -100 before comparing


class TuSimpleInputError(ValueError):
    """A submission or ground truth the official script would reject (or score meaninglessly).

    Attributes:
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
    do not confuse them with the paper's F1.
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
        }


def paper_f1(fp: float, fn: float) -> float:
    """The paper's F1: harmonic mean of ``1 - fp`` and ``1 - fn`` (F1 96.81 from FP 0.0339, FN 0.0299)."""
    a, b = 1.0 - fp, 1.0 - fn
    return 2.0 * a * b / (a + b) if a + b != 0 else 0.0


def prf(tp: int, fp: int, fn: int) -> tuple[float, float, float]:
    """Precision, recall, F1 from counts; each is 0 where its denominator is 0 (F1 is 0 when TP is 0)."""
    p = tp / (tp + fp) if tp + fp > 0 else 0.0
    r = tp / (tp + fn) if tp + fn > 0 else 0.0
    f = 2 * p * r / (p + r) if p + r > 0 else 0.0
    return p, r, f


def _fmt_error(what: str, i: int, message: str) -> TuSimpleInputError:
    return TuSimpleInputError(f"Format of lanes error: {message}", what, i + 1)


def _stack_rows(
    rows: list[object], lengths: np.ndarray, owner: np.ndarray, width: int, what: str, kind: str
) -> np.ndarray:
    """Stack number lists of the given lengths into a ``(len(rows), width)`` float array padded with -100.

    ``owner[j]`` is the image of row j (for the error message); ``kind`` names the rows ("lane", "h_samples").
    """
    out = np.full((len(rows), width), _NEGATIVE_FILL)
    uniq = np.unique(lengths)
    for length in uniq.tolist():
        idx = np.flatnonzero(lengths == length) if len(uniq) > 1 else np.arange(len(rows))
        sub = rows if len(uniq) == 1 else [rows[j] for j in idx.tolist()]
        try:
            arr = np.array(sub)
        except (ValueError, TypeError):
            arr = np.zeros(0, dtype=object)
        if arr.ndim != 2 or arr.dtype.kind not in "iuf":
            for j in idx.tolist():  # find the culprit for the message
                one = np.asarray(rows[j]) if isinstance(rows[j], (list, tuple, np.ndarray)) else np.zeros(0, object)
                if one.ndim != 1 or one.dtype.kind not in "iuf":
                    raise _fmt_error(
                        what, int(owner[j]), f"{what} {kind} must be a list of numbers, got {rows[j]!r:.80}"
                    )
            raise _fmt_error(what, int(owner[idx[0]]), f"{what} {kind}s must be lists of numbers")
        if not np.isfinite(arr).all():
            # lane.py would silently treat NaN as absent and inf as a miss; we refuse instead.
            bad = idx[np.flatnonzero(~np.isfinite(arr).all(axis=1))[0]]
            raise TuSimpleInputError(f"non-finite (NaN/inf) value in {what} {kind}", what, int(owner[bad]) + 1)
        if arr.size and np.abs(arr).max() > MAX_COORDINATE:  # a 1e12 is a bug, not a far-off lane point
            bad = idx[np.flatnonzero(np.abs(arr).max(axis=1) > MAX_COORDINATE)[0]]
            raise TuSimpleInputError(
                f"{what} {kind} value beyond +-{MAX_COORDINATE:g} px: not a pixel coordinate", what, int(owner[bad]) + 1
            )
        out[idx, :length] = arr
    return out


def _flatten_lanes(
    per_image: Sequence[object], n_rows: np.ndarray, what: str, skip: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """All lanes of all images as one ``(L, R_max)`` array (padded with -100) and per-image lane counts.

    Raises lane.py's 'Format of lanes error.' (naming the image) for a lane whose length is not len(h_samples).
    """
    n = len(per_image)
    counts = np.zeros(n, dtype=np.int64)
    flat: list[object] = []
    for i, lanes in enumerate(per_image):
        if skip is not None and skip[i]:
            continue  # quirk: the gt of an early-returned image is never looked at
        if not isinstance(lanes, (list, tuple, np.ndarray)):
            raise _fmt_error(what, i, f"{what} lanes must be a list of lists, got {lanes!r:.80}")
        counts[i] = len(lanes)
        flat.extend(lanes)
    owner = np.repeat(np.arange(n), counts)
    try:
        lengths = np.fromiter(map(len, flat), dtype=np.int64, count=len(flat))
    except TypeError:
        j = next(j for j, lane in enumerate(flat) if not isinstance(lane, (list, tuple, np.ndarray)))
        raise _fmt_error(what, int(owner[j]), f"a {what} lane must be a list of numbers, got {flat[j]!r:.80}") from None
    bad = np.flatnonzero(lengths != n_rows[owner])
    if len(bad):
        i = int(owner[bad[0]])
        raise _fmt_error(what, i, f"a {what} lane has {lengths[bad[0]]} values, h_samples has {n_rows[i]}")
    width = int(n_rows.max(initial=0))
    return _stack_rows(flat, lengths, owner, width, what, "lane"), counts


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
    cnt = on.sum(-1)
    safe = np.maximum(cnt, 1)
    y3 = np.broadcast_to(ys[:, None, :], gt.shape)
    ym = np.where(on, y3, 0.0).sum(-1) / safe
    xm = np.where(on, gt, 0.0).sum(-1) / safe
    yc = np.where(on, y3 - ym[..., None], 0.0)
    xc = np.where(on, gt - xm[..., None], 0.0)
    den = (yc * yc).sum(-1)
    k = np.where(cnt > 1, (yc * xc).sum(-1) / np.where(den > 0, den, 1.0), 0.0)
    theta = np.where(cnt > 1, np.arctan(k), 0.0)
    thresh = PIXEL_THRESH / np.cos(theta)  # (n, G)

    # LaneEval.line_accuracy: every negative value in pred or gt becomes -100 (so rows absent in both
    # count as hits), strict <, divided by len(gt) = all rows.
    pred = np.where(pred >= 0, pred, _NEGATIVE_FILL)
    gt = np.where(gt >= 0, gt, _NEGATIVE_FILL)
    hits = np.abs(pred[:, :, None, :] - gt[:, None, :, :]) < thresh[:, None, :, None]  # (n, P, G, R)
    hits &= row_ok[:, None, None, :]
    accs = hits.sum(-1) / n_rows[:, None, None]  # (n, P, G)
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
        chunk: images per vectorised block (bounds memory).

    Returns:
        One :class:`TuSimpleImageResult` per image.

    Raises:
        TuSimpleInputError: where lane.py raises ('Format of lanes error.') or on NaN/inf values; ``line`` is
            the 1-based position of the image in the batch.
    """
    n = len(preds)
    if len(gts) != n or len(h_samples) != n:
        raise ValueError(f"got {n} preds, {len(gts)} gts and {len(h_samples)} h_samples lists; they must match")
    rt = np.zeros(n) if run_times is None else np.asarray(run_times, dtype=np.float64)
    if rt.shape != (n,):
        raise ValueError(f"expected {n} run_times, got shape {rt.shape}")
    if n == 0:
        return []
    for i, h in enumerate(h_samples):
        if not isinstance(h, (list, tuple, np.ndarray)):
            raise TuSimpleInputError(f"h_samples must be a list of numbers, got {h!r:.80}", "gt", i + 1)
    n_rows = np.fromiter(map(len, h_samples), dtype=np.int64, count=n)
    if not n_rows.all():  # lane.py would divide by zero
        raise TuSimpleInputError("h_samples is empty: no row to score", "gt", int(np.argmin(n_rows)) + 1)
    ys = _stack_rows(list(h_samples), n_rows, np.arange(n), int(n_rows.max()), "gt", "h_samples")
    # Quirk (order of checks): the pred lane lengths are checked first, for every image; then the
    # run_time / count rule; gt lanes only for the images that get past it (where lane.py's indexing fails).
    pred_flat, n_pred = _flatten_lanes(preds, n_rows, "pred")
    n_gt = np.fromiter((len(g) if isinstance(g, (list, tuple, np.ndarray)) else 0 for g in gts), np.int64, count=n)
    early = (rt > MAX_RUN_TIME_MS) | (n_gt + EXTRA_PRED_LANES < n_pred)
    gt_flat, gt_drawn = _flatten_lanes(gts, n_rows, "gt", skip=early)
    # Images with the same lane counts are scored together, so that no block pads lanes it does not have.
    p_start, g_start = np.cumsum(n_pred) - n_pred, np.cumsum(gt_drawn) - gt_drawn
    acc, fp, fn = np.zeros(n), np.zeros(n), np.zeros(n)
    matched = np.zeros(n, dtype=np.int64)
    order = np.lexsort((gt_drawn, n_pred))
    key = n_pred[order] * (int(gt_drawn.max()) + 1) + gt_drawn[order]
    bounds = np.flatnonzero(np.diff(key)) + 1
    for group in np.split(order, bounds):
        for s in range(0, len(group), chunk):
            ids = group[s : s + chunk]
            p_idx = _lane_index(p_start[ids], n_pred[ids])
            g_idx = _lane_index(g_start[ids], gt_drawn[ids])
            res = _bench(
                pred_flat[p_idx],
                n_pred[ids],
                gt_flat[g_idx],
                gt_drawn[ids],
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


def _check_keys(rec: object, keys: tuple[str, ...], source: str, i: int, message: str) -> Mapping:
    if type(rec) is dict and keys[0] in rec and keys[1] in rec and keys[2] in rec:
        return rec  # fast path
    if not isinstance(rec, Mapping) or any(k not in rec for k in keys):
        have = sorted(rec) if isinstance(rec, Mapping) else type(rec).__name__
        raise TuSimpleInputError(f"{message} (has keys {have}, needs {list(keys)})", source, i + 1)
    return rec


def evaluate(preds: Sequence[Mapping], gts: Sequence[Mapping], time_limit: bool = True) -> TuSimpleResult:
    """Score a submission exactly as ``LaneEval.bench_one_submit`` (records as read from the json-lines files).

    Args:
        preds: prediction records ``{"raw_file", "lanes", "run_time"}`` in file order.
        gts: ground-truth records ``{"raw_file", "lanes", "h_samples"}`` in file order.
        time_limit: apply the benchmark's rule that an image whose ``run_time`` exceeds 200 ms is missed
            (lane.py always does). False scores every image on its lanes alone, for comparing models whose
            run times were measured on a busy or slow machine; ``run_time`` is still required and checked.

    Returns:
        Official accuracy/FP/FN (summed in prediction order, divided by the number of unique gt raw_files),
        the paper's F1, lane-count precision/recall/F1 and the per-image results in prediction order.

    Raises:
        TuSimpleInputError: for every condition where lane.py raises, plus duplicate predictions and
            NaN/inf values. A duplicate gt raw_file is accepted as lane.py does (the last one wins and the
            mean divides by unique names) with a warning.
    """
    if len(gts) == 0 and len(preds) == 0:
        # lane.py: ZeroDivisionError ('float division by zero') on two empty files.
        raise TuSimpleInputError("both files are empty: nothing to evaluate")
    if len(gts) != len(preds):
        raise TuSimpleInputError(
            f"We do not get the predictions of all the test tasks: {len(preds)} predictions for {len(gts)} gt images"
        )
    gt_by_name: dict[str, Mapping] = {}
    gt_line: dict[str, int] = {}
    for i, g in enumerate(gts):
        g = _check_keys(g, ("raw_file", "lanes", "h_samples"), "gt", i, "raw_file or lanes or h_samples not in gt")
        if not isinstance(g["raw_file"], str):
            raise TuSimpleInputError(f"raw_file must be a string, got {g['raw_file']!r:.80}", "gt", i + 1)
        gt_by_name[g["raw_file"]] = g  # quirk: a duplicate raw_file keeps the LAST record
        gt_line[g["raw_file"]] = i + 1
    gt_count = Counter(g["raw_file"] for g in gts)
    dups = [name for name, c in gt_count.items() if c > 1]
    if dups:
        warnings.warn(
            f"{len(dups)} duplicate gt raw_file(s) (e.g. {dups[0]!r}): as lane.py, the last record is used and "
            f"the mean divides by the {len(gt_by_name)} unique names",
            stacklevel=2,
        )
    pred_count: Counter[str] = Counter()
    p_lanes, g_lanes, hs, rts = [], [], [], []
    for i, p in enumerate(preds):
        p = _check_keys(
            p, ("raw_file", "lanes", "run_time"), "pred", i, "raw_file or lanes or run_time not in some predictions."
        )
        name = p["raw_file"]
        if not isinstance(name, str) or name not in gt_by_name:
            raise TuSimpleInputError(
                f"Some raw_file from your predictions do not exist in the test tasks: {name!r}", "pred", i + 1
            )
        pred_count[name] += 1
        if pred_count[name] > gt_count[name]:
            # lane.py would score the image twice and another gt image never; refuse.
            raise TuSimpleInputError(f"duplicate prediction for raw_file {name!r}", "pred", i + 1)
        rt = p["run_time"]
        if isinstance(rt, bool) or not isinstance(rt, (int, float)) or not math.isfinite(rt):
            raise TuSimpleInputError(
                f"Format of lanes error: run_time must be a finite number, got {rt!r}", "pred", i + 1
            )
        g = gt_by_name[name]
        p_lanes.append(p["lanes"])
        g_lanes.append(g["lanes"])
        hs.append(g["h_samples"])
        rts.append(float(rt))
    try:
        per_image = evaluate_batch(p_lanes, g_lanes, hs, rts if time_limit else None)
    except TuSimpleInputError as e:
        if e.source == "gt" and e.line is not None:  # batch position -> line of that image in the gt file
            raise TuSimpleInputError(e.message, "gt", gt_line[preds[e.line - 1]["raw_file"]]) from None
        raise
    accuracy = fp = fn = 0.0
    for r in per_image:  # plain float sums in file order, as lane.py, to match to the last bit
        accuracy += r.acc
        fp += r.fp
        fn += r.fn
    num = len(gt_by_name)
    accuracy, fp, fn = accuracy / num, fp / num, fn / num
    tp = sum(r.matched for r in per_image)
    n_pred = sum(r.n_pred for r in per_image)
    n_gt = sum(r.n_gt for r in per_image)
    lp, lr, lf = prf(tp, n_pred - tp, n_gt - tp)
    return TuSimpleResult(
        accuracy=accuracy,
        fp=fp,
        fn=fn,
        f1=paper_f1(fp, fn),
        images=num,
        lane_tp=tp,
        lane_fp=n_pred - tp,
        lane_fn=n_gt - tp,
        lane_precision=lp,
        lane_recall=lr,
        lane_f1=lf,
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
