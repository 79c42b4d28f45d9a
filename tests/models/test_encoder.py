"""VGG16-BN encoder: stage channels and strides, standardisation, input checks."""

from __future__ import annotations

import pytest
import torch

from stamlane.models import VGGEncoder
from stamlane.models.encoder import IMAGENET_MEAN


def test_paper_width_channels_and_strides() -> None:
    encoder = VGGEncoder(1.0)
    assert encoder.out_channels == [64, 128, 256, 512, 512]
    assert encoder.strides == [1, 2, 4, 8, 16]
    convs = [m for m in encoder.modules() if isinstance(m, torch.nn.Conv2d)]
    assert len(convs) == 13  # VGG16: 13 conv layers
    assert sum(isinstance(m, torch.nn.BatchNorm2d) for m in encoder.modules()) == 13


def test_feature_shapes_at_quarter_width() -> None:
    encoder = VGGEncoder(0.25).eval()
    assert encoder.out_channels == [16, 32, 64, 128, 128]
    with torch.no_grad():
        feats = encoder(torch.rand(2, 3, 32, 64))
    assert [tuple(f.shape) for f in feats] == [
        (2, c, 32 // s, 64 // s) for c, s in zip(encoder.out_channels, encoder.strides)
    ]


def test_standardises_input_itself() -> None:
    encoder = VGGEncoder(0.125).eval()
    # a mean-coloured image becomes zeros after standardisation, so the first conv (no bias) sees zeros
    image = torch.tensor(IMAGENET_MEAN).view(1, 3, 1, 1).expand(1, 3, 16, 16)
    with torch.no_grad():
        first = encoder.stages[0][0]((image - encoder.mean) / encoder.std)
    assert first.abs().max() < 1e-6
    assert "mean" not in encoder.state_dict()  # fixed constants, not checkpoint state


def test_rejects_bad_input() -> None:
    encoder = VGGEncoder(0.125)
    with pytest.raises(ValueError, match="multiples of 16"):
        encoder(torch.rand(1, 3, 24, 32))
    with pytest.raises(ValueError, match=r"got \(1, 4, 32, 32\)"):
        encoder(torch.rand(1, 4, 32, 32))
    with pytest.raises(ValueError, match="width"):
        VGGEncoder(0.0)
