"""Pictures of an alignment in the manner of the paper's Figures 2-3: features, matches, warped overlay."""

from __future__ import annotations

import cv2
import numpy as np

from stamlane.align.features import detect_plain_orb, to_gray
from stamlane.align.homography import AlignConfig, Alignment, FramePrep, match_features
from stamlane.align.warp import warp_to_key

__all__ = ["draw_alignment", "label_scale"]

GREEN, RED, YELLOW, CYAN = (60, 200, 60), (40, 40, 230), (0, 220, 255), (255, 200, 0)


def _bgr(image: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 or image.shape[2] == 1 else image.copy()


LABEL_FONT = cv2.FONT_HERSHEY_SIMPLEX
MIN_LABEL_SCALE = 0.35
"""Smallest font scale of a label (about 8 px high): a longer text wraps onto a second line before it shrinks."""


def _text_width(text: str, scale: float) -> int:
    return cv2.getTextSize(text, LABEL_FONT, scale, 1)[0][0]


def _two_lines(text: str) -> list[str]:
    """``text`` split at the space nearest its middle (one line when it has no space)."""
    spaces = [i for i, c in enumerate(text) if c == " "]
    if not spaces:
        return [text]
    cut = min(spaces, key=lambda i: abs(i - len(text) / 2))
    return [text[:cut], text[cut + 1 :]]


def label_scale(frame_width: int) -> float:
    """The font scale of the labels of panels ``frame_width`` px wide: 0.5 at 400 px, between `MIN_LABEL_SCALE`
    and 0.8."""
    return min(0.8, max(MIN_LABEL_SCALE, frame_width / 800))


def _label(panel: np.ndarray, text: str, scale: float) -> np.ndarray:
    """Write ``text`` in white on a black band at the top of ``panel`` (in place), whole whatever the panel's width:
    at font ``scale`` (`label_scale`), on two lines where one would not fit at `MIN_LABEL_SCALE`, and smaller only
    where even two lines would not fit."""
    room = panel.shape[1] - 16
    lines = [text]
    if _text_width(text, scale) > room and _text_width(text, MIN_LABEL_SCALE) > room:
        lines = _two_lines(text)
    widest = max(_text_width(line, scale) for line in lines)
    scale = min(scale, scale * room / widest) if widest > room else scale
    stroke = 2 if scale >= 0.6 else 1
    (_, text_h), base = cv2.getTextSize("Ag", LABEL_FONT, scale, stroke)
    line_h = text_h + base + 4
    cv2.rectangle(panel, (0, 0), (panel.shape[1], 8 + line_h * len(lines)), (0, 0, 0), -1)
    for i, line in enumerate(lines):
        y = 4 + line_h * i + text_h + 2
        cv2.putText(panel, line, (8, y), LABEL_FONT, scale, (255, 255, 255), stroke, cv2.LINE_AA)
    return panel


def _features_panel(image: np.ndarray, points: np.ndarray, horizon_row: int, color: tuple[int, int, int]) -> np.ndarray:
    panel = _bgr(image)
    cv2.line(panel, (0, horizon_row), (panel.shape[1], horizon_row), CYAN, 2)
    for x, y in points:
        cv2.circle(panel, (round(x), round(y)), 5, color, 2, cv2.LINE_AA)
    return panel


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
    fig2a = _features_panel(key, plain.points, horizon_row, RED)
    fig2b = _features_panel(key, spread.points, horizon_row, GREEN)

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
    warped = warp_to_key(_bgr(hist), alignment.key_from_hist)
    warped[:horizon_row] = _bgr(key)[:horizon_row]  # the homography holds for the ground only

    font = label_scale(round(w * scale))

    def shown(panel: np.ndarray, title: str) -> np.ndarray:  # labelled at the size it is seen at
        return _label(cv2.resize(panel, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA), title, font)

    rows = [
        np.hstack([shown(fig2a, f"plain ORB top-{len(plain)}"), shown(fig2b, f"evenly spread, {len(spread)}")]),
        shown(matches, f"history | key: {alignment.num_matches} matches, {alignment.num_inliers} inliers ({state})"),
        np.hstack(
            [
                shown(_blend(key, hist), "key (green) + history (magenta), before alignment"),
                shown(_blend(key, warped), "key (green) + history warped onto key, after alignment"),
            ]
        ),
    ]
    width = min(row.shape[1] for row in rows)  # rounding may leave the two-panel rows a pixel apart
    return np.vstack([row[:, :width] for row in rows])
