"""Streaming inference (each frame encoded once, history aligned in feature space) and ONNX export.

``feature_warp``: image homographies applied to feature maps with ``grid_sample``.
``predictor``: `StreamingPredictor`, frame in -> lanes out, reusing the history's encoder features.
``export``: ONNX graphs of the per-frame encoder, of fusion + decoder, and of the whole clip model.
``cli``: ``stamlane stream VIDEO``.
"""

from stamlane.models.feature_warp import feat_from_net, feature_homography, sampling_grid, warp_features
from stamlane.stream.predictor import StreamingPredictor, StreamOutput, fuse_feature_aligned

__all__ = [
    "StreamOutput",
    "StreamingPredictor",
    "feat_from_net",
    "feature_homography",
    "fuse_feature_aligned",
    "sampling_grid",
    "warp_features",
]
