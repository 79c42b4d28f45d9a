"""Two-branch FCN decoder (paper 3.2): fused deepest features + key-frame skips -> lane logits and embeddings."""

from __future__ import annotations

from collections.abc import Sequence

import torch.nn.functional as F
from torch import Tensor, nn

from stamlane.models._checks import is_tracing
from stamlane.types import nameable

__all__ = ["LaneDecoder"]


def _conv_bn_relu(in_channels: int, out_channels: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(in_channels, out_channels, 3, padding=1, bias=False),
        nn.BatchNorm2d(out_channels),
        nn.ReLU(inplace=True),
    )


@nameable
class LaneDecoder(nn.Module):
    """FCN decoder with additive skips from the key frame's encoder stages, and two heads.

    From the deepest stage up, each step maps the running features to the next-shallower stage's channels
    with a 1x1 conv, upsamples them x2 (bilinear), adds that stage's key-frame features (FCN-style skip) and
    refines with conv3x3-BN-ReLU. At stride 1 two heads (conv3x3-BN-ReLU, conv1x1) give the binary lane
    logits and the pixel embeddings.

    Args:
        in_channels: channels of every encoder stage, shallow first (``VGGEncoder.out_channels``); the
            deepest entry is the fused features' channels. Consecutive stages must differ in stride by 2.
        embed_dim: E, embedding dimension of the instance branch (4 in the paper).
        head_channels: hidden channels of each head (default: ``in_channels[0]``).
    """

    def __init__(self, in_channels: Sequence[int], embed_dim: int = 4, head_channels: int | None = None) -> None:
        super().__init__()
        in_channels = list(in_channels)
        if len(in_channels) < 1 or min(in_channels) < 1:
            raise ValueError(f"in_channels must be a non-empty list of positive ints, got {in_channels}")
        if embed_dim < 1:
            raise ValueError(f"embed_dim must be >= 1, got {embed_dim}")
        hidden = in_channels[0] if head_channels is None else head_channels
        if hidden < 1:
            raise ValueError(f"head_channels must be >= 1, got {hidden}")
        self.in_channels = in_channels
        self.embed_dim = embed_dim
        # lateral[i] / refine[i] bring stage i+1's resolution to stage i (i = len-2 ... 0)
        self.lateral = nn.ModuleList(
            nn.Conv2d(in_channels[i + 1], in_channels[i], 1) for i in range(len(in_channels) - 1)
        )
        self.refine = nn.ModuleList(_conv_bn_relu(c, c) for c in in_channels[:-1])
        self.binary_head = nn.Sequential(_conv_bn_relu(in_channels[0], hidden), nn.Conv2d(hidden, 2, 1))
        self.embedding_head = nn.Sequential(_conv_bn_relu(in_channels[0], hidden), nn.Conv2d(hidden, embed_dim, 1))

    def forward(self, fused: Tensor, skips: Sequence[Tensor]) -> tuple[Tensor, Tensor]:
        """Decode.

        Args:
            fused: fused deepest-stage features of the key frame, (B, in_channels[-1], h, w).
            skips: the key frame's encoder features of the shallower stages, shallow first:
                ``skips[i]`` is (B, in_channels[i], h * 2**(S-1-i), w * 2**(S-1-i)) with S = len(in_channels).
                A list holding also the deepest stage is accepted; that entry is ignored.

        Returns:
            ``(logits, embedding)``: lane / background logits (B, 2, H, W), channel 1 = lane, and pixel
            embeddings (B, E, H, W), at the resolution of ``skips[0]`` (the input resolution for VGGEncoder).
        """
        if not is_tracing():
            self._check(fused, skips)
        x = fused
        for i in reversed(range(len(self.in_channels) - 1)):
            x = F.interpolate(self.lateral[i](x), scale_factor=2.0, mode="bilinear", align_corners=False)
            x = self.refine[i](x + skips[i])
        return self.binary_head(x), self.embedding_head(x)

    def _check(self, fused: Tensor, skips: Sequence[Tensor]) -> None:
        num_skips = len(self.in_channels) - 1
        if len(skips) not in (num_skips, num_skips + 1):
            raise ValueError(f"expected {num_skips} skip tensors (shallow first), got {len(skips)}")
        if fused.ndim != 4 or fused.shape[1] != self.in_channels[-1]:
            raise ValueError(
                f"expected fused features of shape (B, {self.in_channels[-1]}, h, w), got {tuple(fused.shape)}"
            )
        height, width = fused.shape[-2:]
        for i in reversed(range(num_skips)):
            height, width = 2 * height, 2 * width
            skip = skips[i]
            if skip.ndim != 4 or skip.shape[1] != self.in_channels[i] or tuple(skip.shape[-2:]) != (height, width):
                raise ValueError(
                    f"skip {i}: expected shape (B, {self.in_channels[i]}, {height}, {width}), got {tuple(skip.shape)}"
                )
