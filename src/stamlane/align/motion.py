"""A forward-motion prior for ``key_from_hist`` at low frame rates (the ``motion`` preset; issue 57).

At 5 fps a car at 12-28 m/s moves 2.4-5.6 m between frames: the road near the camera is 1.7-2.5x larger in the key
frame than in the history frame, beyond the 1.69x the key frame's feature pyramid covers, and the plain estimator
(`stamlane.align.homography.estimate_prepared`) fails on most pairs (``benchmarks/traffic_diagnosis.py``: within
2 px one frame back on 8-17 % of the 5 fps windows with vehicles, 42-67 % without). This module gives that estimator
a prior:

1. **The plain estimate** first; kept as it is when the tracking check confirms it strongly (at least
   `ACCEPT_RATIO` of the key frame's tracked corners agree), which is what happens at 20 fps.
2. **Pre-warped matching**: for each bottom-row scale ``s`` of ``AlignConfig.motion_scales``, the history frame is
   warped by `forward_motion` (the ground homography of a camera driving straight ahead, which grows the image row
   ``H - 1`` by ``s`` about the vanishing point) and the plain estimator matches the warped frame with the key frame:
   the residual motion is then within the pyramid's range. The candidate is the residual composed with the prior.
3. **The choice**: every candidate (the plain estimate included) is polished by `POLISH_ROUNDS` rounds of the
   Lucas-Kanade refinement (`stamlane.align.homography.refine_homography`) and scored by how many of the key frame's
   tracked corners agree with it; the most agreed wins. A homography locked on a vehicle is agreed by the corners on
   that vehicle alone, the road's by the rest of the ground region, so the agreement is the robust test of the
   ground-plane motion; a candidate agreed by fewer than ``min_track_ratio`` of the tracked corners is rejected.

Each pair is estimated from its own two frames (no state is carried from one pair to the next), so an estimate is
a function of the pair's pixels and the settings, as the pair cache (`stamlane.align.cache`) assumes.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from stamlane.align.homography import AlignConfig, Alignment, FramePrep, check_plausible, refine_homography

__all__ = ["ACCEPT_RATIO", "POLISH_ROUNDS", "VANISHING_OFFSET", "estimate_with_motion", "forward_motion"]

ACCEPT_RATIO = 0.6
"""A plain estimate that this share of the tracked corners agrees with is kept without the search: on 6 diagnosis
clips a kind at 20 fps the plain estimates within 2 px had 0.64-0.97 of 300 corners agreeing, one off by 5.8 px had
0.39 (dev clips, seed 57)."""

POLISH_ROUNDS = 2
"""Lucas-Kanade refinement rounds per candidate: a pre-warped match starts a few pixels off, beyond what one round of
the refinement's single pyramid level always closes; the second starts from the first's result."""

VANISHING_OFFSET = 0.03
"""The prior's vanishing row, as a fraction of the height above the ground region's first row: the synthetic
camera's horizon is at 0.42 H and the default ground region starts at 0.45 H. Only the prior depends on it: a
residual of the wrong vanishing row is a homography the matching stage recovers."""


def forward_motion(scale: float, shape: tuple[int, int], vanishing_row: float) -> np.ndarray:
    """``key_from_hist`` ``(3, 3)`` of the ground when the camera drives straight ahead: the image row ``H - 1``'s
    distance below the vanishing point ``((W - 1) / 2, vanishing_row)`` grows by ``scale``.

    A ground point ``d`` rows below the vanishing point lies at a depth proportional to ``1 / d``; driving ahead
    subtracts a constant from the depth, so ``1 / d`` grows by a constant ``c``: in coordinates centred on the
    vanishing point ``(x, y, 1) -> (x, y, 1 - c y)``, with ``c = (scale - 1) / (H - 1 - vanishing_row)``.

    Args:
        scale: growth of the bottom row's distance to the vanishing point, >= 1 (1: the identity).
        shape: ``(H, W)`` of the frames.
        vanishing_row: image row of the vanishing point, above ``H - 1``.
    """
    height, width = shape
    if scale < 1 or not vanishing_row < height - 1:
        raise ValueError(f"need scale >= 1 and vanishing_row < {height - 1}, got {scale}, {vanishing_row}")
    c = (scale - 1) / (height - 1 - vanishing_row)
    centre = np.array([[1, 0, -(width - 1) / 2], [0, 1, -vanishing_row], [0, 0, 1.0]])
    h = np.linalg.inv(centre) @ np.array([[1, 0, 0], [0, 1, 0], [0, -c, 1.0]]) @ centre
    normalised: np.ndarray = h / h[2, 2]
    return normalised


def _warped_prep(hist: FramePrep, key_from_hist: np.ndarray, cfg: AlignConfig) -> FramePrep:
    """The history frame warped by ``key_from_hist`` into the key frame's pixels, prepared (grey, its features)."""
    height, width = hist.shape
    full_from_crop = np.array([[1, 0, 0], [0, 1, hist.top], [0, 0, 1.0]])
    warped = cv2.warpPerspective(hist.gray, key_from_hist @ full_from_crop, (width, height), flags=cv2.INTER_LINEAR)
    return FramePrep(warped, hist.horizon_row, cfg)


def _polish(hist: FramePrep, key: FramePrep, start: np.ndarray, cfg: AlignConfig) -> tuple[np.ndarray | None, int, int]:
    """`POLISH_ROUNDS` rounds of the refinement from ``start``: ``(key_from_hist or None, agreeing, tracked)``."""
    h, agree, tracked = start, 0, 0
    for _ in range(POLISH_ROUNDS):
        refined, agree, tracked = refine_homography(hist, key, h, cfg)
        if refined is None or check_plausible(refined, key.shape, key.horizon_row, cfg):
            return None, agree, tracked
        h = refined
    return h, agree, tracked


def estimate_with_motion(hist: FramePrep, key: FramePrep, cfg: AlignConfig) -> Alignment:
    """``key_from_hist`` of two prepared frames with the forward-motion prior (the module's docstring); never raises.

    Args:
        hist: the history frame, prepared with ``cfg``.
        key: the key frame, prepared with ``cfg``, the same size.
        cfg: the settings; ``cfg.motion_scales`` the prior's bottom-row scales (empty: the plain estimate alone).

    Returns:
        the alignment; its ``num_matches`` / ``num_inliers`` are those of the chosen candidate's matching stage (of
        the pre-warped frame for a prior's). When no candidate is confirmed: the plain estimate's failure.
    """
    # the plain estimator, imported here: stamlane.align.homography calls this function from estimate_prepared
    from stamlane.align.homography import estimate_prepared

    plain_cfg = replace(cfg, motion_scales=())
    plain = estimate_prepared(hist, key, plain_cfg)
    found: list[tuple[int, np.ndarray, Alignment]] = []
    if plain.ok:
        h, agree, tracked = _polish(hist, key, plain.key_from_hist, cfg)
        if h is not None:
            if agree >= ACCEPT_RATIO * tracked:
                return replace(plain, key_from_hist=h)
            found.append((agree, h, plain))
    vanishing_row = key.horizon_row - VANISHING_OFFSET * key.shape[0]
    for scale in cfg.motion_scales:
        prior = forward_motion(scale, key.shape, vanishing_row)
        residual = estimate_prepared(_warped_prep(hist, prior, cfg), key, plain_cfg)
        if not residual.ok:
            continue
        start = residual.key_from_hist @ prior
        start = start / start[2, 2]
        if check_plausible(start, key.shape, key.horizon_row, cfg):
            continue
        h, agree, tracked = _polish(hist, key, start, cfg)
        if h is not None and agree >= cfg.min_track_ratio * tracked:
            found.append((agree, h, residual))
            if agree >= ACCEPT_RATIO * tracked:
                break  # as confirmed as a plain estimate that is kept: the larger scales would not be chosen
    if not found:
        return plain
    agree, h, source = max(found, key=lambda f: f[0])
    return Alignment(h, source.num_matches, source.num_inliers, True, "")
