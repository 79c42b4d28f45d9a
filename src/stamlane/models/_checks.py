"""Input check shared by the fusion modules (private)."""

from __future__ import annotations

import torch
from torch import Tensor

__all__ = ["check_clip_features", "is_tracing"]


def is_tracing() -> bool:
    """Whether ``torch.jit.trace`` is running (shapes are constants in a trace: checking them there only warns)."""
    # torch.jit re-exports is_tracing without listing it in __all__, and leaves it unannotated
    return bool(torch.jit.is_tracing())  # type: ignore[attr-defined,no-untyped-call]


def check_clip_features(feats: Tensor, channels: int) -> None:
    """Raise ValueError unless ``feats`` is (B, T, channels, h, w) with T >= 1."""
    if is_tracing():  # shapes are fixed in a trace; comparing them only warns
        return
    if feats.ndim != 5 or feats.shape[2] != channels or feats.shape[1] < 1:
        raise ValueError(f"expected features of shape (B, T, {channels}, h, w) with T >= 1, got {tuple(feats.shape)}")
