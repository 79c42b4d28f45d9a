"""Decode the two network heads into lanes: DBSCAN on pixel embeddings, then a robust curve per cluster.

docs/method.md §5 (paper 3.4). numpy in, numpy out; called from ``StamLaneModule`` steps, never inside a
``forward``. Steps, per image:

1. lane pixels = pixels whose lane probability > ``prob_thresh`` (paper: 0.5);
2. at most ``max_points`` of the CONFIDENT ones (probability > ``cluster_thresh``, default
   ``prob_thresh``; a fixed-seed random subset, so the result is deterministic) are clustered with
   sklearn DBSCAN in embedding space (``eps`` of the order of the loss's ``delta_v``). The embedding
   loss never sees background pixels, so the uncertain rim the class-weighted cross-entropy adds
   around lanes carries arbitrary embeddings that can bridge two lanes' clusters; a higher
   ``cluster_thresh`` keeps it out of the clustering (it is still assigned in step 3). Where fewer than
   ``min_samples`` pixels are that confident (a weakly trained network whose lane probabilities top out
   below ``cluster_thresh``), every lane pixel is clustered, as in the paper, rather than no lane reported;
   clustering every pixel is what makes LaneNet's post-processing slow (docs/method.md, docs/training.md);
3. every lane pixel is assigned to the nearest cluster centre (mean embedding of the cluster), pixels
   farther than ``assign_radius`` from every centre are dropped as noise;
4. clusters with fewer than ``min_cluster_pixels`` pixels are dropped;
5. the cluster's pixels are mapped to ORIGINAL-image pixels with ``orig_from_net`` (inverse of the
   sample's ``net_from_orig``), one x (the median) is taken per ``y_step``-pixel band of original rows,
   a polynomial x = f(y) of degree ``degree`` is fitted to those points with iterative outlier
   rejection (points farther than ``max(outlier_px, 3 * MAD)`` from the curve are dropped and the curve
   refitted), and the curve is sampled every ``y_step`` original pixels (or at the given ``y_samples``,
   e.g. TuSimple ``h_samples``) inside the rows the cluster covers.

The counts in network pixels (``min_cluster_pixels``, and ``min_samples``, a count of the subsample) are given at
the network input ``reference_size`` (the 80x256 every shipped model was trained at, where they were chosen) and
scaled to the lane map's own size (`PostprocessConfig.pixel_scale`): a lane covers ``s`` times the pixels on a map of
``s`` times the area. At 80x256 nothing changes. ``max_points`` is a bound on DBSCAN's work, not a size, and is never
scaled; ``y_step`` and ``outlier_px`` are original-image pixels (the label format's rows), which the input size does
not change.

Lanes come out left to right (by x at their lowest row), as ``(N, 2)`` float arrays of ``(x, y)`` in
original-image pixels (``stamlane.types``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from sklearn.cluster import DBSCAN
from sklearn.neighbors import BallTree

try:  # DBSCAN's cluster expansion (private; the estimator is used where it is gone)
    from sklearn.cluster._dbscan_inner import dbscan_inner as _dbscan_inner
except ImportError:  # pragma: no cover
    _dbscan_inner = None

from stamlane.types import Lanes

REFERENCE_SIZE = (80, 256)
"""Network input ``(H, W)`` the default pixel counts were chosen at: the shipped models' (docs/models.md)."""

__all__ = [
    "REFERENCE_SIZE",
    "LaneCurve",
    "PostprocessConfig",
    "cluster_lane_pixels",
    "dbscan",
    "decode_lanes",
    "fit_curve",
    "fit_lane",
    "sample_curve",
    "sample_lanes",
]


@dataclass(frozen=True)
class PostprocessConfig:
    """Options of :func:`decode_lanes`.

    Args:
        prob_thresh: a pixel is a lane pixel when its lane probability is above this (paper: 0.5).
        cluster_thresh: only lane pixels above this probability go into DBSCAN (``None``: ``prob_thresh``;
            every lane pixel where fewer than ``min_samples`` are above it).
            Measured on the synthetic validation clips (4-frame demo model): 0.9 instead of 0.5 raised
            TuSimple accuracy from 0.56 to 0.86 and the paper's F1 from 0.52 to 0.78.
        eps: DBSCAN neighbourhood radius in embedding units (the loss pulls pixels to within
            ``delta_v`` = 0.5 of their lane's mean and pushes means ``2 * delta_d`` = 3 apart); 0.35 as
            LaneNet's reference implementation.
        min_samples: DBSCAN core-point count, measured on the subsample (25 of <= 2000 points: a thin
            bridge of stray pixels between two lanes does not join them); given for the subsample a map of
            ``reference_size`` draws (`core_samples`).
        max_points: at most this many lane pixels go into DBSCAN; the rest are assigned afterwards. A bound on the
            work, never scaled.
        assign_radius: a pixel farther than this (embedding units) from every cluster centre is noise.
        min_cluster_pixels: clusters with fewer lane pixels (network resolution) are dropped; given at
            ``reference_size`` (`min_pixels`).
        y_step: original-image pixels between the rows x is sampled at (paper: 10).
        degree: polynomial degree of x = f(y); lowered when a cluster covers too few rows.
        outlier_px: residual (original pixels) below which a point is never an outlier.
        max_lanes: keep at most this many lanes (the largest clusters).
        seed: seed of the subsample, so decoding is deterministic.
        extend: sample every lane from the image's common far end (the highest row any of its lanes reaches)
            down to the image bottom (the last of ``y_samples``), continuing each curve along its end tangent
            beyond the rows its pixels cover. Lane labels (TuSimple, CULane, the synthetic sets) run through
            vehicles up to a far limit shared by all lanes; a lane whose far part hides behind a vehicle
            otherwise ends early and misses the 85 % of points a TuSimple match needs. On the synthetic test
            clips a detector of the VISIBLE paint scores F1 0.65 without this and 0.84 with it.
        reference_size: the network input ``(H, W)`` that ``min_cluster_pixels`` and ``min_samples`` are given at
            (`REFERENCE_SIZE`, where the defaults were chosen); on a lane map of another size they are scaled by
            the ratio of the areas (`pixel_scale`). ``None``: used as given at any size.
    """

    prob_thresh: float = 0.5
    cluster_thresh: float | None = 0.9
    eps: float = 0.35
    min_samples: int = 25
    max_points: int = 2000
    assign_radius: float = 1.5
    min_cluster_pixels: int = 50
    y_step: int = 10
    degree: int = 2
    outlier_px: float = 10.0
    max_lanes: int = 8
    seed: int = 0
    extend: bool = False
    reference_size: tuple[int, int] | None = REFERENCE_SIZE

    def __post_init__(self) -> None:
        if self.reference_size is not None:
            size = tuple(self.reference_size)  # a run's config or a model's metadata gives a list
            if len(size) != 2 or not all(
                isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 1 for v in size
            ):
                raise ValueError(f"reference_size must be (H, W), two ints >= 1, or None, got {self.reference_size!r}")
            object.__setattr__(self, "reference_size", (int(size[0]), int(size[1])))
        if not 0.0 <= self.prob_thresh < 1.0:
            raise ValueError(f"prob_thresh must be in [0, 1), got {self.prob_thresh}")
        if self.cluster_thresh is not None and not self.prob_thresh <= self.cluster_thresh < 1.0:
            raise ValueError(f"cluster_thresh must be in [prob_thresh, 1), got {self.cluster_thresh}")
        for name in ("eps", "assign_radius", "outlier_px"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("min_samples", "max_points", "min_cluster_pixels", "y_step", "max_lanes"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.degree < 1:
            raise ValueError(f"degree must be >= 1, got {self.degree}")

    def pixel_scale(self, size: tuple[int, int]) -> float:
        """Network pixels at ``size`` ``(H, W)`` per pixel at ``reference_size``: the ratio of the areas (1.0 with no
        reference size)."""
        if self.reference_size is None:
            return 1.0
        return (size[0] * size[1]) / (self.reference_size[0] * self.reference_size[1])

    def min_pixels(self, scale: float = 1.0) -> int:
        """``min_cluster_pixels`` on a map of ``scale`` times the reference area (`pixel_scale`), at least 1."""
        return self.min_cluster_pixels if scale == 1.0 else max(1, round(self.min_cluster_pixels * scale))

    def core_samples(self, candidates: int, scale: float = 1.0) -> int:
        """``min_samples`` for a DBSCAN of ``candidates`` pixels on a map of ``scale`` times the reference area.

        A lane's density in the subsample is what a core point counts: the subsample a map draws
        (``min(candidates, max_points)``) against the one the same road would draw at the reference size
        (``min(candidates / scale, max_points)``), so ``min_samples`` keeps its meaning at any size and is unchanged
        at ``scale`` 1. At least 1."""
        if scale == 1.0:
            return self.min_samples
        drawn, drawn_at_reference = min(candidates, self.max_points), min(candidates / scale, self.max_points)
        return max(1, round(self.min_samples * drawn / max(drawn_at_reference, 1e-9)))


def cluster_lane_pixels(
    embedding: np.ndarray, config: PostprocessConfig, confident: np.ndarray | None = None, scale: float = 1.0
) -> np.ndarray:
    """Cluster lane-pixel embeddings; DBSCAN on a subsample, nearest-centre assignment for all.

    Args:
        embedding: ``(N, E)`` float embeddings of the lane pixels.
        config: the decoding options.
        confident: ``(N,)`` bool, the pixels DBSCAN may use (``None``: all).
        scale: the lane map's area over ``config.reference_size``'s (`PostprocessConfig.pixel_scale`), which
            ``min_samples`` is scaled by (`PostprocessConfig.core_samples`).

    Returns:
        ``(N,)`` int labels: ``0..K-1`` clusters ordered by size (largest first), ``-1`` noise.
    """
    if embedding.ndim != 2:
        raise ValueError(f"expected embedding of shape (N, E), got {embedding.shape}")
    n = len(embedding)
    labels = np.full(n, -1, dtype=np.int64)
    subset = np.arange(n) if confident is None else np.flatnonzero(confident)
    min_samples = config.core_samples(len(subset), scale)
    if n < min_samples or len(subset) < min_samples:
        return labels
    emb = np.ascontiguousarray(embedding, dtype=np.float32)
    if len(subset) > config.max_points:
        rng = np.random.default_rng(config.seed)
        subset = np.sort(rng.choice(subset, size=config.max_points, replace=False))
    points = emb[subset]
    sub_labels = dbscan(points, config.eps, min_samples)
    cluster_ids = np.unique(sub_labels[sub_labels >= 0])
    if len(cluster_ids) == 0:
        return labels
    centres = np.stack([points[sub_labels == c].mean(axis=0) for c in cluster_ids])  # (K, E)
    # squared distances of every lane pixel to every centre, (N, K)
    d2 = (emb**2).sum(1, keepdims=True) - 2.0 * emb @ centres.T + (centres**2).sum(1)[None, :]
    nearest = d2.argmin(axis=1)
    near_enough = d2[np.arange(n), nearest] <= config.assign_radius**2
    counts = np.bincount(nearest[near_enough], minlength=len(centres))
    order = np.argsort(-counts, kind="stable")  # largest first
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    labels[near_enough] = rank[nearest[near_enough]]
    return labels


def dbscan(points: np.ndarray, eps: float, min_samples: int) -> np.ndarray:
    """sklearn's ``DBSCAN(eps, min_samples, algorithm="ball_tree").fit_predict(points)``, the same labels, without
    the estimator's checks and thread pool around its two steps (a third of its time on the ~1,000 points of an
    image): the neighbourhoods of a ``BallTree`` (leaf size 30, Euclidean, as `DBSCAN`'s), then sklearn's own
    cluster expansion. Falls back to the estimator where that private function is gone.

    Args:
        points: ``(N, E)`` float embeddings.
        eps: the neighbourhood radius.
        min_samples: neighbours (the point included) a core point has at least.

    Returns:
        ``(N,)`` labels: ``0..K-1`` in the order DBSCAN finds the clusters, ``-1`` noise.
    """
    if _dbscan_inner is None:  # ball_tree: faster than kd_tree on tight 4-d clusters (docs/training.md)
        found: np.ndarray = DBSCAN(eps=eps, min_samples=min_samples, algorithm="ball_tree").fit_predict(points)
        return found
    data = np.asarray(points, dtype=np.float64)
    neighbourhoods = BallTree(data, leaf_size=30, metric="euclidean").query_radius(data, eps)
    counts = np.fromiter((len(n) for n in neighbourhoods), dtype=np.intp, count=len(data))
    labels = np.full(len(data), -1, dtype=np.intp)
    _dbscan_inner(np.asarray(counts >= min_samples, dtype=np.uint8), neighbourhoods, labels)
    return labels.astype(np.int64)


@dataclass(frozen=True)
class LaneCurve:
    """A fitted lane ``x = polyval(coef, y)`` valid over the rows ``[y_lo, y_hi]`` its pixels cover."""

    coef: np.ndarray
    y_lo: float
    y_hi: float

    def x_at(self, ys: np.ndarray) -> np.ndarray:
        """x at rows ``ys``: the polynomial inside ``[y_lo, y_hi]``, its end tangents outside."""
        ys = np.asarray(ys, dtype=np.float64)
        x = np.polyval(self.coef, np.clip(ys, self.y_lo, self.y_hi))
        slope = np.polyval(np.polyder(self.coef), np.clip(ys, self.y_lo, self.y_hi)) if len(self.coef) > 1 else 0.0
        out: np.ndarray = x + slope * (ys - np.clip(ys, self.y_lo, self.y_hi))
        return out


def fit_curve(points: np.ndarray, config: PostprocessConfig) -> LaneCurve | None:
    """Fit x = f(y) with outlier rejection to one cluster's pixels.

    Args:
        points: ``(N, 2)`` ``(x, y)`` of the cluster's pixels in original-image pixels.
        config: the decoding options (``y_step``, ``degree``, ``outlier_px``).

    Returns:
        the curve, or ``None`` when fewer than 2 bands of ``y_step`` rows are covered.
    """
    x, y = points[:, 0], points[:, 1]
    band = np.floor(y / config.y_step).astype(np.int64)
    bands, inverse = np.unique(band, return_inverse=True)
    if len(bands) < 2:
        return None
    # one point per band of rows: the median x and the median y (robust to a stray pixel)
    bx, by = _band_median(x, inverse, len(bands)), _band_median(y, inverse, len(bands))
    keep = np.ones(len(bx), dtype=bool)
    coef = np.zeros(1)  # set by the first fit
    for _ in range(3):
        degree = min(config.degree, int(keep.sum()) - 1)
        coef = np.polyfit(by[keep], bx[keep], degree)
        resid = np.abs(np.polyval(coef, by) - bx)
        mad = np.median(resid[keep])
        new_keep = resid <= max(config.outlier_px, 3.0 * 1.4826 * mad)
        if new_keep.sum() < 2 or np.array_equal(new_keep, keep):
            break
        keep = new_keep
    return LaneCurve(coef, float(by[keep].min()), float(by[keep].max()))


def sample_curve(
    curve: LaneCurve, y_lo: float, y_hi: float, config: PostprocessConfig, y_samples: Sequence[float] | None = None
) -> np.ndarray | None:
    """Sample a curve at the rows of ``[y_lo, y_hi]``: the given ``y_samples`` (within half a ``y_step``), or every
    ``y_step`` pixels on multiples of ``y_step``. Returns ``(M, 2)`` ``(x, y)``, y ascending, or ``None`` below 2."""
    if y_samples is None:
        start = np.ceil(y_lo / config.y_step) * config.y_step
        ys = np.arange(start, y_hi + 1e-6, config.y_step, dtype=np.float64)
    else:
        ys = np.asarray(y_samples, dtype=np.float64)
        ys = np.sort(ys[(ys >= y_lo - config.y_step / 2) & (ys <= y_hi + config.y_step / 2)])
    if len(ys) < 2:
        return None
    return np.stack([curve.x_at(ys), ys], axis=1)


def fit_lane(
    points: np.ndarray, config: PostprocessConfig, y_samples: Sequence[float] | None = None
) -> np.ndarray | None:
    """Fit x = f(y) with outlier rejection to one cluster's pixels and sample it inside the rows it covers.

    Args:
        points: ``(N, 2)`` ``(x, y)`` of the cluster's pixels in original-image pixels.
        config: the decoding options (``y_step``, ``degree``, ``outlier_px``).
        y_samples: rows to sample the curve at (e.g. TuSimple ``h_samples``); ``None`` = every
            ``y_step`` pixels on multiples of ``y_step``.

    Returns:
        ``(M, 2)`` ``(x, y)`` points with y ascending, inside the rows the cluster covers; ``None``
        when fewer than 2 bands of rows are covered.
    """
    curve = fit_curve(points, config)
    return None if curve is None else sample_curve(curve, curve.y_lo, curve.y_hi, config, y_samples)


def _band_median(values: np.ndarray, group: np.ndarray, n_groups: int) -> np.ndarray:
    """Median of ``values`` per group ``0..n_groups-1`` (every group non-empty), without a Python loop."""
    order = np.lexsort((values, group))
    sorted_values = values[order]
    counts = np.bincount(group, minlength=n_groups)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    lo = starts + (counts - 1) // 2
    hi = starts + counts // 2
    out: np.ndarray = 0.5 * (sorted_values[lo] + sorted_values[hi])
    return out


def decode_lanes(
    lane_prob: np.ndarray,
    embedding: np.ndarray,
    orig_from_net: np.ndarray | Sequence[Sequence[float]] | None = None,
    config: PostprocessConfig | None = None,
    y_samples: Sequence[float] | None = None,
    orig_size: tuple[int, int] | None = None,
) -> Lanes:
    """Lanes of one image from the network's two heads.

    Args:
        lane_prob: ``(H, W)`` lane probability at network resolution (softmax of the binary logits).
        embedding: ``(E, H, W)`` pixel embeddings at network resolution.
        orig_from_net: 3x3 map from network-input pixels to original-image pixels (the inverse of the
            sample's ``net_from_orig``); ``None`` = identity.
        config: decoding options; ``None`` = defaults.
        y_samples: original-image rows to sample each lane at (TuSimple ``h_samples``); ``None`` =
            every ``config.y_step`` pixels.
        orig_size: ``(H, W)`` of the original image; points outside it are dropped (``None`` = keep all).

    Returns:
        the image's lanes, left to right: ``(N, 2)`` float arrays of ``(x, y)`` in original pixels.
    """
    config = config or PostprocessConfig()
    if lane_prob.ndim != 2:
        raise ValueError(f"expected lane_prob of shape (H, W), got {lane_prob.shape}")
    if embedding.ndim != 3 or embedding.shape[1:] != lane_prob.shape:
        raise ValueError(
            f"expected embedding of shape (E, {lane_prob.shape[0]}, {lane_prob.shape[1]}), got {embedding.shape}"
        )
    matrix = np.eye(3) if orig_from_net is None else np.asarray(orig_from_net, dtype=np.float64)
    if matrix.shape != (3, 3):
        raise ValueError(f"expected orig_from_net of shape (3, 3), got {matrix.shape}")

    ys, xs = np.nonzero(lane_prob > config.prob_thresh)
    if len(ys) == 0:
        return []
    scale = config.pixel_scale((lane_prob.shape[0], lane_prob.shape[1]))
    confident = None
    if config.cluster_thresh is not None and config.cluster_thresh > config.prob_thresh:
        confident = lane_prob[ys, xs] > config.cluster_thresh
        sure = int(confident.sum())
        if sure < config.core_samples(sure, scale):  # a weak network is never that sure: cluster every lane pixel
            confident = None
    labels = cluster_lane_pixels(embedding[:, ys, xs].T, config, confident, scale)
    counts = np.bincount(labels[labels >= 0], minlength=1)
    pts_net = np.stack([xs, ys, np.ones_like(xs)], axis=0).astype(np.float64)  # (3, N) homogeneous
    pts_orig = matrix @ pts_net
    pts_orig = (pts_orig[:2] / pts_orig[2:]).T  # (N, 2) (x, y) original pixels
    curves: list[LaneCurve] = []
    min_pixels = config.min_pixels(scale)
    for cluster in range(len(counts)):
        if counts[cluster] < min_pixels or len(curves) >= config.max_lanes:
            continue
        curve = fit_curve(pts_orig[labels == cluster], config)
        if curve is not None:
            curves.append(curve)
    lanes = sample_lanes(curves, config, y_samples, orig_size)
    return lanes


def sample_lanes(
    curves: Sequence[LaneCurve],
    config: PostprocessConfig,
    y_samples: Sequence[float] | None = None,
    orig_size: tuple[int, int] | None = None,
) -> Lanes:
    """The lanes of one image from its fitted curves: each sampled inside the rows it covers, or with ``extend``
    from the image's common far end to the bottom; points outside ``orig_size`` ``(H, W)`` dropped; left to right.

    Args:
        curves: the image's fitted curves (`fit_curve`), original pixels.
        config: the decoding options (``extend``, ``y_step``).
        y_samples: rows to sample at (TuSimple ``h_samples``); ``None`` = every ``y_step`` pixels.
        orig_size: ``(H, W)`` of the original image, or None (keep every point).

    Returns:
        ``(N, 2)`` ``(x, y)`` float arrays, left to right by x at their lowest row.
    """
    top = bottom = 0.0
    if config.extend and curves:
        top = min(c.y_lo for c in curves)
        if y_samples is not None and len(y_samples):
            bottom = float(max(y_samples))
        else:
            bottom = float(orig_size[0] - 1) if orig_size is not None else max(c.y_hi for c in curves)
    lanes: Lanes = []
    for curve in curves:
        lo, hi = (top, bottom) if config.extend else (curve.y_lo, curve.y_hi)
        lane = sample_curve(curve, lo, hi, config, y_samples)
        if lane is not None and orig_size is not None:
            inside = (
                (lane[:, 0] >= 0)
                & (lane[:, 0] <= orig_size[1] - 1)
                & (lane[:, 1] >= 0)
                & (lane[:, 1] <= orig_size[0] - 1)
            )
            lane = lane[inside] if inside.sum() >= 2 else None
        if lane is not None:
            lanes.append(lane)
    # left to right by x at the lane's lowest (largest y) row
    lanes.sort(key=lambda lane: float(lane[np.argmax(lane[:, 1]), 0]))
    return lanes
