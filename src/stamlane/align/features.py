"""Evenly spread ORB features on the ground region (paper 3.1, Figure 2; ORB-SLAM's extractor).

Plain ``cv2.ORB_create`` keeps the N corners with the highest Harris score, and on a weak-texture road
they cluster on the few strong structures (lane marks, cars, the horizon). Here the ground region is
split into cells, each cell keeps its FAST corners at a high threshold or, when it has none, at a low
retry threshold; a quadtree then keeps the strongest corner of each node so the kept corners cover the
road evenly; rotated-BRIEF descriptors are computed on them with ``cv2.ORB``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = [
    "FeatureConfig",
    "Features",
    "concat_features",
    "detect_plain_orb",
    "detect_pyramid_features",
    "detect_spread_features",
    "ground_box",
    "to_gray",
]

PATCH_RADIUS = 15  # px, half of ORB's 31 px patch: the intensity-centroid orientation uses this circle
EDGE = 19  # px, ORB-SLAM's EDGE_THRESHOLD: corners closer to the image border get no full descriptor patch


@dataclass(frozen=True)
class FeatureConfig:
    """How features are detected.

    Attributes:
        cell_size: side of the FAST cells in pixels (ORB-SLAM uses 30).
        fast_threshold: FAST threshold tried first in every cell (ORB-SLAM's iniThFAST, 20).
        min_fast_threshold: retry threshold for a cell without a corner at ``fast_threshold`` (minThFAST, 7).
        max_features: feature budget; the quadtree stops splitting once it has this many nodes.
        spread: ``False`` replaces the grid and quadtree by plain ``cv2.ORB_create`` top-N on each level
            (the paper's Figure 2a baseline, for comparisons).
    """

    cell_size: int = 30
    fast_threshold: int = 20
    min_fast_threshold: int = 7
    max_features: int = 500
    spread: bool = True

    def __post_init__(self) -> None:
        if self.cell_size < 4:
            raise ValueError(f"cell_size must be >= 4 px, got {self.cell_size}")
        if not 0 < self.min_fast_threshold <= self.fast_threshold:
            raise ValueError(
                f"need 0 < min_fast_threshold <= fast_threshold, got {self.min_fast_threshold}, {self.fast_threshold}"
            )
        if self.max_features < 4:
            raise ValueError(f"max_features must be >= 4 (a homography needs 4 points), got {self.max_features}")


@dataclass
class Features:
    """Keypoints and their descriptors in one image.

    Attributes:
        points: ``(N, 2)`` float32 ``(x, y)`` in image pixels.
        descriptors: ``(N, 32)`` uint8 rotated-BRIEF descriptors, one row per point.
    """

    points: np.ndarray
    descriptors: np.ndarray

    def __len__(self) -> int:
        return len(self.points)


def to_gray(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3)`` BGR or ``(H, W)`` / ``(H, W, 1)`` uint8 -> ``(H, W)`` uint8 grey (checked by the caller)."""
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    return image.reshape(image.shape[0], image.shape[1])


def ground_box(shape: tuple[int, int], horizon_row: int) -> tuple[int, int, int, int]:
    """The detection window ``(x0, y0, x1, y1)`` (half-open) below ``horizon_row``, ``EDGE`` px from the border."""
    height, width = shape
    return EDGE, max(int(horizon_row), EDGE), width - EDGE, height - EDGE


def _empty(shape: tuple[int, ...] = (0, 2)) -> Features:
    return Features(np.zeros(shape, np.float32), np.zeros((0, 32), np.uint8))


def _fast(gray: np.ndarray, box: tuple[int, int, int, int], threshold: int) -> tuple[np.ndarray, np.ndarray]:
    """FAST-9 with non-max suppression in ``box``: points ``(N, 2)`` float32 in image pixels, scores ``(N,)``."""
    x0, y0, x1, y1 = box
    # 3 px of context so that corners at the window's edge see their full Bresenham circle
    cx0, cy0 = max(x0 - 3, 0), max(y0 - 3, 0)
    crop = gray[cy0 : y1 + 3, cx0 : x1 + 3]
    keypoints = cv2.FastFeatureDetector.create(threshold, True).detect(crop)
    if not keypoints:
        return np.zeros((0, 2), np.float32), np.zeros(0, np.float32)
    points = cv2.KeyPoint.convert(keypoints) + np.array([cx0, cy0], np.float32)
    scores = np.fromiter((k.response for k in keypoints), np.float32, len(keypoints))
    inside = (points[:, 0] >= x0) & (points[:, 0] < x1) & (points[:, 1] >= y0) & (points[:, 1] < y1)
    return points[inside], scores[inside]


def _cell_ids(points: np.ndarray, box: tuple[int, int, int, int], cell_size: int) -> tuple[np.ndarray, int]:
    """Cell index of each point ``(N,)`` and the number of cells of ``box``."""
    x0, y0, x1, y1 = box
    cols = max((x1 - x0 + cell_size - 1) // cell_size, 1)
    rows = max((y1 - y0 + cell_size - 1) // cell_size, 1)
    ids = ((points[:, 1] - y0) // cell_size).astype(np.int64) * cols + ((points[:, 0] - x0) // cell_size).astype(
        np.int64
    )
    return ids, rows * cols


def _grid_fast(gray: np.ndarray, box: tuple[int, int, int, int], cfg: FeatureConfig) -> tuple[np.ndarray, np.ndarray]:
    """FAST per cell at ``cfg.fast_threshold``, cells without a corner retried at ``cfg.min_fast_threshold``.

    Vectorised: one FAST pass over the window at the high threshold; when some cells stay empty, one pass
    at the low threshold whose corners are kept only in those cells. This equals per-cell FAST with retry
    up to non-max suppression across cell borders (per-cell runs cannot see a neighbour in the next
    cell): a corner's FAST score is the highest threshold at which it is still a corner, and non-max
    suppression only removes a corner next to a higher-scoring one, so the low pass restricted to scores
    >= the high threshold reproduces the high pass (tested).
    """
    points, scores = _fast(gray, box, cfg.fast_threshold)
    ids, n_cells = _cell_ids(points, box, cfg.cell_size)
    occupied = np.zeros(n_cells, bool)
    occupied[ids] = True
    if occupied.all() or cfg.min_fast_threshold >= cfg.fast_threshold:
        return points, scores
    weak_points, weak_scores = _fast(gray, box, cfg.min_fast_threshold)
    weak_ids, _ = _cell_ids(weak_points, box, cfg.cell_size)
    keep = ~occupied[weak_ids]
    return np.concatenate([points, weak_points[keep]]), np.concatenate([scores, weak_scores[keep]])


def _quadtree(points: np.ndarray, scores: np.ndarray, box: tuple[int, int, int, int], budget: int) -> np.ndarray:
    """Indices of the strongest corner of each quadtree node (ORB-SLAM's ``DistributeOctTree``), vectorised.

    The root nodes are squares of the window's height side by side. Splitting every node that holds more
    than one corner down to depth ``L`` leaves exactly the non-empty cells of the ``2^L`` grid of each
    root (a lone corner stays lone in its sub-cell, empty nodes are dropped), so whole levels are counted
    with ``np.unique``; the last level is split partially, most crowded nodes first, until ``budget``
    nodes exist, as ORB-SLAM does.
    """
    if len(points) <= budget:
        return np.arange(len(points))
    x0, y0, _x1, y1 = box
    side = float(max(y1 - y0, 1))
    rel = (points - np.array([x0, y0], np.float32)) / side  # root cell units

    def node_ids(level: int) -> np.ndarray:
        n = 2**level
        gx = np.floor(rel[:, 0] * n).astype(np.int64)
        gy = np.minimum(np.floor(rel[:, 1] * n).astype(np.int64), n - 1)
        ids: np.ndarray = gy * (1 << 40) + gx
        return ids

    level, parent = 0, node_ids(0)
    child = node_ids(1)
    while len(np.unique(child)) <= budget and level < 30:
        level, parent = level + 1, child
        child = node_ids(level + 1)
    # split the most crowded nodes of the last whole level first until the budget is reached
    parents, parent_idx, parent_count = np.unique(parent, return_inverse=True, return_counts=True)
    _children, first, child_idx = np.unique(child, return_index=True, return_inverse=True)
    children_per_parent = np.bincount(parent_idx[first], minlength=len(parents))
    order = np.argsort(-parent_count, kind="stable")
    gain = np.cumsum(children_per_parent[order] - 1)
    n_split = int(np.searchsorted(gain, budget - len(parents), side="left")) + 1
    split = np.zeros(len(parents), bool)
    split[order[:n_split]] = True
    # node key: the child cell where its parent was split, else the parent cell
    node = np.where(split[parent_idx], child_idx.astype(np.int64) + len(parents), parent_idx.astype(np.int64))
    order = np.lexsort((-scores, node))
    node_sorted = node[order]
    keep = order[np.r_[True, node_sorted[1:] != node_sorted[:-1]]]
    if len(keep) > budget:
        keep = keep[np.argsort(-scores[keep], kind="stable")[:budget]]
    return np.sort(keep)


_HALF_WIDTHS = np.floor(np.sqrt(PATCH_RADIUS**2 - np.arange(-PATCH_RADIUS, PATCH_RADIUS + 1) ** 2)).astype(np.int64)
_ROW_OFFSETS = np.arange(-PATCH_RADIUS, PATCH_RADIUS + 1, dtype=np.int64)


def _orientation(gray: np.ndarray, points: np.ndarray) -> np.ndarray:
    """ORB's intensity-centroid angle in degrees ``[0, 360)`` of each point's 31 px circular patch, ``(N,)``.

    The circle is summed row by row from per-row prefix sums of ``I`` and ``x * I`` (4 look-ups per row
    instead of 709 pixel reads per point).
    """
    if len(points) == 0:
        return np.zeros(0, np.float32)
    xi = np.rint(points[:, 0]).astype(np.int64)
    yi = np.rint(points[:, 1]).astype(np.int64)
    top = int(yi.min()) - PATCH_RADIUS
    rows = gray[top : int(yi.max()) + PATCH_RADIUS + 1].astype(np.int32)
    height, width = rows.shape
    s0 = np.zeros((height, width + 1), np.int32)
    s1 = np.zeros((height, width + 1), np.int32)
    np.cumsum(rows, axis=1, out=s0[:, 1:])
    np.cumsum(rows * np.arange(width, dtype=np.int32), axis=1, out=s1[:, 1:])
    r = (yi - top)[:, None] + _ROW_OFFSETS[None]  # (N, 31) rows of the circle
    a = r * (width + 1) + (xi[:, None] - _HALF_WIDTHS[None])  # first column of each row segment
    b = r * (width + 1) + (xi[:, None] + _HALF_WIDTHS[None] + 1)  # one past its last column
    f0, f1 = s0.reshape(-1), s1.reshape(-1)
    row_sum = (f0[b] - f0[a]).astype(np.float64)
    m10 = ((f1[b] - f1[a]).astype(np.float64) - xi[:, None] * row_sum).sum(axis=1)
    m01 = row_sum @ _ROW_OFFSETS.astype(np.float64)
    degrees: np.ndarray = np.degrees(np.arctan2(m01, m10)) % 360.0
    return degrees


def _describe(gray: np.ndarray, points: np.ndarray, scores: np.ndarray, horizon_row: int) -> Features:
    angles = _orientation(gray, points)
    # crop to the ground region (+ the descriptor's reach) so ORB blurs fewer rows; shift back afterwards
    top = max(min(int(horizon_row), int(points[:, 1].min()) if len(points) else 0) - 2 * EDGE, 0)
    xs, ys = points[:, 0].tolist(), (points[:, 1] - top).tolist()  # Python floats: KeyPoint() is faster from them
    keypoints = [
        cv2.KeyPoint(x, y, 31.0, a, s, 0) for x, y, a, s in zip(xs, ys, angles.tolist(), scores.tolist(), strict=True)
    ]
    orb = cv2.ORB.create(edgeThreshold=EDGE, patchSize=31)
    described, descriptors = orb.compute(gray[top:], keypoints)
    if descriptors is None or not described:
        return _empty()
    # KeyPoint.convert returns an (N, 2) float32 array (the stub says a sequence of points)
    points = np.asarray(cv2.KeyPoint.convert(described), np.float32) + np.array([0, top], np.float32)
    return Features(points, descriptors)


def detect_spread_features(gray: np.ndarray, horizon_row: int, cfg: FeatureConfig | None = None) -> Features:
    """Evenly spread ORB features below ``horizon_row``.

    Args:
        gray: ``(H, W)`` uint8 grey image.
        horizon_row: first image row of the ground region.
        cfg: detection settings (defaults: 30 px cells, FAST 20 / retry 7, 500 features).

    Returns:
        at most ``cfg.max_features`` features in image pixels; none on a textureless image.
    """
    cfg = cfg or FeatureConfig()
    box = ground_box(gray.shape, horizon_row)
    if box[2] <= box[0] or box[3] <= box[1]:
        return _empty()
    points, scores = _grid_fast(gray, box, cfg)
    if len(points) == 0:
        return _empty()
    keep = _quadtree(points, scores, box, cfg.max_features)
    return _describe(gray, points[keep], scores[keep], horizon_row)


def detect_plain_orb(gray: np.ndarray, horizon_row: int, max_features: int = 500, nlevels: int = 8) -> Features:
    """Plain ``cv2.ORB.create(max_features)`` on the ground region: the top-N corners by score (Figure 2a).

    Args:
        gray: ``(H, W)`` uint8 grey image.
        horizon_row: first image row of the ground region (rows above are masked out).
        max_features: N.
        nlevels: ORB's own pyramid levels (OpenCV's default 8; 1 inside ``detect_pyramid_features``).

    Returns:
        the features in image pixels.
    """
    mask = np.zeros(gray.shape, np.uint8)
    mask[max(int(horizon_row), 0) :] = 255
    keypoints, descriptors = cv2.ORB.create(max_features, nlevels=nlevels).detectAndCompute(gray, mask)
    if descriptors is None or not keypoints:
        return _empty()
    return Features(np.asarray(cv2.KeyPoint.convert(keypoints), np.float32), descriptors)


def concat_features(parts: list[Features]) -> Features:
    """One feature set from several (e.g. pyramid levels)."""
    parts = [p for p in parts if len(p)]
    if len(parts) <= 1:
        return parts[0] if parts else _empty()
    return Features(
        np.concatenate([p.points for p in parts]),
        np.concatenate([p.descriptors for p in parts]),
    )


def detect_pyramid_features(
    gray: np.ndarray, horizon_row: int, scales: tuple[float, ...], cfg: FeatureConfig | None = None
) -> Features:
    """Evenly spread features on several down-scaled copies of ``gray`` (ORB-SLAM's scale pyramid).

    Level ``s`` is ``gray`` shrunk by ``s`` (``s >= 1``) with a budget of ``cfg.max_features / s**2``; its
    descriptors therefore describe ``s`` times larger patches, which lets a frame seen from closer (the key
    frame, after driving forward) match an older frame at level 1.

    Args:
        gray: ``(H, W)`` uint8 grey image.
        horizon_row: first row of the ground region in ``gray``.
        scales: shrink factors, e.g. ``(1.0, 1.3, 1.69)``.
        cfg: detection settings of level 1 (the cell size is kept on every level, as in ORB-SLAM).

    Returns:
        all levels' features, points ``(N, 2)`` in ``gray``'s pixels.
    """
    cfg = cfg or FeatureConfig()
    parts = []
    for scale in scales:
        if scale < 1:
            raise ValueError(f"pyramid scales must be >= 1, got {scales}")
        level = gray if scale == 1 else cv2.resize(gray, None, fx=1 / scale, fy=1 / scale, interpolation=cv2.INTER_AREA)
        budget = max(int(cfg.max_features / scale**2), 4)
        level_row = round(horizon_row / scale)
        if cfg.spread:
            level_cfg = FeatureConfig(cfg.cell_size, cfg.fast_threshold, cfg.min_fast_threshold, budget)
            part = detect_spread_features(level, level_row, level_cfg)
        else:
            part = detect_plain_orb(level, level_row, budget, nlevels=1)
        part.points = part.points * np.float32(scale)
        parts.append(part)
    return concat_features(parts)
