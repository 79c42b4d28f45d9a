"""`LaneNet` with history aligned in FEATURE space: every frame encoded once, history features warped.

The paper (3.1) warps history IMAGES onto the key frame before the encoder (``LaneNet.forward`` on a
pre-aligned clip). Here the frames reach the encoder unwarped and the same homographies are applied to the
deepest-stage feature maps of the history frames (`stamlane.models.feature_warp`), which are then fused with
the key frame's and decoded. This is what `stamlane.stream.StreamingPredictor` runs on a video (each frame
encoded once, its features cached), and what `stamlane.training.module.StamLaneModule` trains and evaluates on batches
of ``warp="feature"`` data (``key_from_hist_net`` in the batch), so that a model is trained in the alignment
space it is run in. With identity homographies both spaces give the same result.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor

from stamlane.models.feature_warp import warp_features
from stamlane.models.lanenet import LaneNet

__all__ = ["forward_feature_aligned", "fuse_feature_aligned"]


def fuse_feature_aligned(
    net: LaneNet,
    key_feats: Sequence[Tensor],
    hist_feats: Tensor,
    key_from_hist: np.ndarray | Tensor | None,
    stride: int,
    net_from_orig: np.ndarray | None = None,
) -> tuple[Tensor, Tensor]:
    """Warp history features onto the key frame, fuse and decode.

    Args:
        net: the network (``fuse_and_decode`` is used).
        key_feats: the key frames' per-stage features, shallow first, each ``(B, C_i, h_i, w_i)``.
        hist_feats: deepest-stage features of the history frames, ``(B, T-1, C, h, w)``, oldest first.
        key_from_hist: ``(B, T-1, 3, 3)`` homographies history -> key (network pixels, or original pixels with
            ``net_from_orig``); ``None`` = no alignment. Exact identities are skipped (no resampling).
        stride: stride of the deepest stage.
        net_from_orig: ``(3, 3)`` original -> network pixels, or ``None``.

    Returns:
        ``(logits (B, 2, H, W), embedding (B, E, H, W))``.
    """
    if hist_feats.ndim != 5:
        raise ValueError(f"expected hist_feats of shape (B, T-1, C, h, w), got {tuple(hist_feats.shape)}")
    key_last = key_feats[-1]
    batch, num_hist = hist_feats.shape[:2]
    if key_from_hist is not None and num_hist:
        mats = torch.as_tensor(np.asarray(key_from_hist) if isinstance(key_from_hist, np.ndarray) else key_from_hist)
        mats = mats.detach().to(device="cpu", dtype=torch.float64)
        if mats.numel() != batch * num_hist * 9:
            raise ValueError(f"expected key_from_hist of shape ({batch}, {num_hist}, 3, 3), got {tuple(mats.shape)}")
        mats = mats.reshape(batch * num_hist, 3, 3)
        flat = hist_feats.flatten(0, 1)
        moving = torch.nonzero(~(mats == torch.eye(3, dtype=torch.float64)).all(dim=(1, 2))).flatten()
        if len(moving):
            warped = warp_features(flat[moving], mats[moving], stride, net_from_orig=net_from_orig)
            flat = flat.clone()
            flat[moving] = warped
        hist_feats = torch.unflatten(flat, 0, (batch, num_hist))
    last = torch.cat([hist_feats, key_last[:, None]], dim=1)
    return net.fuse_and_decode(last, key_feats[:-1])


def forward_feature_aligned(net: LaneNet, clip: Tensor, key_from_hist: Tensor | np.ndarray) -> tuple[Tensor, Tensor]:
    """Detect lanes in the key frame of unaligned clips, the history aligned in feature space.

    The encoder runs once on all ``B * T`` frames (as in ``LaneNet.forward``); the history frames' deepest-stage
    features are warped onto the key frame with `fuse_feature_aligned`; the decoder gets the key frame's skips.

    Args:
        net: the network; its encoder has ``strides`` (the deepest stride is the fusion grid's).
        clip: frames, ``(B, T, 3, H, W)`` float in [0, 1], key frame last, history NOT warped (same crop, scale
            and flip as the key frame, i.e. ``warp="feature"`` data).
        key_from_hist: ``(B, T, 3, 3)`` homographies history -> key in NETWORK-input pixels, key frame last (its
            own entry, the identity, is not used); exact identities are not resampled.

    Returns:
        ``(logits (B, 2, H, W), embedding (B, E, H, W))`` at input resolution.

    Raises:
        ValueError: on a clip that is not 5-d, homographies not of shape ``(B, T, 3, 3)``, an encoder without
            ``strides``.
    """
    if clip.ndim != 5:
        raise ValueError(f"expected a clip of shape (B, T, 3, H, W), got {tuple(clip.shape)}")
    batch, num_frames = clip.shape[:2]
    if tuple(key_from_hist.shape) != (batch, num_frames, 3, 3):
        raise ValueError(
            f"expected key_from_hist of shape ({batch}, {num_frames}, 3, 3) for a clip of shape "
            f"{tuple(clip.shape)}, got {tuple(key_from_hist.shape)}"
        )
    strides = getattr(net.encoder, "strides", None)
    if not strides:
        raise ValueError(f"net.encoder must have a strides attribute, got {type(net.encoder).__name__}")
    feats = net.encode(clip.flatten(0, 1))
    per_clip = [torch.unflatten(f, 0, (batch, num_frames)) for f in feats]
    key_feats = [f[:, -1] for f in per_clip]
    return fuse_feature_aligned(net, key_feats, per_clip[-1][:, :-1], key_from_hist[:, :-1], int(strides[-1]))
