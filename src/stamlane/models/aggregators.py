"""Temporal aggregators of the paper's Table 4 and the single-frame baseline (docs/method.md §3, last paragraph).

Every aggregator has STAM's interface: ``Module(channels)``, ``forward(feats: (B, T, C, h, w)) -> (B, C, h, w)``
with the key frame last, so a config swaps them freely. Interpretations where the paper gives no detail are
stated in each class docstring.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from stamlane.models._checks import check_clip_features
from stamlane.types import nameable

__all__ = ["STPSA", "ConvLSTMFusion", "CosineWeightedSum", "KeyFrameOnly", "STDANet", "SimpleAdd"]


class _ParameterFree(nn.Module):
    """Base of the aggregators without parameters: checks the input, then ``_fuse`` combines the frames.

    Args:
        channels: C, checked against the input.
    """

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.channels = channels

    def forward(self, feats: Tensor) -> Tensor:
        """(B, T, C, h, w), key frame last -> (B, C, h, w)."""
        check_clip_features(feats, self.channels)
        return self._fuse(feats)

    def _fuse(self, feats: Tensor) -> Tensor:
        """Checked (B, T, C, h, w), key frame last -> (B, C, h, w)."""
        raise NotImplementedError


@nameable
class KeyFrameOnly(_ParameterFree):
    """The single-frame baseline: returns the key frame's features, ignores history. No parameters.

    Args:
        channels: C, checked against the input.
    """

    def _fuse(self, feats: Tensor) -> Tensor:
        return feats[:, -1]


@nameable
class SimpleAdd(_ParameterFree):
    """Table 4 "simple add": the sum of all frames' features, ``out = sum_t F_t``. No parameters.

    Args:
        channels: C, checked against the input.
    """

    def _fuse(self, feats: Tensor) -> Tensor:
        return feats.sum(dim=1)


class _ConvLSTMCell(nn.Module):
    def __init__(self, in_channels: int, hidden_channels: int, kernel_size: int) -> None:
        super().__init__()
        self.hidden_channels = hidden_channels
        self.gates = nn.Conv2d(
            in_channels + hidden_channels, 4 * hidden_channels, kernel_size, padding=kernel_size // 2
        )
        assert self.gates.bias is not None  # a Conv2d's bias (bias=True)
        with torch.no_grad():  # forget-gate bias 1: remember by default (Jozefowicz et al. 2015)
            self.gates.bias.zero_()
            self.gates.bias[hidden_channels : 2 * hidden_channels].fill_(1.0)

    def forward(self, x: Tensor, state: tuple[Tensor, Tensor]) -> tuple[Tensor, Tensor]:
        h, c = state
        i, f, o, g = self.gates(torch.cat([x, h], dim=1)).chunk(4, dim=1)
        c = torch.sigmoid(f) * c + torch.sigmoid(i) * torch.tanh(g)
        h = torch.sigmoid(o) * torch.tanh(c)
        return h, c


@nameable
class ConvLSTMFusion(nn.Module):
    """Table 4 ConvLSTM: a stacked ConvLSTM (Shi et al. 2015) run over the frames oldest first; the output is
    the last layer's hidden state after the key frame. Zero initial state.

    Args:
        channels: C, input and output channels.
        num_layers: stacked ConvLSTM layers (2 in the paper).
        kernel_size: gate-convolution kernel size.
        hidden_channels: hidden state channels (default C). If it differs from C a 1x1 conv maps the
            output back to C. At width 1.0 (C = 512) the default costs ~10 GMAC per layer and frame at 16x32.
    """

    def __init__(
        self, channels: int, num_layers: int = 2, kernel_size: int = 3, hidden_channels: int | None = None
    ) -> None:
        super().__init__()
        if num_layers < 1:
            raise ValueError(f"num_layers must be >= 1, got {num_layers}")
        if kernel_size < 1 or kernel_size % 2 == 0:
            raise ValueError(f"kernel_size must be a positive odd number, got {kernel_size}")
        hidden = channels if hidden_channels is None else hidden_channels
        if hidden < 1:
            raise ValueError(f"hidden_channels must be >= 1, got {hidden}")
        self.channels = channels
        self.cells = nn.ModuleList(
            _ConvLSTMCell(channels if layer == 0 else hidden, hidden, kernel_size) for layer in range(num_layers)
        )
        self.project = nn.Identity() if hidden == channels else nn.Conv2d(hidden, channels, 1)

    def forward(self, feats: Tensor) -> Tensor:
        """(B, T, C, h, w), key frame last -> last hidden state of the last layer after the key frame, (B, C, h, w)."""
        check_clip_features(feats, self.channels)
        sequence = list(feats.unbind(1))
        for cell in self.cells:
            assert isinstance(cell, _ConvLSTMCell)
            zeros = sequence[0].new_zeros(sequence[0].shape[0], cell.hidden_channels, *sequence[0].shape[-2:])
            state = (zeros, zeros)
            outputs = []
            for x in sequence:
                state = cell(x, state)
                outputs.append(state[0])
            sequence = outputs
        projected: Tensor = self.project(sequence[-1])
        return projected


@nameable
class CosineWeightedSum(_ParameterFree):
    """Table 4 cosine-similarity weighted sum: per pixel, the cosine similarity of each frame's feature vector
    to the key frame's, softmax over frames, weighted sum of the frames. No parameters (the key frame's
    own similarity is 1, so it always weighs the most).

    Args:
        channels: C, checked against the input.
    """

    def _fuse(self, feats: Tensor) -> Tensor:
        similarity = F.cosine_similarity(feats, feats[:, -1:], dim=2, eps=1e-6)  # (B, T, h, w)
        weights = similarity.softmax(dim=1).unsqueeze(2)
        return (weights * feats).sum(dim=1)


@nameable
class STDANet(nn.Module):
    """Table 4 ST-DANet: DANet's position and channel attention (Fu et al., CVPR 2019) stretched over time,
    queries from the key frame K, keys and values from all T frames.

    - position: ``q = Wq K`` (C/r), ``k_t = Wk F_t`` (C/r), ``v_t = Wv F_t`` (C); every key pixel attends over
      all T*h*w pixels: ``P(p) = sum_{t,q} softmax(q(p) . k_t(q)) v_t(q)``.
    - channel: every key channel attends over the T*C channels of all frames (energies summed over pixels,
      DANet's ``max - energy`` trick kept): ``Ch = softmax(max(E) - E) [F_1; ...; F_T]``, ``E = K [F_1; ...; F_T]^T``.
    - ``out = K + gamma_p P + gamma_c Ch`` with both scales initialised to 0 (so training starts from K).

    Args:
        channels: C.
        reduction: r, query/key channels of the position attention are ``max(1, C // r)`` (8 in DANet).
    """

    def __init__(self, channels: int, reduction: int = 8) -> None:
        super().__init__()
        if reduction < 1:
            raise ValueError(f"reduction must be >= 1, got {reduction}")
        inner = max(1, channels // reduction)
        self.channels = channels
        self.query = nn.Conv2d(channels, inner, 1)
        self.key = nn.Conv2d(channels, inner, 1)
        self.value = nn.Conv2d(channels, channels, 1)
        self.gamma_position = nn.Parameter(torch.zeros(1))
        self.gamma_channel = nn.Parameter(torch.zeros(1))

    def forward(self, feats: Tensor) -> Tensor:
        """(B, T, C, h, w), key frame last -> (B, C, h, w)."""
        check_clip_features(feats, self.channels)
        batch, num_frames, channels, height, width = feats.shape
        key_frame = feats[:, -1]
        folded = feats.flatten(0, 1)  # (B*T, C, h, w)
        q = self.query(key_frame).flatten(2).transpose(1, 2)  # (B, hw, C')
        k = self.key(folded).reshape(batch, num_frames, -1, height * width)  # (B, T, C', hw)
        k = k.permute(0, 2, 1, 3).flatten(2)  # (B, C', T*hw)
        v = self.value(folded).reshape(batch, num_frames, channels, height * width)
        v = v.permute(0, 2, 1, 3).flatten(2)  # (B, C, T*hw)
        attention = torch.bmm(q, k).softmax(dim=-1)  # (B, hw, T*hw)
        position = torch.bmm(v, attention.transpose(1, 2)).reshape(batch, channels, height, width)

        queries = key_frame.flatten(2)  # (B, C, hw)
        keys = feats.reshape(batch, num_frames * channels, height * width)  # (B, T*C, hw)
        energy = torch.bmm(queries, keys.transpose(1, 2))  # (B, C, T*C)
        energy = energy.amax(dim=-1, keepdim=True) - energy  # DANet's CAM uses max - energy
        channel = torch.bmm(energy.softmax(dim=-1), keys).reshape(batch, channels, height, width)
        return key_frame + self.gamma_position * position + self.gamma_channel * channel


@nameable
class STPSA(nn.Module):
    """Table 4 ST-PSA: polarized self-attention (Liu et al. 2021, parallel layout) with the key frame as query.

    For every frame F_t (key frame included), with K the key frame:

    - channel-only: ``z_t = Wv_c(F_t) softmax_hw(Wq_c(K))`` (C/2), ``c_t = sigmoid(LN(Wz z_t))`` (C, 1, 1).
    - spatial-only: ``s_t = sigmoid(softmax_c(avgpool(Wq_s(K))) . Wv_s(F_t))`` (1, h, w).
    - ``out = sum_t (c_t x F_t + s_t x F_t)``.

    With T = 1 this is PSA (parallel) on the key frame. History content reaches the output, gated by
    attention whose queries come from the key frame.

    Args:
        channels: C; the branches' inner width is ``max(1, C // 2)``.
    """

    def __init__(self, channels: int) -> None:
        super().__init__()
        inner = max(1, channels // 2)
        self.channels = channels
        self.channel_query = nn.Conv2d(channels, 1, 1)
        self.channel_value = nn.Conv2d(channels, inner, 1)
        self.channel_up = nn.Conv2d(inner, channels, 1)
        self.channel_norm = nn.LayerNorm([channels, 1, 1])
        self.spatial_query = nn.Conv2d(channels, inner, 1)
        self.spatial_value = nn.Conv2d(channels, inner, 1)

    def forward(self, feats: Tensor) -> Tensor:
        """(B, T, C, h, w), key frame last -> (B, C, h, w)."""
        check_clip_features(feats, self.channels)
        batch, num_frames, channels, height, width = feats.shape
        key_frame = feats[:, -1]
        folded = feats.flatten(0, 1)  # (B*T, C, h, w)

        pool = self.channel_query(key_frame).reshape(batch, 1, height * width, 1).softmax(dim=2)  # (B, 1, hw, 1)
        values = self.channel_value(folded).reshape(batch, num_frames, -1, height * width)  # (B, T, C/2, hw)
        z = torch.matmul(values, pool).reshape(batch * num_frames, -1, 1, 1)  # (B*T, C/2, 1, 1)
        channel_gate = torch.sigmoid(self.channel_norm(self.channel_up(z))).reshape(batch, num_frames, channels, 1, 1)

        query = self.spatial_query(key_frame).mean(dim=(2, 3)).softmax(dim=1)  # (B, C/2)
        values = self.spatial_value(folded).reshape(batch, num_frames, -1, height * width)  # (B, T, C/2, hw)
        spatial = torch.matmul(query.reshape(batch, 1, 1, -1), values)  # (B, T, 1, hw)
        spatial_gate = torch.sigmoid(spatial).reshape(batch, num_frames, 1, height, width)

        return ((channel_gate + spatial_gate) * feats).sum(dim=1)
