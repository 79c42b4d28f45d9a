"""Two-branch FCN decoder."""

from __future__ import annotations

import pytest
import torch

from stamlane.models import LaneDecoder

CHANNELS = [8, 16, 32, 64, 64]


def _skips(batch: int = 2, height: int = 32, width: int = 48) -> list[torch.Tensor]:
    return [torch.randn(batch, c, height >> i, width >> i) for i, c in enumerate(CHANNELS)]


def test_output_shapes_at_input_resolution() -> None:
    decoder = LaneDecoder(CHANNELS, embed_dim=4).eval()
    feats = _skips()
    with torch.no_grad():
        logits, embedding = decoder(feats[-1], feats[:-1])
        logits_all, _ = decoder(feats[-1], feats)  # the deepest entry may be passed and is ignored
    assert logits.shape == (2, 2, 32, 48)
    assert embedding.shape == (2, 4, 32, 48)
    torch.testing.assert_close(logits, logits_all)


def test_every_skip_is_used() -> None:
    decoder = LaneDecoder(CHANNELS).eval()
    feats = [f.requires_grad_() for f in _skips()]
    logits, embedding = decoder(feats[-1], feats[:-1])
    (logits.sum() + embedding.sum()).backward()
    assert all(f.grad is not None and f.grad.abs().sum() > 0 for f in feats)


def test_rejects_mismatched_inputs() -> None:
    decoder = LaneDecoder(CHANNELS)
    feats = _skips()
    with pytest.raises(ValueError, match="skip tensors"):
        decoder(feats[-1], feats[:2])
    with pytest.raises(ValueError, match="skip 0"):
        decoder(feats[-1], [feats[0][..., :-2], *feats[1:-1]])
    with pytest.raises(ValueError, match="fused features"):
        decoder(torch.randn(2, 32, 2, 3), feats[:-1])
    with pytest.raises(ValueError, match="embed_dim"):
        LaneDecoder(CHANNELS, embed_dim=0)
