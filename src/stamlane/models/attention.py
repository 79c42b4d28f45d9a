"""CBAM channel and spatial attention blocks (Woo et al., ECCV 2018), as docs/method.md §3 defines them.

Both blocks return the attention map only (not the gated features), because STAM applies a map
computed on one frame to the features of another.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

__all__ = ["ChannelAttention", "SpatialAttention"]


class ChannelAttention(nn.Module):
    """CA(X) = sigmoid(MLP(avgpool_hw(X)) + MLP(maxpool_hw(X))), MLP C -> C/r -> C with ReLU, shared.

    Args:
        channels: C, the channels of X.
        reduction: r; the hidden layer has ``max(1, C // r)`` units.
    """

    def __init__(self, channels: int, reduction: int = 16) -> None:
        super().__init__()
        if channels < 1:
            raise ValueError(f"channels must be >= 1, got {channels}")
        if reduction < 1:
            raise ValueError(f"reduction must be >= 1, got {reduction}")
        hidden = max(1, channels // reduction)
        self.mlp = nn.Sequential(
            nn.Conv2d(channels, hidden, 1),
            nn.ReLU(inplace=True),
            nn.Conv2d(hidden, channels, 1),
        )

    def forward(self, x: Tensor) -> Tensor:
        """Channel attention map.

        Args:
            x: features, (B, C, h, w).

        Returns:
            gains in (0, 1), (B, C, 1, 1).
        """
        avg = x.mean(dim=(2, 3), keepdim=True)
        peak = x.amax(dim=(2, 3), keepdim=True)
        return torch.sigmoid(self.mlp(avg) + self.mlp(peak))


class SpatialAttention(nn.Module):
    """SA(X) = sigmoid(conv_kxk([mean_c(X); max_c(X)])).

    Args:
        kernel_size: k, odd; the conv pads to keep h x w.
    """

    def __init__(self, kernel_size: int = 7) -> None:
        super().__init__()
        if kernel_size < 1 or kernel_size % 2 == 0:
            raise ValueError(f"kernel_size must be a positive odd number, got {kernel_size}")
        self.conv = nn.Conv2d(2, 1, kernel_size, padding=kernel_size // 2)

    def forward(self, x: Tensor) -> Tensor:
        """Spatial attention map.

        Args:
            x: features, (B, C, h, w).

        Returns:
            gains in (0, 1), (B, 1, h, w).
        """
        pooled = torch.cat([x.mean(dim=1, keepdim=True), x.amax(dim=1, keepdim=True)], dim=1)
        return torch.sigmoid(self.conv(pooled))
