"""Pre-alignment (paper 3.1): evenly spread ORB features, a RANSAC ground-plane homography ``key_from_hist``,
history frames warped onto the key frame; and the one camera model of stamlane (`stamlane.align.camera`: a pinhole
over a flat road, which the synthetic generator renders with and `stamlane.align.egomotion` takes exact homographies
from). numpy/OpenCV only (no torch), so data loading and the ``stamlane align`` command start fast."""

from stamlane.align.features import FeatureConfig, Features, detect_plain_orb, detect_spread_features
from stamlane.align.homography import (
    ALIGN_PRESETS,
    DEFAULT_HORIZON_FRACTION,
    AlignConfig,
    Alignment,
    align_preset,
    check_plausible,
    default_horizon_row,
    estimate_homography,
)
from stamlane.align.warp import align_clip, chain_alignments, estimate_clip, warp_to_key

__all__ = [
    "ALIGN_PRESETS",
    "DEFAULT_HORIZON_FRACTION",
    "AlignConfig",
    "Alignment",
    "FeatureConfig",
    "Features",
    "align_clip",
    "align_preset",
    "chain_alignments",
    "check_plausible",
    "default_horizon_row",
    "detect_plain_orb",
    "detect_spread_features",
    "estimate_clip",
    "estimate_homography",
    "warp_to_key",
]
