"""Pictures of an alignment in the manner of the paper's Figures 2-3: features, matches, warped overlay."""

from __future__ import annotations

import cv2
import numpy as np

from stamlane.align.features import detect_plain_orb, to_gray
from stamlane.align.homography import AlignConfig, Alignment, FramePrep, match_features
from stamlane.align.warp import warp_to_key

__all__ = ["draw_alignment"]

GREEN, RED, YELLOW, CYAN = (60, 200, 60), (40, 40, 230), (0, 220, 255), (255, 200, 0)


def _bgr(image: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 or image.shape[2] == 1 else image.copy()


def _label(panel: np.ndarray, text: str) -> np.ndarray:
    cv2.rectangle(panel, (0, 0), (panel.shape[1], 34), (0, 0, 0), -1)
    cv2.putText(panel, text, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.75, (255, 255, 255), 2, cv2.LINE_AA)
    return panel


def _features_panel(image: np.ndarray, points: np.ndarray, horizon_row: int, color: tuple, title: str) -> np.ndarray:
    panel = _bgr(image)
    cv2.line(panel, (0, horizon_row), (panel.shape[1], horizon_row), CYAN, 2)
    for x, y in points:
        cv2.circle(panel, (round(x), round(y)), 5, color, 2, cv2.LINE_AA)
    return _label(panel, title)


def _blend(key: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Key frame in green, the other frame in magenta: aligned structure turns grey, misaligned shows colour."""
    k, o = to_gray(key), to_gray(other)
    return cv2.merge([o, k, o])


def draw_alignment(
    hist: np.ndarray,
    key: np.ndarray,
    alignment: Alignment,
    horizon_row: int,
    config: AlignConfig | None = None,
    *,
    scale: float = 0.5,
    max_lines: int = 150,
) -> np.ndarray:
    """A three-row picture of one alignment.

    Rows: plain ``cv2.ORB_create`` top-N features vs the evenly spread features on the key frame (Figure 2);
    matches between history and key frame, green where they agree with ``key_from_hist`` (Figure 3a);
    key/history blends before and after warping the history frame onto the key frame (Figure 3b).

    Args:
        hist: history frame, uint8 ``(H, W, 3)`` or ``(H, W)``.
        key: key frame, same size.
        alignment: the alignment of ``hist`` to ``key``.
        horizon_row: first row of the ground region.
        config: the estimation settings used.
        scale: size of each panel relative to the frame.
        max_lines: most match lines drawn.

    Returns:
        uint8 BGR picture, ``(3 * scale * H, 2 * scale * W, 3)``.
    """
    cfg = config or AlignConfig()
    hp, kp = FramePrep(hist, horizon_row, cfg), FramePrep(key, horizon_row, cfg)
    spread = kp.features()
    plain = detect_plain_orb(to_gray(key), horizon_row, max(len(spread), 4))
    fig2a = _features_panel(key, plain.points, horizon_row, RED, f"plain ORB top-{len(plain)}")
    fig2b = _features_panel(key, spread.points, horizon_row, GREEN, f"evenly spread, {len(spread)}")

    src, dst = match_features(hp.features(), kp.features(cfg.key_scales), cfg)
    _h, w = key.shape[:2]
    matches = np.hstack([_bgr(hist), _bgr(key)])
    if len(src):
        projected = cv2.perspectiveTransform(src.reshape(-1, 1, 2).astype(np.float64), alignment.key_from_hist)
        agree = np.linalg.norm(projected.reshape(-1, 2) - dst, axis=1) < 3 * cfg.ransac_threshold
        order = np.random.default_rng(0).permutation(len(src))[:max_lines]
        for i in order:
            color = GREEN if agree[i] and alignment.ok else RED
            p, q = (int(src[i, 0]), int(src[i, 1])), (int(dst[i, 0]) + w, int(dst[i, 1]))
            cv2.line(matches, p, q, color, 2, cv2.LINE_AA)
    state = "ok" if alignment.ok else f"FAILED: {alignment.reason}"
    _label(matches, f"history | key: {alignment.num_matches} matches, {alignment.num_inliers} inliers ({state})"[:110])
    warped = warp_to_key(_bgr(hist), alignment.key_from_hist)
    warped[:horizon_row] = _bgr(key)[:horizon_row]  # the homography holds for the ground only
    before = _label(_blend(key, hist), "key (green) + history (magenta), before alignment")
    after = _label(_blend(key, warped), "key (green) + history warped onto key, after alignment")
    grid = np.vstack([np.hstack([fig2a, fig2b]), matches, np.hstack([before, after])])
    return cv2.resize(grid, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
