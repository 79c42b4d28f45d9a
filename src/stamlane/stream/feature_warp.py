"""Feature-map warping for streaming; the implementation lives in `stamlane.models.feature_warp`.

It moved there so that training (`stamlane.module`, ``warp="feature"`` data) and streaming share one pure-torch
implementation without the model layer importing this package. The names stay importable from here.
"""

from stamlane.models.feature_warp import feat_from_net, feature_homography, sampling_grid, warp_features

__all__ = ["feat_from_net", "feature_homography", "sampling_grid", "warp_features"]
