"""Pseudo-labels that agree over a clip: a teacher's lane probabilities carried between frames by the ground plane.

`stamlane adapt` (`stamlane.training.adapt`) fine-tunes a model on a user's unlabelled video with labels made from
the model's own predictions. A single frame's prediction is kept or dropped by its confidence alone (CARLANE's
self-training baselines); a clip gives a second test that a single-frame detector lacks: lane paint lies on the
road, so the ground-plane homography that pre-aligns a history frame onto the key frame (`stamlane.align`, the
``key_from_hist`` of every sample) also carries that frame's lane probabilities onto the key frame's pixels. A pixel
is labelled where the key frame and its warped history agree:

- **lane** (1) where the key frame's probability is above ``hi`` and at least ``min_agree`` of the warped history
  frames are above ``hi`` there too (within ``tolerance_px``: a 1-px misregistration of a 3-px line is agreement);
- **background** (0) where the key frame and every warped history frame that sees the pixel are below ``lo``
  (within ``tolerance_px`` as well: a lane next to the pixel in any frame is no background);
- **ignored** (`IGNORE`) everywhere else: a lane one frame sees and another does not (a dash that came into view,
  a line through a vehicle that moved, flicker), the uncertain rim of every line, pixels no history frame sees.

numpy and OpenCV only (no torch): every map is ``(h, w)`` at the network's input size, each frame in its own
network pixels; homographies map history network pixels to key network pixels (``key_from_hist_net``,
`stamlane.data.transforms.net_homographies`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import cv2
import numpy as np

__all__ = ["IGNORE", "PseudoLabelConfig", "clip_pseudo_labels", "consistent_labels", "warp_probability"]

IGNORE = -1
"""The label of a pixel no loss sees (``F.cross_entropy(..., ignore_index=IGNORE)``)."""


@dataclass(frozen=True)
class PseudoLabelConfig:
    """When a teacher's lane probabilities become labels.

    Attributes:
        hi: a frame calls a pixel lane above this probability (the decoding's threshold is 0.5: a pseudo-label asks
            for more).
        lo: a frame calls a pixel background below this probability.
        min_agree: history frames (warped onto the key frame) that must call a lane pixel lane too; 0 is plain
            confidence thresholding of the key frame (the single-frame self-training of CARLANE's baselines).
        tolerance_px: network pixels a warped history frame may be off (its maximum over a square of this radius
            votes for lane, and is what must stay below ``lo`` for background).
    """

    hi: float = 0.7
    lo: float = 0.1
    min_agree: int = 2
    tolerance_px: int = 1

    def __post_init__(self) -> None:
        if not 0.0 <= self.lo < self.hi <= 1.0:
            raise ValueError(f"pseudo-label thresholds need 0 <= lo < hi <= 1, got lo={self.lo}, hi={self.hi}")
        if self.min_agree < 0:
            raise ValueError(f"min_agree must be >= 0, got {self.min_agree}")
        if self.tolerance_px < 0:
            raise ValueError(f"tolerance_px must be >= 0, got {self.tolerance_px}")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def warp_probability(prob: np.ndarray, key_from_hist: np.ndarray) -> np.ndarray:
    """A history frame's probability map in the key frame's pixels.

    Args:
        prob: ``(h, w)`` lane probability of the history frame, its own network pixels.
        key_from_hist: ``(3, 3)`` history -> key frame, network pixels.

    Returns:
        ``(h, w)`` float32: the warped probability, NaN where the history frame has no content (outside its view).
    """
    if prob.ndim != 2:
        raise ValueError(f"expected a probability map of shape (h, w), got {prob.shape}")
    if np.shape(key_from_hist) != (3, 3):
        raise ValueError(f"expected a 3x3 homography, got shape {np.shape(key_from_hist)}")
    h, w = prob.shape
    matrix = np.asarray(key_from_hist, dtype=np.float64)
    warped = cv2.warpPerspective(prob.astype(np.float32), matrix, (w, h), flags=cv2.INTER_LINEAR, borderValue=0.0)
    seen = cv2.warpPerspective(np.ones((h, w), np.float32), matrix, (w, h), flags=cv2.INTER_NEAREST, borderValue=0.0)
    warped[seen < 0.5] = np.nan
    return warped


def _spread(prob: np.ndarray, radius: int) -> np.ndarray:
    """The maximum of ``prob`` over a ``(2 radius + 1)``-px square (NaN, no view, stays NaN where every value is)."""
    if radius == 0:
        return prob
    kernel = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
    filled = np.where(np.isnan(prob), -1.0, prob).astype(np.float32)
    out = cv2.dilate(filled, kernel)
    return np.where(out < 0, np.nan, out)


def consistent_labels(key: np.ndarray, warped: np.ndarray, config: PseudoLabelConfig) -> np.ndarray:
    """The key frame's pseudo-labels from its probability and its history's, already in the key frame's pixels.

    Args:
        key: ``(h, w)`` lane probability of the key frame.
        warped: ``(K, h, w)`` lane probabilities of K history frames warped onto the key frame (`warp_probability`;
            NaN where a frame has no view), K >= 0.
        config: the thresholds.

    Returns:
        ``(h, w)`` int64: 1 lane, 0 background, `IGNORE` elsewhere (see the module docstring).
    """
    if key.ndim != 2 or warped.ndim != 3 or warped.shape[1:] != key.shape:
        raise ValueError(f"expected key (h, w) and warped (K, h, w) of one size, got {key.shape} and {warped.shape}")
    if config.min_agree > len(warped):
        raise ValueError(f"min_agree {config.min_agree} needs as many history frames, got {len(warped)}")
    spread = np.stack([_spread(frame, config.tolerance_px) for frame in warped]) if len(warped) else warped
    with np.errstate(invalid="ignore"):  # NaN (no view) compares False: it votes for neither
        votes = (spread > config.hi).sum(axis=0)
        quiet = ~(spread >= config.lo).any(axis=0)
    labels = np.full(key.shape, IGNORE, dtype=np.int64)
    labels[(key < config.lo) & quiet] = 0
    labels[(key > config.hi) & (votes >= config.min_agree)] = 1
    return labels


def clip_pseudo_labels(probs: np.ndarray, key_from_hist: np.ndarray, config: PseudoLabelConfig) -> np.ndarray:
    """Pseudo-labels of a clip's key frame.

    Args:
        probs: ``(T, h, w)`` lane probability of every frame of the clip, each in its own network pixels, key frame
            last (each frame predicted as the key frame of its own clip).
        key_from_hist: ``(T, 3, 3)`` history -> key frame, network pixels (the key frame's the identity).
        config: the thresholds.

    Returns:
        ``(h, w)`` int64 labels of the key frame (`consistent_labels`).
    """
    if probs.ndim != 3 or np.shape(key_from_hist) != (len(probs), 3, 3):
        raise ValueError(
            f"expected probs (T, h, w) and homographies (T, 3, 3), got {probs.shape} and {np.shape(key_from_hist)}"
        )
    hist = [warp_probability(probs[j], key_from_hist[j]) for j in range(len(probs) - 1)]
    warped = np.stack(hist) if hist else np.zeros((0, *probs.shape[1:]), np.float32)
    return consistent_labels(probs[-1], warped, config)
