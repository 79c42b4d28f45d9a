"""The whole network: shared encoder on every frame -> fusion of the deepest stage -> two-branch decoder."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from torch import Tensor, nn

__all__ = ["LaneNet"]


class LaneNet(nn.Module):
    """Lane detector on a clip of pre-aligned frames, key frame last (paper Figure 1).

    The encoder runs once on all ``B * T`` frames (frames folded into the batch); the fusion module fuses the
    deepest stage over time; the decoder upsamples the fused features with skips from the KEY frame's
    shallower stages.

    Args:
        encoder: per-frame encoder, ``(N, 3, H, W) -> list of stage features`` with an ``out_channels``
            attribute (e.g. `stamlane.models.VGGEncoder`).
        fusion: a factory called as ``fusion(encoder.out_channels[-1])`` — e.g. the class `STAM` or a
            ``functools.partial`` / jsonargparse ``class_path`` without ``channels`` — or a built module.
            Either way the result maps (B, T, C, h, w) -> (B, C, h, w).
        decoder: a factory called as ``decoder(encoder.out_channels)`` (e.g. `LaneDecoder`) or a built module;
            ``decoder(fused, key_skips) -> (logits, embedding)``.
        fuse_skip: fuse the second-deepest stage (stride 8 for `VGGEncoder`) over time too, with a second fusion
            module of the same kind (``fusion`` called with that stage's channels; ``fusion`` must then be a
            factory): the decoder's skip at that stride carries the aligned history as well, at twice the
            deepest stage's resolution. Needs pre-aligned images (``LaneNet.forward``); feature-space alignment
            and the streaming predictor fuse the deepest stage only and refuse such a network.

    For speed on CPUs with AMX: ``model.to(memory_format=torch.channels_last)`` (frames are converted to match
    inside `encode`) and ``torch.autocast("cpu", dtype=torch.bfloat16)`` around the forward pass.
    """

    def __init__(
        self,
        encoder: nn.Module,
        fusion: nn.Module | Callable[[int], nn.Module],
        decoder: nn.Module | Callable[[Sequence[int]], nn.Module],
        fuse_skip: bool = False,
    ) -> None:
        super().__init__()
        out_channels = getattr(encoder, "out_channels", None)  # any nn.Module with the attribute
        if out_channels is None:
            raise TypeError(f"encoder must have an out_channels attribute, got {type(encoder).__name__}")
        self.encoder = encoder
        channels = list(out_channels)
        self.fusion = fusion if isinstance(fusion, nn.Module) else fusion(channels[-1])
        self.decoder = decoder if isinstance(decoder, nn.Module) else decoder(channels)
        self.skip_fusion: nn.Module | None = None
        if fuse_skip:
            if isinstance(fusion, nn.Module) or len(channels) < 2:
                raise ValueError(
                    "fuse_skip needs the fusion as a factory (a class or partial, not a built module) and an encoder "
                    f"of at least 2 stages, got {type(fusion).__name__} and {len(channels)} stage(s)"
                )
            self.skip_fusion = fusion(channels[-2])

    def _memory_format(self) -> torch.memory_format:
        """channels_last when the encoder's first conv weight is (and is not also plain contiguous)."""
        weight = next((m.weight for m in self.encoder.modules() if isinstance(m, nn.Conv2d)), None)
        if (
            weight is not None
            and weight.is_contiguous(memory_format=torch.channels_last)
            and not weight.is_contiguous()
        ):
            return torch.channels_last
        return torch.contiguous_format

    def encode(self, frames: Tensor) -> list[Tensor]:
        """Run the shared encoder on independent frames.

        Args:
            frames: images, (N, 3, H, W) float in [0, 1] (N = B * T for a folded clip).

        Returns:
            per-stage features, shallow first, each (N, C_i, H / s_i, W / s_i).
        """
        if frames.ndim != 4:
            raise ValueError(f"expected frames of shape (N, 3, H, W), got {tuple(frames.shape)}")
        memory_format = self._memory_format()
        if memory_format is torch.channels_last:
            frames = frames.contiguous(memory_format=memory_format)
        feats: list[Tensor] = self.encoder(frames)
        return feats

    def fuse_and_decode(
        self, last_stage_feats: Tensor, key_skips: Sequence[Tensor], skip_stage_feats: Tensor | None = None
    ) -> tuple[Tensor, Tensor]:
        """Fuse the deepest stage over time and decode (the streaming half of `forward`).

        Args:
            last_stage_feats: deepest-stage features of every frame, (B, T, C, h, w); key frame last,
                history aligned to it.
            key_skips: the key frame's features of the shallower stages, shallow first, (B, C_i, h_i, w_i)
                (the list `encode` returns for the key frame is accepted as is; its deepest entry is ignored).
            skip_stage_feats: the second-deepest stage of every frame, (B, T, C', 2h, 2w), aligned; required when
                the network fuses it too (``fuse_skip``): its fusion replaces the key frame's skip at that stage.

        Returns:
            ``(logits (B, 2, H, W), embedding (B, E, H, W))`` at input resolution.
        """
        fused = self.fusion(last_stage_feats)
        if self.skip_fusion is not None:
            if skip_stage_feats is None:
                raise ValueError(
                    "this network fuses the second-deepest stage too (fuse_skip): it needs that stage of every "
                    "frame, pre-aligned images (feature-space alignment and streaming fuse the deepest stage only)"
                )
            # any nn.Module with in_channels: read untyped (nn.Module types an attribute as Tensor | Module)
            decoder_channels = getattr(self.decoder, "in_channels")  # noqa: B009
            skips = list(key_skips[: len(decoder_channels) - 1])
            skips[-1] = self.skip_fusion(skip_stage_feats)
            key_skips = skips
        out: tuple[Tensor, Tensor] = self.decoder(fused, key_skips)
        return out

    def forward(self, clip: Tensor) -> tuple[Tensor, Tensor]:
        """Detect lanes in the key frame of each clip.

        Args:
            clip: frames, (B, T, 3, H, W) float in [0, 1], key frame last, history pre-aligned.

        Returns:
            ``(logits, embedding)``: lane / background logits (B, 2, H, W) (channel 1 = lane) and pixel
            embeddings (B, E, H, W).
        """
        if clip.ndim != 5:
            raise ValueError(f"expected a clip of shape (B, T, 3, H, W), got {tuple(clip.shape)}")
        batch, num_frames = clip.shape[:2]
        feats = self.encode(clip.flatten(0, 1))
        last = torch.unflatten(feats[-1], 0, (batch, num_frames))
        key_skips = [torch.unflatten(f, 0, (batch, num_frames))[:, -1] for f in feats[:-1]]
        skip_stage = torch.unflatten(feats[-2], 0, (batch, num_frames)) if self.skip_fusion is not None else None
        return self.fuse_and_decode(last, key_skips, skip_stage)
