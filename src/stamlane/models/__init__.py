"""The network: VGG16 encoder, STAM and the Table 4 aggregators, the two-branch decoder (pure torch); the
feature-space alignment of history frames (`forward_feature_aligned`, `warp_features`).

This package never imports ``stamlane.data``, ``stamlane.training.module`` or lightning.
"""

from stamlane.models.aggregators import STPSA, ConvLSTMFusion, CosineWeightedSum, KeyFrameOnly, SimpleAdd, STDANet
from stamlane.models.attention import ChannelAttention, SpatialAttention
from stamlane.models.decoder import LaneDecoder
from stamlane.models.encoder import VGGEncoder
from stamlane.models.feature_aligned import forward_feature_aligned, fuse_feature_aligned
from stamlane.models.feature_warp import warp_features
from stamlane.models.lanenet import LaneNet
from stamlane.models.stam import STAM

__all__ = [
    "STAM",
    "STPSA",
    "ChannelAttention",
    "ConvLSTMFusion",
    "CosineWeightedSum",
    "KeyFrameOnly",
    "LaneDecoder",
    "LaneNet",
    "STDANet",
    "SimpleAdd",
    "SpatialAttention",
    "VGGEncoder",
    "forward_feature_aligned",
    "fuse_feature_aligned",
    "warp_features",
]
