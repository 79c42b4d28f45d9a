"""Streaming inference (each frame encoded once, history aligned in feature space) and ONNX export.

``predictor``: `StreamingPredictor`, frame in -> lanes out, reusing the history's encoder features.
``export``: ONNX graphs of the per-frame encoder, of fusion + decoder, and of the whole clip model;
``metadata``: what they carry about their preprocessing and decoding; ``export_cli``: ``stamlane export``.
``cli``: ``stamlane stream VIDEO``.

The feature warp (image homographies applied to feature maps with ``grid_sample``) lives in
`stamlane.models.feature_warp`; its names stay importable from here.

The names are imported on first use, so that ``stamlane stream`` and ``stamlane export`` check their arguments
(a missing file, the missing ``export`` extra) before torch is imported.
"""

from __future__ import annotations

import importlib
from typing import Any

_HOMES = {
    "StreamOutput": "stamlane.stream.predictor",
    "StreamingPredictor": "stamlane.stream.predictor",
    "fuse_feature_aligned": "stamlane.stream.predictor",
    "feat_from_net": "stamlane.models.feature_warp",
    "feature_homography": "stamlane.models.feature_warp",
    "sampling_grid": "stamlane.models.feature_warp",
    "warp_features": "stamlane.models.feature_warp",
}

__all__ = [
    "StreamOutput",
    "StreamingPredictor",
    "feat_from_net",
    "feature_homography",
    "fuse_feature_aligned",
    "sampling_grid",
    "warp_features",
]


def __getattr__(name: str) -> Any:
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_HOMES[name]), name)
