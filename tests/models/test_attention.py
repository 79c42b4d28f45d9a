"""CBAM channel / spatial attention blocks."""

from __future__ import annotations

import pytest
import torch

from stamlane.models import ChannelAttention, SpatialAttention


def test_channel_attention_matches_formula() -> None:
    torch.manual_seed(0)
    block = ChannelAttention(32, reduction=8)
    x = torch.randn(2, 32, 5, 7)
    mlp = block.mlp
    expected = torch.sigmoid(mlp(x.mean((2, 3), keepdim=True)) + mlp(x.amax((2, 3), keepdim=True)))
    out = block(x)
    assert out.shape == (2, 32, 1, 1)
    torch.testing.assert_close(out, expected)
    assert mlp[0].out_channels == 4


def test_spatial_attention_matches_formula() -> None:
    torch.manual_seed(0)
    block = SpatialAttention(kernel_size=5)
    x = torch.randn(2, 16, 6, 9)
    pooled = torch.cat([x.mean(1, keepdim=True), x.amax(1, keepdim=True)], 1)
    expected = torch.sigmoid(torch.nn.functional.conv2d(pooled, block.conv.weight, block.conv.bias, padding=2))
    out = block(x)
    assert out.shape == (2, 1, 6, 9)
    torch.testing.assert_close(out, expected)


def test_hidden_units_never_zero() -> None:
    assert ChannelAttention(4, reduction=16).mlp[0].out_channels == 1


@pytest.mark.parametrize("kwargs", [{"channels": 0}, {"channels": 8, "reduction": 0}])
def test_channel_attention_rejects_bad_args(kwargs: dict) -> None:
    with pytest.raises(ValueError, match="must be >= 1"):
        ChannelAttention(**kwargs)


def test_spatial_attention_rejects_even_kernel() -> None:
    with pytest.raises(ValueError, match="odd"):
        SpatialAttention(kernel_size=4)
