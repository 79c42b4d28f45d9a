"""Ground-plane homography ``key_from_hist`` between two frames (paper 3.1).

Two stages, both on the ground region below ``horizon_row``:

1. **Match** (the paper's method): evenly spread ORB features of the history frame against those of the
   key frame on a small scale pyramid (the key frame sees the road from closer, so its level ``s``
   matches the history's level 1), Hamming cross-check matching, RANSAC homography, plausibility checks.
   Done at ``working_scale`` (half resolution by default, but never narrower than ``min_working_width``) for
   speed.
2. **Refine** (ours, for sub-pixel accuracy): warp the history frame with the stage-1 homography, track
   the key frame's spread corners into it with pyramidal Lucas-Kanade at full resolution (the residual
   motion is now small and nearly scale-free), and compose the residual RANSAC homography.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import cv2
import numpy as np

from stamlane.align.features import FeatureConfig, Features, concat_features, detect_pyramid_features, to_gray

__all__ = [
    "ALIGN_PRESETS",
    "DEFAULT_HORIZON_FRACTION",
    "AlignConfig",
    "Alignment",
    "FramePrep",
    "align_preset",
    "check_image",
    "check_plausible",
    "default_horizon_row",
    "estimate_homography",
    "estimate_prepared",
    "fit_homography",
    "ground_corners",
    "match_features",
    "refine_homography",
    "resolve_horizon_row",
]

DEFAULT_HORIZON_FRACTION = 0.45
"""Default horizon row as a fraction of the height: 0.45 * 720 = 324 on TuSimple, 40-60 px below its
vanishing line (rows 260-290), so that only road, not sky or far-away objects, feeds the homography."""


@dataclass(frozen=True)
class AlignConfig:
    """How ``key_from_hist`` is estimated.

    Attributes:
        features: evenly spread feature settings at ``working_scale`` (cell 15 px there = 30 px at full size).
        working_scale: resize factor of the matching stage (0.5: half resolution).
        min_working_width: the matching stage never shrinks a frame below this width (the scale used is
            ``max(working_scale, min(1, min_working_width / W))``): half of a 1280-wide TuSimple frame is 640 px,
            but half of a 640-wide frame leaves too little texture to match 1-3 m of forward motion
            (measured on 640x360 clips in ``benchmarks/synth_align.py``). 0: always ``working_scale``.
        key_scales: pyramid shrink factors of the key frame's features (the history frame uses level 1).
        max_hamming: largest Hamming distance (of 256 bits) of a kept match.
        ratio: Lowe's ratio test on two nearest neighbours; ``None`` uses a cross check instead.
        ransac_threshold: RANSAC reprojection threshold of the matching stage, full-size pixels.
        min_matches: fewest matches to try RANSAC at all.
        min_inliers: fewest RANSAC inliers to accept the homography.
        refine: run the Lucas-Kanade refinement stage.
        refine_scale: resize factor of the refinement stage (1: full resolution).
        lk_window: Lucas-Kanade window side, full-size pixels.
        max_track_points: most key-frame corners tracked by the refinement.
        min_track_ratio: fewest tracked corners, as a fraction, that must agree with the refined homography
            (the check that catches a confidently wrong stage-1 fit; 0 disables it).
        refine_threshold: RANSAC threshold of the refinement, pixels.
        max_scale: largest scale change (either way) of the ground region's area and of each side.
        max_displacement: largest shift of a ground-region corner as a fraction of the image width.
        max_models: homographies tried per pair: when the tracking check rejects a fit (or it is implausible),
            its RANSAC inliers are set aside and the rest of the matches are fitted again (sequential RANSAC:
            a car driving ahead is a second, wrong "plane" that can outvote the road). 1: one fit only.
        motion_scales: the forward-motion prior of low frame rates (`stamlane.align.motion`, the ``motion`` preset):
            the bottom-row scales, each >= 1, at which the history frame is pre-warped and matched again when the
            plain estimate is not strongly confirmed; the candidates compete on tracked-corner agreement.
            Empty (the default): the plain estimate alone.
        ground_sign: `check_plausible` reads the homography's sign and scale at the ground region's corner farthest
            from the line at infinity instead of at the image origin. The origin lies above the horizon: after 10 m
            or more of driving (two frames back at 5 fps) it can lie beyond the line at infinity of ``hist_from_key``
            while the whole ground region lies before it, and the default test then rejects the true homography as
            "perspective too strong" (docs/alignment.md counts the generator's own). False (the default): the
            origin's, as every result so far was made with.
    """

    features: FeatureConfig = field(default_factory=lambda: FeatureConfig(cell_size=15, max_features=300))
    working_scale: float = 0.5
    min_working_width: int = 640
    key_scales: tuple[float, ...] = (1.0, 1.3, 1.69)
    max_hamming: int = 64
    ratio: float | None = None
    ransac_threshold: float = 3.0
    min_matches: int = 15
    min_inliers: int = 10
    refine: bool = True
    refine_scale: float = 1.0
    lk_window: int = 21
    max_track_points: int = 300
    min_track_ratio: float = 0.5
    refine_threshold: float = 1.0
    max_scale: float = 3.0
    max_displacement: float = 0.5
    max_models: int = 3
    motion_scales: tuple[float, ...] = ()
    ground_sign: bool = False

    def __post_init__(self) -> None:
        if any(not np.isfinite(s) or not 1 <= s <= 8 for s in self.motion_scales):
            raise ValueError(f"motion_scales must each be in [1, 8], got {self.motion_scales}")
        if not 0.1 <= self.refine_scale <= 1:
            raise ValueError(f"refine_scale must be in [0.1, 1], got {self.refine_scale}")
        if not 0.1 <= self.working_scale <= 1:
            raise ValueError(f"working_scale must be in [0.1, 1], got {self.working_scale}")
        if self.min_working_width < 0:
            raise ValueError(f"min_working_width must be >= 0, got {self.min_working_width}")
        if not self.key_scales or min(self.key_scales) < 1:
            raise ValueError(f"key_scales must be non-empty and >= 1, got {self.key_scales}")
        if self.ratio is not None and not 0 < self.ratio <= 1:
            raise ValueError(f"ratio must be in (0, 1] or None, got {self.ratio}")
        if self.max_models < 1:
            raise ValueError(f"max_models must be >= 1, got {self.max_models}")
        if self.min_inliers < 4 or self.min_matches < 4:
            raise ValueError(f"min_matches and min_inliers must be >= 4, got {self.min_matches}, {self.min_inliers}")

    def __repr__(self) -> str:
        # the dataclass's own repr, without the fields added for the motion preset while they are off: the pair cache
        # names an entry by the settings' repr (`stamlane.align.cache.pair_key`), so the presets made before keep theirs
        shown = [f for f in fields(self) if f.name not in ("motion_scales", "ground_sign") or getattr(self, f.name)]
        return f"{type(self).__qualname__}({', '.join(f'{f.name}={getattr(self, f.name)!r}' for f in shown)})"


ALIGN_PRESETS: dict[str, AlignConfig] = {
    "standard": AlignConfig(),
    "fast": AlignConfig(key_scales=(1.0,), max_track_points=150),
    "motion": AlignConfig(motion_scales=(1.4, 1.8, 2.4), ground_sign=True, max_scale=5.0, max_displacement=0.75),
}
"""Named `AlignConfig` settings, chosen by ``data.clip.align_preset`` and ``stamlane stream --align-preset``
(``stamlane align`` writes ``standard``'s). ``standard``: every setting's default, what every shipped model and result was made
with. ``fast``: the key frame's features at one scale (no pyramid) and 150 tracked corners instead of 300; faster
on real-frame pairs with the same median corner error and success (`benchmarks/align_presets.py`, measured in
docs/alignment.md).
Its homographies differ from ``standard``'s, so a model's numbers change slightly with it: opt in. ``motion``:
``standard`` with the forward-motion prior of low frame rates (`stamlane.align.motion`; bottom-row scales 1.4 / 1.8
/ 2.4 span the 2.4-5.6 m a frame of 5 fps driving) and the ground region's sign in the plausibility check (which
lets a chain 2-3 frames back at 5 fps through), for 5 fps clips and traffic (docs/alignment.md); slower where the
plain estimate is not confirmed."""


def align_preset(name: str) -> AlignConfig:
    """The `ALIGN_PRESETS` entry ``name``.

    Raises:
        ValueError: for a name that is not one, listing those that are.
    """
    if name not in ALIGN_PRESETS:
        raise ValueError(f"align preset must be one of {tuple(ALIGN_PRESETS)}, got {name!r}")
    return ALIGN_PRESETS[name]


@dataclass
class Alignment:
    """Where a history frame lies in the key frame.

    Attributes:
        key_from_hist: ``(3, 3)`` float64 homography mapping history pixels to key pixels (identity on failure).
        num_matches: descriptor matches that went into RANSAC.
        num_inliers: RANSAC inliers among those matches.
        ok: whether the homography was estimated and passed the plausibility checks.
        reason: empty when ``ok``; otherwise why the identity was returned.
        extrapolated: the homography was not matched but composed from the clip's other frame pairs under
            constant motion (`stamlane.align.warp.alignments_to_key`: a frame pair that failed, e.g. on a frame
            washed out by glare, takes the motion of the nearest pair that matched).
    """

    key_from_hist: np.ndarray = field(default_factory=lambda: np.eye(3))
    num_matches: int = 0
    num_inliers: int = 0
    ok: bool = False
    reason: str = ""
    extrapolated: bool = False

    @classmethod
    def failed(cls, reason: str, num_matches: int = 0, num_inliers: int = 0) -> Alignment:
        """The identity with ``ok=False`` and ``reason``."""
        return cls(np.eye(3), int(num_matches), int(num_inliers), False, reason)


def default_horizon_row(height: int) -> int:
    """``DEFAULT_HORIZON_FRACTION * height`` rounded to a row."""
    return round(DEFAULT_HORIZON_FRACTION * height)


def check_image(image: object, name: str) -> np.ndarray:
    """Raise ``ValueError`` unless ``image`` is a uint8 ``(H, W)``, ``(H, W, 1)`` or ``(H, W, 3)`` array, >= 64x64."""
    if not isinstance(image, np.ndarray):
        raise ValueError(f"{name} must be a numpy array, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise ValueError(f"{name} must be uint8, got dtype {image.dtype}")
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (1, 3))):
        raise ValueError(f"{name} must be (H, W), (H, W, 1) or (H, W, 3), got shape {image.shape}")
    if image.shape[0] < 64 or image.shape[1] < 64:
        raise ValueError(f"{name} must be at least 64x64 pixels, got shape {image.shape}")
    return image


def resolve_horizon_row(horizon_row: int | None, height: int) -> int:
    """Check ``horizon_row`` against an image ``height`` (``None``: the default fraction)."""
    if horizon_row is None:
        return default_horizon_row(height)
    if isinstance(horizon_row, bool) or not isinstance(horizon_row, (int, np.integer)):
        raise ValueError(f"horizon_row must be an int or None, got {horizon_row!r}")
    if not 0 <= horizon_row <= height - 32:
        raise ValueError(
            f"horizon_row must be in [0, {height - 32}] for an image of height {height}, got {horizon_row}"
        )
    return int(horizon_row)


def ground_corners(shape: tuple[int, int], horizon_row: int) -> np.ndarray:
    """The ground region's corners ``(4, 2)`` float64 ``(x, y)``: top-left, top-right, bottom-right, bottom-left."""
    height, width = shape
    return np.array([[0, horizon_row], [width - 1, horizon_row], [width - 1, height - 1], [0, height - 1]], float)


class FramePrep:
    """One frame's grey images and features, computed once and shared by every pair it takes part in.

    Attributes:
        gray: ``(H - top, W)`` uint8 grey rows ``top:`` of the frame (the ground region and a margin).
        scale: resize factor of the matching stage for this frame's width (see ``AlignConfig.min_working_width``).
        small: ``gray`` resized by ``scale``.

    Args:
        image: uint8 ``(H, W, 3)`` BGR or ``(H, W)`` grey (checked by the caller).
        horizon_row: first row of the ground region in ``image``.
        cfg: the estimation settings.
    """

    def __init__(self, image: np.ndarray, horizon_row: int, cfg: AlignConfig) -> None:
        self.shape: tuple[int, int] = image.shape[:2]
        self.horizon_row = horizon_row
        self.cfg = cfg
        # only the ground region (and a margin for descriptor patches and LK windows) is ever read
        self.top = max(horizon_row - 40, 0)
        self.gray = to_gray(image[self.top :])
        s = max(cfg.working_scale, min(1.0, cfg.min_working_width / image.shape[1]))
        self.scale = s
        self.small = self.gray if s == 1 else cv2.resize(self.gray, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
        self._levels: dict[float, Features] = {}
        self._normalized: dict[float, np.ndarray] = {}

    def normalized_at(self, scale: float) -> np.ndarray:
        """``gray`` resized by ``scale`` with the ground region's mean and contrast fixed (Lucas-Kanade
        assumes constant brightness); ``(round(scale * (H - top)), round(scale * W))`` uint8."""
        if scale not in self._normalized:
            if scale == 1:
                image = self.gray
            elif scale == self.scale:
                image = self.small
            else:
                image = cv2.resize(self.gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
            ground = image[round((self.horizon_row - self.top) * scale) :]
            mean, std = cv2.meanStdDev(ground)
            gain = 40.0 / max(float(std[0, 0]), 1.0)
            self._normalized[scale] = cv2.convertScaleAbs(image, alpha=gain, beta=128.0 - gain * float(mean[0, 0]))
        return self._normalized[scale]

    def features(self, scales: tuple[float, ...] = (1.0,)) -> Features:
        """Spread features on pyramid ``scales`` of the working image, points ``(N, 2)`` in full-size pixels.

        Levels are computed once each: the frame's level 1 serves both as a history frame and as a key frame.
        """
        s = self.scale
        for scale in scales:
            if scale not in self._levels:
                row = round((self.horizon_row - self.top) * s)
                feats = detect_pyramid_features(self.small, row, (scale,), self.cfg.features)
                feats.points = feats.points / np.float32(s) + np.array([0, self.top], np.float32)
                self._levels[scale] = feats
        return concat_features([self._levels[scale] for scale in scales])


def match_features(hist: Features, key: Features, cfg: AlignConfig | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Hamming matches between two feature sets.

    Returns:
        matched points ``(M, 2)`` float32 in the history frame and ``(M, 2)`` in the key frame.
    """
    cfg = cfg or AlignConfig()
    empty = np.zeros((0, 2), np.float32)
    if len(hist) < 2 or len(key) < 2:
        return empty, empty
    if cfg.ratio is None:
        matches = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True).match(hist.descriptors, key.descriptors)
    else:
        pairs = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(hist.descriptors, key.descriptors, k=2)
        matches = [p[0] for p in pairs if len(p) == 2 and p[0].distance < cfg.ratio * p[1].distance]
    matches = [m for m in matches if m.distance <= cfg.max_hamming]
    if not matches:
        return empty, empty
    qi = np.fromiter((m.queryIdx for m in matches), np.int64, len(matches))
    ti = np.fromiter((m.trainIdx for m in matches), np.int64, len(matches))
    return hist.points[qi], key.points[ti]


def check_plausible(
    key_from_hist: np.ndarray, shape: tuple[int, int], horizon_row: int, cfg: AlignConfig | None = None
) -> str:
    """Why ``key_from_hist`` cannot be an ego-motion of the ground plane, or ``""`` when it can.

    The key frame's ground region is mapped into the history frame (``hist_from_key``, what warping
    samples). Rejected: a non-finite or singular matrix, a region that crosses the line at infinity, a
    mirror image (negative determinant), a non-convex image of the region (extreme shear/perspective),
    area or side scale beyond ``cfg.max_scale`` either way, a corner shift beyond ``cfg.max_displacement``
    of the width.
    """
    cfg = cfg or AlignConfig()
    h: np.ndarray = np.asarray(key_from_hist, np.float64)
    if h.shape != (3, 3) or not np.all(np.isfinite(h)):
        return "non-finite homography"
    if abs(np.linalg.det(h)) < 1e-12:
        return "singular homography"
    h = np.linalg.inv(h)  # hist_from_key
    corners = ground_corners(shape, horizon_row)
    scale = h[2, 2]  # the sign and scale the test of w below reads: the image origin's w
    if cfg.ground_sign:  # the ground region's own: its corner farthest from the line at infinity
        w = corners @ h[2, :2] + h[2, 2]
        scale = w[np.argmax(np.abs(w))]
    if abs(scale) < 1e-12:
        return "singular homography"
    h = h / scale
    w = corners @ h[2, :2] + h[2, 2]
    if np.any(w <= 1e-3):
        return "perspective too strong: the ground region crosses the line at infinity"
    mapped = (corners @ h[:2, :2].T + h[:2, 2]) / w[:, None]
    edges = np.roll(mapped, -1, axis=0) - mapped
    nxt = np.roll(edges, -1, axis=0)
    turn = edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0]  # all > 0: convex, same orientation as the input
    if np.all(turn < 0):
        return "mirror image (negative determinant)"
    if not np.all(turn > 0):
        return "ground region maps to a non-convex quadrilateral (extreme shear or perspective)"

    def area(q: np.ndarray) -> float:
        return 0.5 * abs(float(np.dot(q[:, 0], np.roll(q[:, 1], -1)) - np.dot(q[:, 1], np.roll(q[:, 0], -1))))

    ratio = area(mapped) / area(corners)
    if not 1 / cfg.max_scale**2 <= ratio <= cfg.max_scale**2:
        return f"extreme scale: ground area x{ratio:.3g}"
    sides = np.linalg.norm(edges, axis=1) / np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1)
    if np.any(sides > cfg.max_scale) or np.any(sides < 1 / cfg.max_scale):
        return f"extreme scale or shear: side lengths x{np.round(sides, 2).tolist()}"
    shift = float(np.linalg.norm(mapped - corners, axis=1).max())
    if shift > cfg.max_displacement * shape[1]:
        return f"implausible motion: a ground corner moves {shift:.0f} px"
    return ""


def refine_homography(
    hist: FramePrep, key: FramePrep, key_from_hist: np.ndarray, cfg: AlignConfig
) -> tuple[np.ndarray | None, int, int]:
    """Lucas-Kanade refinement: ``(key_from_hist, agreeing corners, tracked corners)``; ``key_from_hist`` is
    ``None`` when it cannot be done. A corner agrees when the refined homography puts it within 3 px of
    where it was tracked.

    The history frame is warped onto the key frame with the stage-1 homography, so the remaining motion
    between the two is a few pixels and nearly free of scale change; the key frame's spread corners are
    tracked into the warped frame and the residual homography is composed with the stage-1 one. Runs on
    the frames resized by ``cfg.refine_scale``.
    """
    s = cfg.refine_scale
    points = key.features().points
    points = points[points[:, 1] >= key.horizon_row]
    if len(points) > cfg.max_track_points:  # an even subset of the (already evenly spread) corners
        points = points[np.linspace(0, len(points) - 1, cfg.max_track_points).astype(np.int64)]
    if len(points) < cfg.min_inliers:
        return None, 0, len(points)
    # scaled crop pixels (what ``FramePrep.normalized_at`` holds) <- full-size pixels, for each frame
    key_from_full = np.array([[s, 0, 0], [0, s, -s * key.top], [0, 0, 1.0]])
    hist_from_full = np.array([[s, 0, 0], [0, s, -s * hist.top], [0, 0, 1.0]])
    warp = key_from_full @ key_from_hist @ np.linalg.inv(hist_from_full)
    target = key.normalized_at(s)
    warped = cv2.warpPerspective(hist.normalized_at(s), warp, target.shape[::-1], flags=cv2.INTER_LINEAR)
    points = (points * np.float32(s) - np.array([0, s * key.top], np.float32)).reshape(-1, 1, 2)
    side = max(round(cfg.lk_window * s) | 1, 7)
    # the stub wants an array for nextPts; OpenCV takes None (an output unless OPTFLOW_USE_INITIAL_FLOW)
    moved, status, _ = cv2.calcOpticalFlowPyrLK(target, warped, points, None, winSize=(side, side), maxLevel=1)  # type: ignore[call-overload]
    good = status.ravel() == 1
    tracked = len(points)
    if good.sum() < cfg.min_inliers:
        return None, int(good.sum()), tracked
    residual, mask = cv2.findHomography(
        moved.reshape(-1, 2)[good], points.reshape(-1, 2)[good], cv2.RANSAC, cfg.refine_threshold * s
    )
    if residual is None or mask is None or mask.sum() < cfg.min_inliers:
        return None, 0 if mask is None else int(mask.sum()), tracked
    # agreement for the confirmation check, at a looser tolerance than the fit (3 px, full size)
    predicted = cv2.perspectiveTransform(moved[good].astype(np.float64), residual).reshape(-1, 2)
    agree = int((np.linalg.norm(predicted - points.reshape(-1, 2)[good], axis=1) < 3.0 * s).sum())
    h = np.linalg.inv(key_from_full) @ residual @ key_from_full @ key_from_hist
    return h / h[2, 2], agree, tracked


def fit_homography(
    src: np.ndarray, dst: np.ndarray, shape: tuple[int, int], horizon_row: int, cfg: AlignConfig | None = None
) -> Alignment:
    """RANSAC homography ``dst <- src`` from matched points, checked for plausibility; never raises.

    Args:
        src: ``(M, 2)`` matched points in the history frame.
        dst: ``(M, 2)`` the same points in the key frame.
        shape: ``(H, W)`` of the frames.
        horizon_row: first row of the ground region.
        cfg: thresholds.
    """
    return _fit(src, dst, shape, horizon_row, cfg or AlignConfig())[0]


def _fit(
    src: np.ndarray, dst: np.ndarray, shape: tuple[int, int], horizon_row: int, cfg: AlignConfig
) -> tuple[Alignment, np.ndarray | None]:
    """``fit_homography`` and the RANSAC inlier mask ``(M,)`` bool (None when RANSAC did not run or found nothing)."""
    n = len(src)
    if n < cfg.min_matches:
        return Alignment.failed(f"too few matches: {n} < {cfg.min_matches}", n), None
    # USAC_ACCURATE (GC-RANSAC with local optimisation): on the pairs of benchmarks/align.py it was faster than
    # cv2.RANSAC at the low inlier ratios of pyramid matching, and more accurate on weak texture (docs/results/timings/)
    h, mask = cv2.findHomography(src, dst, cv2.USAC_ACCURATE, cfg.ransac_threshold, maxIters=2000, confidence=0.999)
    if h is None or mask is None:
        return Alignment.failed("RANSAC found no homography (degenerate matches)", n), None
    inliers = int(mask.sum())
    mask = mask.ravel().astype(bool)
    if inliers < cfg.min_inliers:
        return Alignment.failed(f"too few inliers: {inliers} < {cfg.min_inliers}", n, inliers), mask
    reason = check_plausible(h, shape, horizon_row, cfg)
    if reason:
        return Alignment.failed(reason, n, inliers), mask
    return Alignment(h / h[2, 2], n, inliers, True, ""), mask


def estimate_prepared(hist: FramePrep, key: FramePrep, cfg: AlignConfig | None = None) -> Alignment:
    """``key_from_hist`` between two prepared frames of one size; never raises (see ``estimate_homography``)."""
    cfg = cfg or AlignConfig()
    if cfg.motion_scales:
        from stamlane.align.motion import estimate_with_motion  # it calls back here with motion_scales=()

        return estimate_with_motion(hist, key, cfg)
    fh, fk = hist.features(), key.features(cfg.key_scales)
    if len(fh) < 4 or len(fk) < 4:
        return Alignment.failed(f"too few features: {len(fh)} in history, {len(fk)} in key (textureless?)")
    src, dst = match_features(fh, fk, cfg)
    first: Alignment | None = None
    for _ in range(cfg.max_models):
        alignment, mask = _fit(src, dst, key.shape, key.horizon_row, cfg)
        if alignment.ok and cfg.refine:
            refined, agree, tracked = refine_homography(hist, key, alignment.key_from_hist, cfg)
            if refined is None or agree < cfg.min_track_ratio * tracked:
                # a wrong homography (e.g. locked on a car driving ahead, or on self-similar lane lines) leaves
                # the warped frame unlike the key frame, and few corners track consistently
                reason = f"not confirmed by tracking: {agree} of {tracked} corners agree"
                alignment = Alignment.failed(reason, alignment.num_matches, alignment.num_inliers)
            elif not check_plausible(refined, key.shape, key.horizon_row, cfg):
                alignment.key_from_hist = refined
        if alignment.ok:
            return alignment
        first = first or alignment
        if mask is None or alignment.num_inliers < cfg.min_inliers:
            break  # nothing was fitted, or too little to set aside: another fit would not differ
        src, dst = src[~mask], dst[~mask]  # set the rejected model's inliers aside and fit the rest
    assert first is not None, "max_models >= 1 (AlignConfig checks it): the loop fitted at least once"
    return first


def estimate_homography(
    hist: np.ndarray, key: np.ndarray, *, horizon_row: int | None = None, config: AlignConfig | None = None
) -> Alignment:
    """Estimate the ground-plane homography from a history frame to the key frame.

    Args:
        hist: history frame, uint8 ``(H, W, 3)`` BGR or ``(H, W)`` grey.
        key: key frame, same size as ``hist``.
        horizon_row: first image row of the ground region; default ``round(0.45 * H)``.
        config: estimation settings.

    Returns:
        the alignment; on textureless, black, blurred or unmatched frames, or an implausible fit, the
        identity with ``ok=False`` and the reason. Never raises on a valid image.

    Raises:
        ValueError: on a non-uint8 or wrongly shaped image, different sizes, or a bad ``horizon_row``.
    """
    check_image(hist, "hist")
    check_image(key, "key")
    if hist.shape[:2] != key.shape[:2]:
        raise ValueError(f"hist and key must have the same size, got {hist.shape} and {key.shape}")
    cfg = config or AlignConfig()
    row = resolve_horizon_row(horizon_row, key.shape[0])
    return estimate_prepared(FramePrep(hist, row, cfg), FramePrep(key, row, cfg), cfg)
