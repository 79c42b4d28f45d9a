"""Temporal stability of lane detection (Ns, Nj, Nm and Rs, Rj, Rm), number for number as RVLD's script.

Reference: dongkwonjin/RVLD @ 294075d5, ``Modeling/VIL-100/PLD/code/evaluation/evaluate_temporal.py``
(``LaneEval_Temporal``; protocol ``"vil100"``) and its OpenLane-V copy
``Modeling/OpenLane-V/PLD/code/evaluation/evaluate_temporal.py`` (protocol ``"openlane-v"``): the script RVLD
(ICCV 2023), OMR, LaneTCA and PHNet report temporal stability with.

For each pair of consecutive frames (t-1, t) of a sequence:

1. the annotated lanes of t and of t-1 are matched to each other: both drawn 30 px wide, IoU, Hungarian
   (``scipy.optimize.linear_sum_assignment``), pairs with IoU > 0.5 kept;
2. for each kept pair, ``iou1`` is the IoU of the annotated lane at t with the prediction assigned to it by
   that frame's own Hungarian matching of annotations to predictions (0 when none is assigned), ``iou2`` the
   same at t-1;
3. with the threshold T: **Jump** when one of them is above T and the other below, else **Missing** when both
   are below, else **Stable** (both above, or either exactly T: the script tests ``>`` and ``<`` only).

``Ns``, ``Nj``, ``Nm`` are summed over every pair of every sequence; ``Rs = Ns / (Ns + Nj + Nm)`` and so on.
Every quirk of the script is kept and commented where it happens. Lanes are ``(N, 2)`` float arrays of ``(x, y)``
points in original-image pixels (OpenLane-V: pixels of its 1920x1280 frames).

Speed: each lane is fitted and drawn once per frame (OpenCV itself, as in :mod:`stamlane_eval.culane`, in a
canvas cropped to the lane, pixel-identical to the script's full-image drawing), the annotations reused for
the next pair; an intersection is counted only where two crops overlap, instead of on two full (H, W, 3)
masks per pair.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from stamlane_eval._long_runs import map_sequences
from stamlane_eval.aggregate import count_update, stability_rates
from stamlane_eval.culane import check_lane
from stamlane_eval.io.limits import CanvasBudget, check_image_size
from stamlane_eval.video import Frame

__all__ = [
    "ANNO_MATCH_IOU",
    "CHANNELS",
    "INT32_LIMIT",
    "IOU_EPS",
    "LANE_WIDTH",
    "OPENLANE_V_EVAL_SIZE",
    "OPENLANE_V_SIZE",
    "PROTOCOLS",
    "SPLINE_SAMPLES",
    "TEMPORAL_IOU_THRESHOLDS",
    "StabilityCounts",
    "TemporalFrame",
    "TemporalResult",
    "TemporalSequenceResult",
    "evaluate",
    "evaluate_frame",
    "evaluate_pair",
    "evaluate_sequence",
    "stability_counts",
]

PROTOCOLS = ("vil100", "openlane-v")
TEMPORAL_IOU_THRESHOLDS = (0.5, 0.8)  # the thresholds RVLD and the papers after it report Rs/Rj/Rm at
LANE_WIDTH = 30  # px: settings() lane_width = 30 and matching_lane_instance(width=30)
ANNO_MATCH_IOU = 0.5  # matching_lane_instance(iou_threshold=0.5): annotated lanes of t-1 and t pair above it
SPLINE_SAMPLES = 5  # interp(points, n=5): (m - 1) * 5 + 1 samples of the spline, m = the lane's unique points
IOU_EPS = 1e-10  # discrete_cross_iou: (x & y).sum() / ((x | y).sum() + eps)
CHANNELS = 3  # the lanes are drawn on (H, W, 3) images: every pixel is counted three times in the IoU
OPENLANE_V_SIZE = (1280, 1920)  # (H, W) of OpenLane-V frames: the pixels its labels and predictions are in
OPENLANE_V_EVAL_SIZE = (1280 // 2, 1920 // 2)  # config.py: eval_h, eval_w = org_height // 2, org_width // 2
INT32_LIMIT = 2.0**31  # draw_lane: lane.astype(np.int32); a spline sample must fit


# ------------------------------------------------------------------------------------------------ results
@dataclass(frozen=True)
class StabilityCounts:
    """Ns, Nj, Nm at one threshold and the ratios (NaN when no pair was counted: the script divides by 0)."""

    ns: int
    nj: int
    nm: int

    @property
    def total(self) -> int:
        return self.ns + self.nj + self.nm

    @property
    def rs(self) -> float:
        return stability_rates(self.ns, self.nj, self.nm)[0]

    @property
    def rj(self) -> float:
        return stability_rates(self.ns, self.nj, self.nm)[1]

    @property
    def rm(self) -> float:
        return stability_rates(self.ns, self.nj, self.nm)[2]

    def __add__(self, other: StabilityCounts) -> StabilityCounts:
        return StabilityCounts(self.ns + other.ns, self.nj + other.nj, self.nm + other.nm)

    def as_dict(self) -> dict[str, float | int | None]:
        """``{"Ns", "Nj", "Nm", "Rs", "Rj", "Rm"}`` as the script names them; an undefined ratio is None."""
        out: dict[str, float | int | None] = {"Ns": self.ns, "Nj": self.nj, "Nm": self.nm}
        for name, value in (("Rs", self.rs), ("Rj", self.rj), ("Rm", self.rm)):
            out[name] = None if math.isnan(value) else value
        return out


@dataclass(frozen=True)
class TemporalSequenceResult:
    """One sequence: counts per threshold, and per pair of consecutive frames (frame 1 onwards)."""

    name: str
    frames: int
    counts: dict[float, StabilityCounts]
    per_pair: list[dict[float, tuple[int, int, int]]] = field(default_factory=list, repr=False)

    @property
    def pairs(self) -> int:
        return max(self.frames - 1, 0)

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"sequence": self.name, "frames": self.frames, "pairs": self.pairs}
        out.update({str(t): c.as_dict() for t, c in self.counts.items()})
        return out


@dataclass(frozen=True)
class TemporalResult:
    """Dataset counts per threshold (summed over sequences) and the per-sequence results."""

    totals: dict[float, StabilityCounts]
    sequences: int
    frames: int
    protocol: str
    per_sequence: list[TemporalSequenceResult] = field(default_factory=list, repr=False)

    @property
    def pairs(self) -> int:
        return sum(s.pairs for s in self.per_sequence)

    def as_dict(self) -> dict[str, object]:
        """``{"0.5": {"Ns", "Nj", "Nm", "Rs", "Rj", "Rm"}, "0.8": {...}, "sequences", "frames", "pairs", ...}``."""
        out: dict[str, object] = {str(t): c.as_dict() for t, c in self.totals.items()}
        out.update(sequences=self.sequences, frames=self.frames, pairs=self.pairs, protocol=self.protocol)
        return out


# ------------------------------------------------------------------------------------------ lane points
def _check_protocol(protocol: str) -> None:
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol must be one of {PROTOCOLS}, got {protocol!r}")


def _unique_points(lane: np.ndarray, protocol: str, i: int, what: str) -> list[tuple[float, float]] | None:
    """The points of one lane as the script interpolates them, or None for a lane it drops."""
    arr = check_lane(lane, i, what)
    # a lane far outside the image, annotated or predicted (x = 150,000), is scored as the script scores it: drawn
    # clipped, nothing of it on the image, up to the int32 range of its drawing (_spline)
    if protocol == "openlane-v":
        # load_culane_img_data / load_gt_data: 1920x1280 pixels to the 960x640 canvas, in this operation order
        arr = arr.copy()
        arr[:, 0] = arr[:, 0] / (OPENLANE_V_SIZE[1] - 1) * (OPENLANE_V_SIZE[1] // 2 - 1)
        arr[:, 1] = arr[:, 1] / (OPENLANE_V_SIZE[0] - 1) * (OPENLANE_V_SIZE[0] // 2 - 1)
    if len(arr) < 2:
        return None  # load_culane_img_data: [lane for lane in img_data if len(lane) >= 2], before de-duplication
    # interp(list(dict.fromkeys(lane)), n=5): repeated points dropped wherever they occur (not only consecutive
    # ones), the first occurrence kept in place; (x, y) tuples of Python floats, so -0.0 == 0.0
    return list(dict.fromkeys(map(tuple, arr.tolist())))


def _frame_lanes(lanes: Sequence[np.ndarray], protocol: str, what: str) -> list[list[tuple[float, float]]]:
    out = []
    for i, lane in enumerate(lanes):
        pts = _unique_points(lane, protocol, i, what)
        if pts is not None:
            out.append(pts)
    return out


def _spline(pts: list[tuple[float, float]]) -> np.ndarray | None:
    """``interp(pts, n=5)`` then ``astype(np.int32)``: the integer polyline the script draws; None where the
    script's ``splprep`` raises (all points one point: ``k = min(3, m - 1) = 0``, a TypeError)."""
    if len(pts) < 2:
        return None
    from scipy.interpolate import splev, splprep  # imported here: only this metric and lanedet's need scipy

    x = [p[0] for p in pts]
    y = [p[1] for p in pts]
    # The call of interp(): s = 0 interpolates the points (chord-length parameter, knots chosen by FITPACK);
    # t=n is passed as the knot vector, which splprep ignores for task = 0; k = min(3, m - 1).
    tck, u = splprep([x, y], s=0, t=SPLINE_SAMPLES, k=min(3, len(pts) - 1))
    # (len(u) - 1) * n + 1 samples evenly spread over the parameter [0, 1], not per point interval
    samples: np.ndarray = np.array(splev(np.linspace(0.0, 1.0, num=(len(u) - 1) * SPLINE_SAMPLES + 1), tck)).T
    if not (np.abs(samples) < INT32_LIMIT).all():
        # beyond int32 the script's truncation depends on whether the frame's lanes have equal lengths (an object
        # array of floats then raises OverflowError, a float array wraps): no single number to reproduce
        raise ValueError(
            f"a lane's spline reaches beyond +-{INT32_LIMIT:g} px (int32, which RVLD's script draws with); its "
            f"result there depends on the other lanes of the frame"
        )
    # draw_lane: lane.astype(np.int32), truncation toward zero (the script's object arrays convert the same way)
    return samples.astype(np.int32)


def _one_point_error(what: str, k: int) -> ValueError:
    return ValueError(
        f"{what} lane {k} (of those with >= 2 points) has all its points at one place; RVLD's script fails on it "
        f"(its splprep gets k = 0 and raises TypeError)"
    )


def _splines(lanes: list[list[tuple[float, float]]], what: str) -> list[np.ndarray]:
    out = []
    for k, pts in enumerate(lanes):
        spline = _spline(pts)
        if spline is None:
            raise _one_point_error(what, k)
        out.append(spline)
    return out


# ---------------------------------------------------------------------------------------- rasterisation
@dataclass(slots=True)
class _Drawn:
    """A lane drawn ``LANE_WIDTH`` wide on an image, kept as the crop ``[y0:y0+h, x0:x0+w]`` that holds it
    (``mask``: uint8, 1 where drawn) and its pixel count."""

    y0: int
    x0: int
    mask: np.ndarray = field(repr=False)
    area: int


_EMPTY = _Drawn(0, 0, np.zeros((0, 0), np.uint8), 0)
_FAR = 2**28  # px: beyond this a crop is not worth it (OpenCV's own clipping then decides, as in the script)


def _draw(pts: np.ndarray, size: tuple[int, int], budget: CanvasBudget | None = None) -> _Drawn:
    """``draw_lane``: ``cv2.line`` of thickness 30 between consecutive points, here into a cropped canvas.

    ``pts``: the ``(N >= 2, 2)`` int32 polyline. The drawing is translation invariant, so the crop holds the
    pixels of the script's full image. Repeated points are drawn as they come: a zero-length segment draws
    only the round cap its neighbour draws anyway, the same pixels (test_temporal checks against draw_lane).
    The canvas is never larger than the image, whatever the coordinates (a lane at x = 150,000 is drawn
    nowhere, as the script's clipped drawing), and is counted in ``budget`` before it is allocated.
    """
    import cv2  # here, not at the top: `stamlane-eval tusimple` imports the command line, which imports this

    if budget is None:
        budget = CanvasBudget(size)

    h_img, w_img = size
    xmin, ymin, w, h = cv2.boundingRect(pts)  # one C call: min/max of both columns
    # Nothing of a 30-px line reaches beyond 15 px of its points (corners at +-15 px, caps of radius 15): a
    # canvas 17 px larger on each side never clips a drawing primitive, so no pixel moves (translation invariance)
    margin = LANE_WIDTH // 2 + 2
    if max(-xmin, -ymin, xmin + w - 1, ymin + h - 1) > _FAR:
        x0, y0, x1, y1 = 0, 0, w_img, h_img  # absurd points: draw on the whole image as the script does
    else:
        x0, y0 = max(xmin - margin, 0), max(ymin - margin, 0)
        x1, y1 = min(xmin + w + margin, w_img), min(ymin + h + margin, h_img)
    if x0 >= x1 or y0 >= y1:
        return _EMPTY  # entirely outside the image
    budget.take(y1 - y0, x1 - x0)
    canvas = np.zeros((y1 - y0, x1 - x0), np.uint8)
    local = pts - np.array([x0, y0], dtype=pts.dtype) if x0 or y0 else pts
    # cv2.polylines(open) draws exactly the union of the cv2.line calls of draw_lane (same caps at the joints)
    cv2.polylines(canvas, [local.reshape(-1, 1, 2)], False, 1, thickness=LANE_WIDTH)
    return _Drawn(y0, x0, canvas, cv2.countNonZero(canvas))


def _inter(a: _Drawn, b: _Drawn) -> int:
    """Pixels two drawn lanes share (counted where their crops overlap)."""
    y0, x0 = max(a.y0, b.y0), max(a.x0, b.x0)
    y1 = min(a.y0 + a.mask.shape[0], b.y0 + b.mask.shape[0])
    x1 = min(a.x0 + a.mask.shape[1], b.x0 + b.mask.shape[1])
    if y0 >= y1 or x0 >= x1:
        return 0
    ma = a.mask[y0 - a.y0 : y1 - a.y0, x0 - a.x0 : x1 - a.x0]
    mb = b.mask[y0 - b.y0 : y1 - b.y0, x0 - b.x0 : x1 - b.x0]
    import cv2  # see _draw

    return cv2.countNonZero(cv2.bitwise_and(ma, mb))


def _iou_matrix(rows: Sequence[_Drawn], cols: Sequence[_Drawn]) -> np.ndarray:
    """``discrete_cross_iou(rows, cols)``: (x & y).sum() / ((x | y).sum() + eps) over (H, W, 3) masks."""
    ious = np.zeros((len(rows), len(cols)))
    for i, a in enumerate(rows):
        for j, b in enumerate(cols):
            inter = _inter(a, b)
            union = a.area + b.area - inter
            # both sums count each pixel CHANNELS times; eps makes two lanes outside the image IoU 0 (not 0/0)
            ious[i, j] = (CHANNELS * inter) / (CHANNELS * union + IOU_EPS)
    return ious


def _assign(ious: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``linear_sum_assignment(1 - ious)`` exactly as the script calls it (same matrix, same tie-breaking)."""
    from scipy.optimize import linear_sum_assignment

    rows, cols = linear_sum_assignment(1 - ious)
    return rows, cols


# ------------------------------------------------------------------------------------------- per frame
@dataclass(frozen=True)
class TemporalFrame:
    """What the pairs need of one frame.

    Attributes:
        size: ``(H, W)`` of the canvas the frame's lanes are drawn on.
        anno_points: the annotated lanes the script keeps (>= 2 points), as the integer polylines it draws;
            None for a lane whose points are all one point (the script fails when it interpolates it).
        anno_drawn: the same lanes drawn at ``size`` (None where ``anno_points`` is None).
        anno_iou: ``(n_anno,)`` IoU of each kept annotated lane with the prediction the frame's Hungarian
            matching assigns it, 0.0 when none (no prediction, or more annotations than predictions).
    """

    size: tuple[int, int]
    anno_points: list[np.ndarray | None] = field(repr=False)
    anno_drawn: list[_Drawn | None] = field(repr=False)
    anno_iou: np.ndarray


def _canvas_size(size: tuple[int, int] | None, protocol: str) -> tuple[int, int]:
    if protocol == "openlane-v":
        if size is not None and tuple(size) != OPENLANE_V_SIZE:
            raise ValueError(
                f"the openlane-v protocol takes lanes in OpenLane-V's {OPENLANE_V_SIZE[1]}x{OPENLANE_V_SIZE[0]} "
                f"pixels and draws them at {OPENLANE_V_EVAL_SIZE[1]}x{OPENLANE_V_EVAL_SIZE[0]}; got size {size!r}"
            )
        return OPENLANE_V_EVAL_SIZE
    if size is None:
        raise ValueError("size must be the image (H, W), got None")
    return check_image_size(size)  # the one check of the sizes canvases are made for


def evaluate_frame(
    preds: Sequence[np.ndarray],
    target: Sequence[np.ndarray],
    size: tuple[int, int] | None,
    protocol: str = "vil100",
) -> TemporalFrame:
    """Score one frame: the Hungarian matching of its annotated lanes to its predictions (``culane_metric2``).

    Args:
        preds: predicted lanes, each ``(N, 2)`` ``(x, y)`` in original pixels.
        target: annotated lanes, same form.
        size: image ``(H, W)`` (vil100: each frame's own size, as RVLD's ``shape_list``); openlane-v: None.
        protocol: ``"vil100"`` or ``"openlane-v"``.

    Returns:
        The frame's drawn annotations and their matched IoUs.

    Raises:
        ValueError: bad lanes, size or protocol; a lane whose points are all one point where the script
            interpolates it (here: in a frame with both predictions and annotations).
    """
    _check_protocol(protocol)
    canvas = _canvas_size(size, protocol)
    pred_unique = _frame_lanes(preds, protocol, "predicted")
    anno_unique = _frame_lanes(target, protocol, "annotated")
    anno_iou = np.zeros(len(anno_unique))
    budget = CanvasBudget(canvas)  # the frame's canvases, as the CULane metric counts an image's
    if not pred_unique or not anno_unique:
        # culane_metric2 returns [], [], [] before interpolating anything: every annotation's IoU is 0, and a
        # one-point lane fails only when a pair of frames interpolates the annotations (evaluate_pair)
        anno_pts = [_spline(p) for p in anno_unique]
        anno_drawn = [None if p is None else _draw(p, canvas, budget) for p in anno_pts]
        return TemporalFrame(canvas, anno_pts, anno_drawn, anno_iou)
    pred_drawn = [_draw(p, canvas, budget) for p in _splines(pred_unique, "predicted")]
    kept_pts = _splines(anno_unique, "annotated")
    kept_drawn = [_draw(p, canvas, budget) for p in kept_pts]
    ious = _iou_matrix(kept_drawn, pred_drawn)  # rows: annotations, columns: predictions, as the script
    rows, cols = _assign(ious)
    anno_iou[rows] = ious[rows, cols]
    return TemporalFrame(canvas, list(kept_pts), list(kept_drawn), anno_iou)


def stability_counts(iou1: float, iou2: float, threshold: float) -> tuple[int, int, int]:
    """``metric_per_inter_frame`` for one matched annotated lane: ``(1, 0, 0)`` Stable, ``(0, 1, 0)`` Jump,
    ``(0, 0, 1)`` Missing, with ``iou1`` at t and ``iou2`` at t-1."""
    if (iou1 > threshold and iou2 < threshold) or (iou1 < threshold and iou2 > threshold):
        return 0, 1, 0
    if iou1 < threshold and iou2 < threshold:
        return 0, 0, 1
    return 1, 0, 0  # the script's else: both above, or either exactly at the threshold


def evaluate_pair(
    prev: TemporalFrame, cur: TemporalFrame, iou_thresholds: Sequence[float] = TEMPORAL_IOU_THRESHOLDS
) -> dict[float, tuple[int, int, int]]:
    """Count one pair of consecutive frames (``matching_lane_instance`` + ``metric_per_inter_frame``).

    Args:
        prev: frame t-1.
        cur: frame t.
        iou_thresholds: thresholds T of Stable / Jump / Missing.

    Returns:
        threshold -> ``(Ns, Nj, Nm)`` of this pair.
    """
    thresholds = tuple(float(t) for t in iou_thresholds)
    out = {t: (0, 0, 0) for t in thresholds}
    # matching_lane_instance interpolates every annotated lane of both frames, even when the other has none
    for frame, when in ((cur, "t"), (prev, "t-1")):
        if any(p is None for p in frame.anno_points):
            k = next(k for k, p in enumerate(frame.anno_points) if p is None)
            raise ValueError(f"at {when}: {_one_point_error('annotated', k)}")
    if not cur.anno_drawn or not prev.anno_drawn:
        return out
    # no lane is None past the check above (anno_drawn is None exactly where anno_points is): the filters narrow
    cur_drawn = [d for d in cur.anno_drawn if d is not None]
    # The annotations of t-1 are drawn on frame t's shape (self.shape = img_shape[idx] of the current frame).
    if prev.size == cur.size:
        prev_drawn = [d for d in prev.anno_drawn if d is not None]
    else:
        budget = CanvasBudget(cur.size)
        prev_drawn = [_draw(p, cur.size, budget) for p in prev.anno_points if p is not None]
    ious = _iou_matrix(cur_drawn, prev_drawn)  # rows: annotations at t (ref), columns: at t-1 (tgt)
    rows, cols = _assign(ious)
    kept = ious[rows, cols] > ANNO_MATCH_IOU
    for t in thresholds:
        ns = nj = nm = 0
        for i, j in zip(rows[kept].tolist(), cols[kept].tolist(), strict=True):
            s, jump, miss = stability_counts(float(cur.anno_iou[i]), float(prev.anno_iou[j]), t)
            ns, nj, nm = ns + s, nj + jump, nm + miss
        out[t] = (ns, nj, nm)
    return out


# ------------------------------------------------------------------------------------ sequences, dataset
def evaluate_sequence(
    frames: Sequence[Frame],
    name: str = "",
    iou_thresholds: Sequence[float] = TEMPORAL_IOU_THRESHOLDS,
    size: tuple[int, int] | None = None,
    protocol: str = "vil100",
) -> TemporalSequenceResult:
    """Score one sequence of consecutive frames (the first frame opens the sequence: it has no pair).

    Args:
        frames: the frames in time order (:class:`stamlane_eval.video.Frame`; ``pred_ids`` / ``target_ids``
            are not used).
        name: the sequence's name (for results and messages).
        iou_thresholds: thresholds T of Stable / Jump / Missing.
        size: image ``(H, W)`` of frames that do not give their own (vil100); None for openlane-v.
        protocol: ``"vil100"`` or ``"openlane-v"``.

    Returns:
        Counts per threshold and per pair.
    """
    thresholds = tuple(float(t) for t in iou_thresholds)
    per_pair: list[dict[float, tuple[int, int, int]]] = []
    prev = None
    for i, fr in enumerate(frames):
        try:
            cur = evaluate_frame(fr.preds, fr.target, fr.size or size, protocol)
            counts = None if prev is None else evaluate_pair(prev, cur, thresholds)
        except ValueError as e:
            raise ValueError(f"{name} frame {i}: {e}" if name else f"frame {i}: {e}") from None
        if counts is not None:
            per_pair.append(counts)
        prev = cur
    return TemporalSequenceResult(name, len(frames), _totals(per_pair, thresholds), per_pair)


def evaluate(
    sequences: Mapping[str, Sequence[Frame]],
    iou_thresholds: Sequence[float] = TEMPORAL_IOU_THRESHOLDS,
    size: tuple[int, int] | None = None,
    protocol: str = "vil100",
    progress: bool = False,
    jobs: int = 1,
) -> TemporalResult:
    """Score sequences and sum their counts (``total_ns``, ... of the script).

    Args:
        sequences: name -> frames in time order.
        iou_thresholds, size, protocol: as :func:`evaluate_sequence`.
        progress: show a tqdm progress bar over the frames (when tqdm is installed).
        jobs: worker processes the sequences are spread over (1: this process; 0: one per core); the numbers
            do not depend on it.

    Returns:
        Dataset counts and ratios per threshold, and the per-sequence results (in the mapping's order).
    """
    _check_protocol(protocol)
    if not sequences:
        raise ValueError("no sequence to evaluate")
    thresholds = tuple(float(t) for t in iou_thresholds)
    score = functools.partial(evaluate_sequence, iou_thresholds=thresholds, size=size, protocol=protocol)
    per = map_sequences(score, sequences, jobs, progress, "temporal")
    pairs = [c for s in per for c in s.per_pair]  # the script's total_ns, ...: every pair of every sequence
    return TemporalResult(_totals(pairs, thresholds), len(per), sum(s.frames for s in per), protocol, per)


def _totals(
    per_pair: Sequence[dict[float, tuple[int, int, int]]], thresholds: Sequence[float]
) -> dict[float, StabilityCounts]:
    """Ns, Nj, Nm per threshold, summed over pairs of frames (`stamlane_eval.aggregate.count_update`)."""
    sums = count_update([(0, 0, 0)] * len(thresholds), per_pair, thresholds)
    return {t: StabilityCounts(*c) for t, c in zip(thresholds, sums, strict=True)}
