"""Overlay pictures: predicted (and annotated) lanes drawn on the original key frame, with a legend.

Colours come from the Okabe-Ito palette (`OKABE_ITO`, safe for the common colour-vision deficiencies): each
predicted lane in its own colour (`LANE_COLOURS`, left to right); the ground truth as a yellow band inside a black
outline (`GT_CORE`, `GT_EDGE`), wider than a prediction, so that it shows on dark asphalt (the yellow), on glare and
white paint (the black), and around a prediction drawn on it (a matched lane: the prediction inside the band).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from stamlane.types import Lanes

__all__ = [
    "GT_CORE",
    "GT_EDGE",
    "LANE_COLOURS",
    "OKABE_ITO",
    "draw_lanes",
    "draw_legend",
    "gt_edge",
    "gt_width",
    "label_strip",
    "line_width",
    "text_scale",
]

OKABE_ITO: dict[str, tuple[int, int, int]] = {
    "blue": (0, 114, 178),
    "orange": (230, 159, 0),
    "bluish green": (0, 158, 115),
    "vermillion": (213, 94, 0),
    "sky blue": (86, 180, 233),
    "reddish purple": (204, 121, 167),
    "yellow": (240, 228, 66),
    "black": (0, 0, 0),
}
"""RGB colours of Okabe & Ito's colour-blind-safe palette (2008), in the order plots take them
(`stamlane.experiments.plots.series_style`)."""


def _bgr(name: str) -> tuple[int, int, int]:
    r, g, b = OKABE_ITO[name]
    return b, g, r


LANE_COLOURS: tuple[tuple[int, int, int], ...] = tuple(
    _bgr(name) for name in ("vermillion", "sky blue", "bluish green", "reddish purple", "blue", "orange")
)
"""BGR colour of the i-th predicted lane (left to right), cycled; never the ground truth's yellow or black."""
GT_CORE = _bgr("yellow")
"""BGR colour of the inside of an annotated lane."""
GT_EDGE = (0, 0, 0)
"""BGR colour of the outline of an annotated lane."""


def line_width(image: np.ndarray) -> int:
    """The width of a predicted lane on ``image`` (``(H, W, ...)``): 2 px, and 1 px more per 320 px of width."""
    return max(2, int(image.shape[1]) // 320)


def gt_width(width: int) -> int:
    """The width of an annotated lane's core beside predicted lanes ``width`` wide: three times theirs, so that it
    shows on both sides of a prediction drawn on it (with its dots)."""
    return 3 * width


def gt_edge(width: int) -> int:
    """The width of an annotated lane's outline on each side of its core: 2 px at least (anti-aliasing blends one)."""
    return max(2, width // 2 + 1)


def _points(lane: object) -> np.ndarray:
    return np.round(np.asarray(lane, dtype=np.float64)).astype(np.int32).reshape(-1, 1, 2)


def draw_lanes(image: np.ndarray, lanes: Lanes, gt_lanes: Lanes | None = None, thickness: int = 0) -> np.ndarray:
    """Draw lanes on a copy of an image.

    Args:
        image: ``(H, W, 3)`` uint8 BGR, the ORIGINAL key frame (lanes are in its pixels).
        lanes: predicted lanes, ``(N, 2)`` ``(x, y)`` arrays; one colour each (``LANE_COLOURS``), a dot per point.
        gt_lanes: annotated lanes, drawn first (under the predictions) as a `GT_CORE` band three times the width of
            a prediction (`gt_width`) inside a `GT_EDGE` outline (``None``: none).
        thickness: width of a predicted lane in pixels; 0 = `line_width`.

    Returns:
        the picture, ``(H, W, 3)`` uint8 BGR.
    """
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected a (H, W, 3) uint8 image, got {image.shape} {image.dtype}")
    out: np.ndarray = image.copy()
    width = thickness or line_width(image)
    gt = [pts for pts in map(_points, gt_lanes or []) if len(pts) >= 2]
    for pts in gt:  # every outline first: where two annotated lanes meet, both cores stay visible
        cv2.polylines(out, [pts], False, GT_EDGE, gt_width(width) + 2 * gt_edge(width), cv2.LINE_AA)
    for pts in gt:
        cv2.polylines(out, [pts], False, GT_CORE, gt_width(width), cv2.LINE_AA)
    dot = max(1, math.ceil(0.75 * width))
    for i, lane in enumerate(lanes):
        pts = _points(lane)
        colour = LANE_COLOURS[i % len(LANE_COLOURS)]
        if len(pts) >= 2:
            cv2.polylines(out, [pts], False, colour, width, cv2.LINE_AA)
        for x, y in pts[:, 0]:
            cv2.circle(out, (int(x), int(y)), dot, colour, -1, cv2.LINE_AA)
    return out


_FONT = cv2.FONT_HERSHEY_SIMPLEX


def text_scale(image: np.ndarray) -> float:
    """OpenCV font scale of legend text on ``image``: 0.5 at 640 px wide, in proportion (0.35 at least)."""
    return max(0.35, int(image.shape[1]) / 1280)


def draw_legend(
    image: np.ndarray,
    *,
    model: str | None = None,
    score: str | None = None,
    ground_truth: bool = False,
    predictions: bool = True,
    corner: str = "top",
) -> np.ndarray:
    """Draw a legend box on ``image`` (in place) and return it: the model's name, a sample of each kind of line drawn
    (a prediction, and the ground truth when ``ground_truth``) and the image's score.

    Args:
        image: ``(H, W, 3)`` uint8 BGR, usually what `draw_lanes` returned.
        model: the model's name (first line); None: none.
        score: the image's score against its labels (last line, `stamlane.predict.image_score.image_score`); None: none.
        ground_truth: the picture shows annotated lanes: their sample is drawn.
        predictions: the sample of a predicted lane is drawn.
        corner: ``"top"`` (top left) or ``"bottom"`` (bottom left).

    Returns:
        ``image``.
    """
    if corner not in ("top", "bottom"):
        raise ValueError(f"corner must be 'top' or 'bottom', got {corner!r}")
    scale = text_scale(image)
    stroke = 1 if scale < 0.6 else 2
    (_, text_h), base = cv2.getTextSize("Ag", _FONT, scale, stroke)
    line_h, pad = text_h + base + 4, max(4, text_h // 2)
    width = line_width(image)
    sample = 3 * text_h  # length of a line sample
    rows: list[tuple[str, str]] = []  # (kind, text)
    rows += [("text", model)] if model else []
    rows += [("prediction", "prediction")] if predictions else []
    rows += [("truth", "ground truth")] if ground_truth else []
    rows += [("text", score)] if score else []
    if not rows:
        return image
    indent = {kind: (sample + pad if kind != "text" else 0) for kind, _ in rows}
    box_w = 2 * pad + max(indent[k] + cv2.getTextSize(t, _FONT, scale, stroke)[0][0] for k, t in rows)
    box_h = 2 * pad + line_h * len(rows)
    box_w, box_h = min(box_w, image.shape[1]), min(box_h, image.shape[0])
    top = 0 if corner == "top" else image.shape[0] - box_h
    region = image[top : top + box_h, :box_w]
    region[:] = (region * 0.35).astype(np.uint8)  # a dark veil: white text reads on any picture
    for i, (kind, text) in enumerate(rows):
        y = top + pad + line_h * i + text_h + 2
        mid = y - text_h // 2
        if kind == "prediction":  # one short segment per lane colour
            step = sample / min(3, len(LANE_COLOURS))
            for k in range(min(3, len(LANE_COLOURS))):
                a, b = (round(pad + k * step), mid), (round(pad + (k + 1) * step) - 1, mid)
                cv2.line(image, a, b, LANE_COLOURS[k], width, cv2.LINE_AA)
        elif kind == "truth":
            cv2.line(image, (pad, mid), (pad + sample, mid), GT_EDGE, gt_width(width) + 2 * gt_edge(width), cv2.LINE_AA)
            cv2.line(image, (pad, mid), (pad + sample, mid), GT_CORE, gt_width(width), cv2.LINE_AA)
        cv2.putText(image, text, (pad + indent[kind], y), _FONT, scale, (255, 255, 255), stroke, cv2.LINE_AA)
    return image


def label_strip(width: int, texts: Sequence[str], height: int, scale: float) -> np.ndarray:
    """A dark strip ``(height, width, 3)`` uint8 with ``texts`` written in equal columns (a grid's header), each
    at font ``scale`` or smaller where it would not fit its column."""
    strip = np.full((height, width, 3), 32, np.uint8)
    column = width / max(1, len(texts))
    for i, text in enumerate(texts):
        fit = scale
        stroke = 1 if fit < 0.6 else 2
        text_w = cv2.getTextSize(text, _FONT, fit, stroke)[0][0]
        if text_w > column - 16:
            fit = scale * (column - 16) / text_w
            stroke = 1 if fit < 0.6 else 2
        (_, text_h), _ = cv2.getTextSize(text, _FONT, fit, stroke)
        x, y = round(i * column) + 8, (height + text_h) // 2
        cv2.putText(strip, text, (x, y), _FONT, fit, (255, 255, 255), stroke, cv2.LINE_AA)
    return strip
