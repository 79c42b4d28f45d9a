"""CULane / ApolloScape area metric, number for number equal to the official C++ tool (or to lanedet's port).

``variant="official"`` reproduces XingangPan/SCNN @ 428d5e00 ``tools/lane_evaluation`` (``evaluate -w 30 -t T
-c W -r H -f 1``): every line of a ``.lines.txt`` is a lane; lanes of > 2 points are resampled by a natural cubic
spline (chord-length parameter, 50 samples per segment plus the last point); points are float32 and rounded to
int; each lane is drawn with ``cv::line`` of thickness ``width``; IoU = |A and B| / |A or B|; a lane with < 2
points has IoU 0 with everything; matching is the tool's Kuhn-Munkres (maximum total IoU, 1e-2 tolerance);
TP = matched pairs with IoU > t (strict).

``variant="lanedet"`` reproduces Turoad/lanedet @ 35665fc9 ``lanedet/utils/culane_metric.py``
(``culane_metric(..., official=True)``), the Python port most papers' code used: lanes of < 2 points are
dropped, lanes are resampled with scipy ``splprep`` (k <= 3, s = 0, 5 samples per knot interval), truncated
to int, and matched with scipy ``linear_sum_assignment``.

Speed: each lane is rasterised once, with OpenCV itself, into a canvas cropped to its bounding box (the
drawing is translation invariant, so the pixels equal those of a full-size image); a pair's intersection is
counted only where the two boxes overlap.

Lanes are ``(N, 2)`` float arrays of ``(x, y)`` points in original-image pixels.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from stamlane_eval._long_runs import progress_bar
from stamlane_eval.aggregate import count_update, prf
from stamlane_eval.io.limits import CanvasBudget, check_image_size

__all__ = [
    "APOLLO_SIZE",
    "CULANE_SIZE",
    "IOU_THRESHOLDS",
    "LANE_WIDTH",
    "VARIANTS",
    "CULaneCounts",
    "CULaneImageResult",
    "CULaneResult",
    "aggregate",
    "counts_to_prf",
    "evaluate",
    "evaluate_image",
]

CULANE_SIZE = (590, 1640)  # (H, W) of CULane images (1640x590)
APOLLO_SIZE = (2710, 3384)  # (H, W) of ApolloScape frames (3384x2710)
LANE_WIDTH = 30  # px, the protocol's line thickness (the C++ binary's built-in default 10 is not the protocol)
IOU_THRESHOLDS = (0.3, 0.5)
VARIANTS = ("official", "lanedet")
SPLINE_SAMPLES = 50  # C++: splineInterpTimes(lane, 50) samples per segment, plus the last point
LANEDET_SAMPLES = 5  # lanedet: interp(lane, n=5), i.e. (len(u) - 1) * 5 + 1 samples
SPLINE_POINTS = 1 << 20  # resampled points per spline batch (~100 MB of float64 temporaries)
BATCH_IMAGES = 128  # images whose lanes are resampled together (bounds the memory of the batch: ~17 MB)
BATCH_POINTS = 1 << 16  # ... and at most this many input points in a batch but its first image (~80 MB resampled)
KM_TOLERANCE = 1e-2  # C++ hungarianGraph: an edge is "tight" when |lw + rw - w| < 1e-2


@dataclass(frozen=True)
class CULaneImageResult:
    """One image.

    Attributes:
        counts: threshold -> ``(tp, fp, fn)``.
        ious: ``(n_pred, n_gt)`` pixel IoU (NaN where both lanes lie outside the image: 0/0 in both tools).
        matched_iou: ``(n_pred,)`` IoU with the matched annotation, 0 when unmatched (not thresholded).
        n_pred: predicted lanes counted (lanedet: after dropping < 2-point lanes).
        n_gt: annotated lanes counted.
        pred_to_gt: ``(n_pred,)`` index of the matched annotation, -1 when unmatched (not thresholded).
    """

    counts: dict[float, tuple[int, int, int]]
    ious: np.ndarray = field(repr=False)
    matched_iou: np.ndarray = field(repr=False)
    n_pred: int = 0
    n_gt: int = 0
    pred_to_gt: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64), repr=False)


@dataclass(frozen=True)
class CULaneCounts:
    """Totals at one threshold: P = TP/(TP+FP), R = TP/(TP+FN), F1 = 2PR/(P+R), each 0 where undefined."""

    tp: int
    fp: int
    fn: int
    precision: float
    recall: float
    f1: float

    def as_dict(self) -> dict[str, float | int]:
        return {k: getattr(self, k) for k in ("tp", "fp", "fn", "precision", "recall", "f1")}


@dataclass(frozen=True)
class CULaneResult:
    """Dataset totals per threshold, image count and the per-image results (in input order)."""

    totals: dict[float, CULaneCounts]
    images: int
    per_image: list[CULaneImageResult] = field(default_factory=list, repr=False)

    def as_dict(self) -> dict[str, object]:
        """``{"0.3": {"tp", "fp", "fn", "precision", "recall", "f1"}, "0.5": {...}, "images": N}``."""
        out: dict[str, object] = {str(t): c.as_dict() for t, c in self.totals.items()}
        out["images"] = self.images
        return out


# ---------------------------------------------------------------------------------------------- resampling
def _spline_official_many(pts: np.ndarray, times: int = SPLINE_SAMPLES) -> np.ndarray:
    """C++ ``Spline::splineInterpTimes`` of L lanes of n > 2 points at once: ``(L, n, 2)`` float32 ->
    ``(L, (n-1)*times + 1, 2)`` float32.

    Natural cubic spline per coordinate, parameter = chord length, solved with the tool's TDMA in the same
    operation order (float32 differences promoted to double, as ``Point2f`` arithmetic in C++), element by element
    for all lanes at once (numpy's float64 arithmetic is IEEE's: each lane's points are bit-identical to a
    per-lane computation; checked on 3,429 random lanes against the per-lane Python version this replaced). A
    lane where the C++ divides by zero (repeated points) comes out all NaN, as there.
    """
    n_lanes, n = pts.shape[0], pts.shape[1]
    d = (pts[:, 1:] - pts[:, :-1]).astype(np.float64)  # float32 subtraction, as Point2f.x - Point2f.x
    h = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)  # (L, n-1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        slope = d / h[..., None]
        rhs = 6 * (slope[:, 1:] - slope[:, :-1])  # (L, n-2, 2)
        a, b, c = h[:, :-1], 2 * (h[:, :-1] + h[:, 1:]), h[:, 1:].copy()
        dx, dy = rhs[..., 0].copy(), rhs[..., 1].copy()
        failed = b[:, 0] == 0  # the C++ divides by 0 (repeated points): NaN points
        c[:, 0] = c[:, 0] / b[:, 0]
        dx[:, 0] = dx[:, 0] / b[:, 0]
        dy[:, 0] = dy[:, 0] / b[:, 0]
        for i in range(1, n - 2):  # TDMA forward sweep
            tmp = b[:, i] - a[:, i] * c[:, i - 1]
            failed |= tmp == 0
            c[:, i] = c[:, i] / tmp
            dx[:, i] = (dx[:, i] - a[:, i] * dx[:, i - 1]) / tmp
            dy[:, i] = (dy[:, i] - a[:, i] * dy[:, i - 1]) / tmp
        m = np.zeros((n_lanes, n, 2))
        m[:, n - 2, 0], m[:, n - 2, 1] = dx[:, n - 3], dy[:, n - 3]
        for i in range(n - 4, -1, -1):
            m[:, i + 1, 0] = dx[:, i] - c[:, i] * m[:, i + 2, 0]
            m[:, i + 1, 1] = dy[:, i] - c[:, i] * m[:, i + 2, 1]
        h2 = h[..., None]
        coef_b = slope - (2 * h2 * m[:, :-1] + h2 * m[:, 1:]) / 6
        coef_c = m[:, :-1] / 2
        coef_d = (m[:, 1:] - m[:, :-1]) / (6 * h2)
        t = (h / times)[..., None] * np.arange(times, dtype=np.float64)  # (L, n-1, times): delta * k
        t2 = t * t
        t3 = np.power(t, 3.0)
        # a + b t + c t^2 + d t^3, left to right as in C++, per coordinate on contiguous (L, n-1, times) arrays
        # (a trailing axis of 2 would make numpy's inner loops 2 elements long: slower, same numbers)
        out = np.empty((n_lanes, (n - 1) * times + 1, 2), np.float32)
        for k in (0, 1):
            v = pts[:, :-1, k, None].astype(np.float64) + coef_b[:, :, k, None] * t
            v += coef_c[:, :, k, None] * t2
            v += coef_d[:, :, k, None] * t3
            out[:, :-1, k] = v.reshape(n_lanes, -1)  # Point2f(x1, y1): float64 -> float32, round to nearest
    out[:, -1] = pts[:, -1]  # plus the last input point
    out[failed] = np.nan
    return out


def _points_official(lane: np.ndarray) -> np.ndarray | None:
    """Integer polyline the C++ tool draws for a lane, or None for a lane of < 2 points."""
    return _points_official_many([lane])[0]


def _points_official_many(lanes: Sequence[np.ndarray]) -> list[np.ndarray | None]:
    """`_points_official` of many lanes; lanes of the same point count share one `_spline_official_many`."""
    pts = [np.asarray(lane, dtype=np.float64).reshape(-1, 2).astype(np.float32) for lane in lanes]  # Point2f
    out: list[np.ndarray | None] = [p if len(p) == 2 else None for p in pts]
    by_count: dict[int, list[int]] = {}
    for i, p in enumerate(pts):
        if len(p) > 2:
            by_count.setdefault(len(p), []).append(i)
    for count, idx in by_count.items():
        step = max(1, SPLINE_POINTS // ((count - 1) * SPLINE_SAMPLES))  # lanes per batch: bounded memory
        for s in range(0, len(idx), step):
            batch = idx[s : s + step]
            rounded = _round_points(_spline_official_many(np.stack([pts[i] for i in batch])))  # one call per batch
            for i, spline in zip(batch, rounded, strict=True):
                out[i] = spline
    return [_round_points(p) if p is not None and len(p) == 2 else p for p in out]


def _round_points(pts: np.ndarray) -> np.ndarray:
    r = np.rint(pts.astype(np.float64))  # Point2f -> Point: cvRound, round half to even
    # cvRound of NaN or of a value outside int32 gives INT_MIN (x86 "integer indefinite")
    return np.where(np.isfinite(r) & (np.abs(r) < 2**31), r, -(2**31)).astype(np.int64)


def _points_lanedet(lane: np.ndarray, n: int = LANEDET_SAMPLES) -> np.ndarray:
    """lanedet ``interp(points, n=5)`` then ``astype(np.int32)`` (truncation toward zero)."""
    x = [float(v) for v in lane[:, 0]]
    y = [float(v) for v in lane[:, 1]]
    from scipy.interpolate import splev, splprep  # imported here: `stamlane-eval tusimple` never pays for scipy

    try:
        # Same call as lanedet (its t=n is ignored by splprep for task=0; kept for identical behaviour).
        tck, u = splprep([x, y], s=0, t=n, k=min(3, len(x) - 1))
    except (ValueError, TypeError) as e:
        raise ValueError(f"lanedet variant: scipy splprep fails on this lane (duplicate points?): {e}") from None
    u = np.linspace(0.0, 1.0, num=(len(u) - 1) * n + 1)
    points: np.ndarray = np.array(splev(u, tck)).T.astype(np.int32).astype(np.int64)
    return points


# ----------------------------------------------------------------------------------------- rasterisation
@dataclass
class _Mask:
    """A lane drawn into the crop ``[y0:y0+h, x0:x0+w]`` of the image (bool ``(h, w)``)."""

    y0: int
    x0: int
    mask: np.ndarray
    area: int


def _rasterise(
    pts: np.ndarray | None, size: tuple[int, int], width: int, budget: CanvasBudget | None = None
) -> _Mask | None:
    """Draw a polyline as ``cv::line`` calls of thickness ``width`` on a ``size`` = (H, W) image, cropped; each
    canvas counted in ``budget`` before it is allocated."""
    if budget is None:
        budget = CanvasBudget(size)
    if pts is None:
        return None
    import cv2  # here, not at the top: `stamlane-eval tusimple` imports this module but never draws

    h_img, w_img = size
    # Consecutive equal points add nothing: a zero-length cv::line only draws the end cap, already drawn by
    # the previous segment (pixel-identical, and 50 samples per segment repeat points a lot).
    step = pts[1:] != pts[:-1]
    keep = np.ones(len(pts), dtype=bool)
    keep[1:] = step[:, 0] | step[:, 1]
    kept = pts[keep]
    if len(kept):
        (xmin, ymin), (xmax, ymax) = kept.min(0).tolist(), kept.max(0).tolist()
    if len(kept) == 0 or max(-xmin, -ymin, xmax, ymax) > 2**28:  # NaN points (cvRound -> INT_MIN), absurd values
        budget.take(h_img, w_img)
        canvas = np.zeros((h_img, w_img), np.uint8)
        pts32 = np.clip(pts, -(2**31), 2**31 - 1).astype(np.int32)
        cv2.polylines(canvas, [pts32.reshape(-1, 1, 2)], False, 1, thickness=width)
        return _Mask(0, 0, canvas.view(bool), int(np.count_nonzero(canvas)))
    pts = kept if len(kept) >= 2 else pts[[0, 0]]
    margin = width + 2
    x0, y0 = max(int(xmin) - margin, 0), max(int(ymin) - margin, 0)
    x1, y1 = min(int(xmax) + margin + 1, w_img), min(int(ymax) + margin + 1, h_img)
    if x0 >= x1 or y0 >= y1:
        return _Mask(0, 0, np.zeros((0, 0), bool), 0)
    budget.take(y1 - y0, x1 - x0)
    canvas = np.zeros((y1 - y0, x1 - x0), np.uint8)
    # cv2.polylines(open) draws exactly the union of cv::line(p[i], p[i+1]) calls (same caps at the joints).
    local = (pts - np.array([x0, y0])).astype(np.int32).reshape(-1, 1, 2)
    cv2.polylines(canvas, [local], False, 1, thickness=width)
    return _Mask(y0, x0, canvas.view(bool), int(np.count_nonzero(canvas)))


def _iou(a: _Mask | None, b: _Mask | None) -> float:
    """Pixel IoU of two drawn lanes; 0 when either has < 2 points, NaN (0/0) when both are empty."""
    if a is None or b is None:
        return 0.0  # C++ get_lane_similarity: "lane size must be greater or equal to 2" -> 0
    ya, xa = a.y0, a.x0
    yb, xb = b.y0, b.x0
    y0, x0 = max(ya, yb), max(xa, xb)
    y1 = min(ya + a.mask.shape[0], yb + b.mask.shape[0])
    x1 = min(xa + a.mask.shape[1], xb + b.mask.shape[1])
    inter = 0
    if y0 < y1 and x0 < x1:
        inter = int(
            np.count_nonzero(
                a.mask[y0 - ya : y1 - ya, x0 - xa : x1 - xa] & b.mask[y0 - yb : y1 - yb, x0 - xb : x1 - xb]
            )
        )
    union = a.area + b.area - inter
    return inter / union if union > 0 else float("nan")


# --------------------------------------------------------------------------------------------- matching
def _kuhn_munkres_cpp(sim: list[list[float]]) -> list[int]:
    """The C++ tool's ``pipartiteGraph::match`` (maximum weight, 1e-2 tolerance); len(rows) <= len(cols).

    Returns:
        For each row, the matched column or -1. NaN weights never form an edge, as in C++.
    """
    n_l, n_r = len(sim), len(sim[0])
    lw = []
    for row in sim:
        w = -1e5
        for v in row:
            if w < v:
                w = v
        lw.append(w)
    rw = [0.0] * n_r
    left_match = [-1] * n_l
    right_match = [-1] * n_r
    left_used = [False] * n_l
    right_used = [False] * n_r

    def dfs(u: int) -> bool:
        left_used[u] = True
        for v in range(n_r):
            if not right_used[v] and abs(lw[u] + rw[v] - sim[u][v]) < KM_TOLERANCE:
                right_used[v] = True
                if right_match[v] == -1 or dfs(right_match[v]):
                    right_match[v] = u
                    left_match[u] = v
                    return True
        return False

    for u in range(n_l):
        for _ in range(10_000):  # the C++ loops until matched; a cap only guards against pathological input
            left_used[:] = [False] * n_l
            right_used[:] = [False] * n_r
            if dfs(u):
                break
            d = 1e10
            for i in range(n_l):
                if left_used[i]:
                    for j in range(n_r):
                        if not right_used[j]:
                            d = min(d, lw[i] + rw[j] - sim[i][j])  # std::min: NaN never wins
            if d == 1e10:
                return left_match  # quirk: the C++ gives up on ALL remaining rows here
            for i in range(n_l):
                if left_used[i]:
                    lw[i] -= d
            for j in range(n_r):
                if right_used[j]:
                    rw[j] += d
    return left_match


def _match_official(ious: np.ndarray) -> list[tuple[int, int]]:
    """C++ ``Counter::makeMatch`` on similarity[anno][detect]; returns (pred, gt) pairs."""
    sim = ious.T.tolist()  # rows = annotations, as in the C++
    n_gt, n_pred = ious.shape[1], ious.shape[0]
    if n_gt > n_pred:  # the C++ swaps so that the left side is the smaller one
        rows = _kuhn_munkres_cpp(ious.tolist())  # rows = predictions
        return [(p, g) for p, g in enumerate(rows) if g >= 0]
    rows = _kuhn_munkres_cpp(sim)
    return [(p, g) for g, p in enumerate(rows) if p >= 0]


# -------------------------------------------------------------------------------------------- per image
def check_lane(lane: object, i: int, what: str) -> np.ndarray:
    """THE check of one lane's points (CULane, video and temporal metrics): float64 ``(N, 2)`` ``(x, y)``, finite.

    Args:
        lane: the lane's points, ``(N, 2)`` ``(x, y)`` (an empty lane may have any empty shape).
        i: the lane's index in its image (for the message).
        what: ``"predicted"`` or ``"annotated"`` (for the message).

    Returns:
        the points, ``(N, 2)`` float64.

    Raises:
        ValueError: naming the lane, for another shape or a NaN/inf coordinate.
    """
    arr = np.asarray(lane, dtype=np.float64)
    if arr.size == 0:
        arr = arr.reshape(0, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{what} lane {i}: expected an (N, 2) array of (x, y) points, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{what} lane {i}: non-finite coordinate (NaN/inf)")
    return arr


def _check_lanes(lanes: Sequence[np.ndarray], what: str) -> list[np.ndarray]:
    return [check_lane(lane, i, what) for i, lane in enumerate(lanes)]


def evaluate_image(
    preds: Sequence[np.ndarray],
    target: Sequence[np.ndarray],
    iou_thresholds: Sequence[float] = IOU_THRESHOLDS,
    width: int = LANE_WIDTH,
    size: tuple[int, int] = CULANE_SIZE,
    variant: str = "official",
) -> CULaneImageResult:
    """Score one image.

    Args:
        preds: predicted lanes, each ``(N, 2)`` float ``(x, y)`` in original pixels (``N`` may be 0 or 1).
        target: annotated lanes, same form.
        iou_thresholds: TP when the matched IoU is strictly greater.
        width: line thickness in pixels.
        size: image ``(H, W)``; CULane ``(590, 1640)``, ApolloScape ``(2710, 3384)``.
        variant: ``"official"`` (the C++ tool) or ``"lanedet"`` (lanedet's culane_metric).

    Returns:
        Counts per threshold, the IoU matrix and each prediction's matched IoU.

    Raises:
        ValueError: bad lanes, sizes or variant; in the lanedet variant, where lanedet raises (duplicate
            consecutive points, a prediction and an annotation both outside the image).
    """
    return _evaluate_images([preds], [target], iou_thresholds, width, size, variant)[0]


def _evaluate_images(
    preds: Sequence[Sequence[np.ndarray]],
    targets: Sequence[Sequence[np.ndarray]],
    iou_thresholds: Sequence[float],
    width: int,
    size: tuple[int, int],
    variant: str,
    names: Sequence[str] | None = None,
) -> list[CULaneImageResult]:
    """:func:`evaluate_image` of several images; the official variant resamples all their lanes in one batch
    (`_points_official_many`). ``names`` (one per image) prefix the error messages."""
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    size = check_image_size(size)
    if width <= 0:
        raise ValueError(f"width must be a positive number of pixels, got {width!r}")
    thresholds = tuple(float(t) for t in iou_thresholds)
    size = (int(size[0]), int(size[1]))
    width = int(width)
    checked = []
    for i, (p, g) in enumerate(zip(preds, targets, strict=True)):
        try:
            pred, gt = _check_lanes(p, "predicted"), _check_lanes(g, "annotated")
        except ValueError as e:
            raise ValueError(f"{names[i]}: {e}" if names is not None else str(e)) from None
        if variant == "lanedet":
            pred = [lane for lane in pred if len(lane) >= 2]  # load_culane_img_data drops lanes with < 2 points
            gt = [lane for lane in gt if len(lane) >= 2]
        checked.append((pred, gt))
    drawn = [pred + gt if pred and gt else [] for pred, gt in checked]  # early returns draw nothing
    if variant == "official":
        flat = _points_official_many([lane for lanes in drawn for lane in lanes])
        starts = np.cumsum([0] + [len(lanes) for lanes in drawn]).tolist()
        points = [flat[starts[k] : starts[k + 1]] for k in range(len(drawn))]
    out = []
    for k, (pred, gt) in enumerate(checked):
        try:
            pts: list[np.ndarray | None] = (
                points[k] if variant == "official" else [_points_lanedet(lane) for lane in drawn[k]]
            )
            out.append(_score_image(pred, gt, pts, thresholds, width, size, variant))
        except ValueError as e:
            raise ValueError(f"{names[k]}: {e}" if names is not None else str(e)) from None
    return out


def _score_image(
    pred: list[np.ndarray],
    gt: list[np.ndarray],
    points: list[np.ndarray | None],
    thresholds: tuple[float, ...],
    width: int,
    size: tuple[int, int],
    variant: str,
) -> CULaneImageResult:
    """One image from its checked lanes and the polylines to draw (``points``: the predictions', then the
    annotations'; empty when either side has no lane)."""
    n_pred, n_gt = len(pred), len(gt)
    if n_pred == 0 or n_gt == 0:  # both tools return early: everything is FP or FN
        return CULaneImageResult(
            {t: (0, n_pred, n_gt) for t in thresholds},
            np.zeros((n_pred, n_gt)),
            np.zeros(n_pred),
            n_pred,
            n_gt,
            np.full(n_pred, -1, dtype=np.int64),
        )
    budget = CanvasBudget(size)  # io.MAX_DRAWN_PIXELS, each canvas counted before it is allocated
    masks = [_rasterise(pts, size, width, budget) for pts in points]
    pm, gm = masks[:n_pred], masks[n_pred:]
    ious = np.array([[_iou(a, b) for b in gm] for a in pm], dtype=np.float64)  # (n_pred, n_gt)
    if variant == "official":
        pairs = _match_official(ious)
    else:
        if np.isnan(ious).any():
            raise ValueError(
                "lanedet variant: a prediction and an annotation both lie outside the image (IoU 0/0); "
                "lanedet's linear_sum_assignment raises here"
            )
        from scipy.optimize import linear_sum_assignment  # only the lanedet variant needs it

        rows, cols = linear_sum_assignment(1 - ious)
        pairs = list(zip(rows.tolist(), cols.tolist(), strict=True))
    matched_iou = np.zeros(n_pred)
    pred_to_gt = np.full(n_pred, -1, dtype=np.int64)
    for p, g in pairs:
        matched_iou[p] = ious[p, g]
        pred_to_gt[p] = g
    counts = {}
    for t in thresholds:
        tp = sum(1 for p, g in pairs if ious[p, g] > t)  # strict; NaN is never > t
        counts[t] = (tp, n_pred - tp, n_gt - tp)
    return CULaneImageResult(counts, ious, np.nan_to_num(matched_iou, nan=0.0), n_pred, n_gt, pred_to_gt)


def aggregate(per_image: Sequence[CULaneImageResult], iou_thresholds: Sequence[float] = IOU_THRESHOLDS) -> CULaneResult:
    """Sum TP/FP/FN over images and derive P, R, F1 per threshold (0 where a denominator is 0), with the helpers
    the torchmetrics class uses (``stamlane_eval.aggregate``)."""
    thresholds = [float(t) for t in iou_thresholds]
    sums = count_update([(0, 0, 0)] * len(thresholds), (r.counts for r in per_image), thresholds)
    totals = {t: counts_to_prf(*c) for t, c in zip(thresholds, sums, strict=True)}
    return CULaneResult(totals, len(per_image), list(per_image))


def counts_to_prf(tp: int, fp: int, fn: int) -> CULaneCounts:
    """:class:`CULaneCounts` from summed counts (``stamlane_eval.aggregate.prf``: lanedet's formulas)."""
    return CULaneCounts(int(tp), int(fp), int(fn), *prf(tp, fp, fn))


def _batches(preds: Sequence[Sequence[np.ndarray]], targets: Sequence[Sequence[np.ndarray]]) -> Iterator[slice]:
    """Consecutive images resampled together: at most ``BATCH_IMAGES``, and at most ``BATCH_POINTS`` points
    unless one image alone holds more (memory; a batch changes no number)."""
    start = points = 0
    for i, (p, g) in enumerate(zip(preds, targets, strict=True)):
        n = sum(map(len, p)) + sum(map(len, g))
        if i > start and (i - start >= BATCH_IMAGES or points + n > BATCH_POINTS):
            yield slice(start, i)
            start, points = i, 0
        points += n
    if start < len(preds):
        yield slice(start, len(preds))


def evaluate(
    preds: Sequence[Sequence[np.ndarray]],
    targets: Sequence[Sequence[np.ndarray]],
    iou_thresholds: Sequence[float] = IOU_THRESHOLDS,
    width: int = LANE_WIDTH,
    size: tuple[int, int] = CULANE_SIZE,
    variant: str = "official",
    progress: bool = False,
    names: Sequence[str] | None = None,
) -> CULaneResult:
    """Score a dataset: :func:`evaluate_image` per image, then :func:`aggregate`.

    Args:
        preds: per image, the predicted lanes (``(N, 2)`` arrays).
        targets: per image, the annotated lanes.
        iou_thresholds, width, size, variant: as :func:`evaluate_image`.
        progress: show a tqdm progress bar (when tqdm is installed).
        names: per image, a name for error messages (e.g. the list entry).

    Returns:
        Totals per threshold and per-image results.
    """
    if len(preds) != len(targets):
        raise ValueError(f"got {len(preds)} prediction images and {len(targets)} annotated images")
    names = list(names) if names is not None else [f"image {i}" for i in range(len(preds))]
    bar = progress_bar(progress, len(preds), "culane", "img")
    per_image = []
    for chunk in _batches(preds, targets):
        per_image += _evaluate_images(preds[chunk], targets[chunk], iou_thresholds, width, size, variant, names[chunk])
        if bar is not None:
            bar.update(len(per_image) - bar.n)
    if bar is not None:
        bar.close()
    return aggregate(per_image, iou_thresholds)
