"""Input check shared by the fusion modules (private)."""

from __future__ import annotations

import torch
from torch import Tensor

__all__ = ["check_clip_features"]


def check_clip_features(feats: Tensor, channels: int) -> None:
    """Raise ValueError unless ``feats`` is (B, T, channels, h, w) with T >= 1."""
    if torch.jit.is_tracing():  # shapes are fixed in a trace; comparing them only warns
        return
    if feats.ndim != 5 or feats.shape[2] != channels or feats.shape[1] < 1:
        raise ValueError(f"expected features of shape (B, T, {channels}, h, w) with T >= 1, got {tuple(feats.shape)}")
