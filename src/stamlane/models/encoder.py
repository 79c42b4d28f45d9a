"""VGG16 encoder with batch norm, shared by every frame of a clip (paper 3.2).

Stage layout (the choice the FCN decoder and the fusion rely on): the five VGG16 conv blocks
``(64, 128, 256, 512, 512) * width`` each form one stage; stage ``i > 0`` starts with a 2x2 max-pool, so
the stage outputs sit at strides ``(1, 2, 4, 8, 16)``. VGG16's fifth pool is dropped: the deepest
stage — the one STAM fuses — stays at stride 16, so a 128x256 input fuses on an 8x16 grid and a
256x512 input on 16x32 (stride 32 would leave 4x8 cells, too coarse to align or gate lanes). The
input height and width must therefore be multiples of 16.

ImageNet initialisation: ``weights`` names a torchvision ``vgg16_bn`` or ``vgg16`` state-dict file
(`stamlane.models.imagenet`), loaded by `VGGEncoder.load_weights` (``StamLaneModule`` calls it when ``fit`` starts).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from stamlane.models._checks import is_tracing
from stamlane.models.imagenet import ImageNetWeightsError, read_torchvision_vgg16
from stamlane.types import nameable

__all__ = ["IMAGENET_MEAN", "IMAGENET_STD", "VGG16_BLOCKS", "VGGEncoder"]

VGG16_BLOCKS: tuple[tuple[int, int], ...] = ((64, 2), (128, 2), (256, 3), (512, 3), (512, 3))
"""VGG16 configuration D (Simonyan & Zisserman 2015): (channels, number of 3x3 convs) per block."""

IMAGENET_MEAN = (0.485, 0.456, 0.406)
"""Per-channel RGB mean of ImageNet; the encoder standardises its [0, 1] input with it (fixed, not learnt)."""
IMAGENET_STD = (0.229, 0.224, 0.225)
"""Per-channel RGB standard deviation of ImageNet."""


def _conv_bn_relu(in_channels: int, out_channels: int) -> list[nn.Module]:
    return [
        nn.Conv2d(in_channels, out_channels, 3, padding=1, bias=False),
        nn.BatchNorm2d(out_channels),
        nn.ReLU(inplace=True),
    ]


@nameable
class VGGEncoder(nn.Module):
    """VGG16-BN conv blocks with a width multiplier; trained from scratch or from ImageNet weights.

    Args:
        width: channel multiplier; 1.0 is the paper's VGG16 (64 ... 512 channels), 0.25 a CPU-sized
            network with the same graph. Each block gets ``max(1, round(c * width))`` channels.
        in_channels: channels of the input image; 3 = RGB, standardised with the ImageNet mean / std, any
            other count with mean 0.5 and std 0.25 per channel.
        weights: a torchvision ``vgg16_bn`` or ``vgg16`` state-dict file (ImageNet; width 1.0, 3 channels), read by
            `load_weights`, not here: ``StamLaneModule`` loads it when ``fit`` starts (before a resumed checkpoint
            is restored), so a trained model is built, validated or exported without the file.

    Attributes:
        out_channels: channels of each stage output, shallow first, e.g. ``[64, 128, 256, 512, 512]``.
        strides: stride of each stage output w.r.t. the input, ``[1, 2, 4, 8, 16]``.
    """

    mean: Tensor  # (1, in_channels, 1, 1) buffers: the input normalisation
    std: Tensor

    def __init__(self, width: float = 1.0, in_channels: int = 3, weights: str | None = None) -> None:
        super().__init__()
        if not width > 0:
            raise ValueError(f"width must be > 0, got {width}")
        if in_channels < 1:
            raise ValueError(f"in_channels must be >= 1, got {in_channels}")
        self.width = width
        self.in_channels = in_channels
        self.weights = weights
        self.out_channels: list[int] = []
        self.strides: list[int] = []
        stages: list[nn.Module] = []
        prev = in_channels
        for index, (channels, depth) in enumerate(VGG16_BLOCKS):
            out = max(1, round(channels * width))
            layers: list[nn.Module] = [nn.MaxPool2d(2)] if index > 0 else []
            for _ in range(depth):
                layers += _conv_bn_relu(prev, out)
                prev = out
            stages.append(nn.Sequential(*layers))
            self.out_channels.append(out)
            self.strides.append(2**index)
        self.stages = nn.ModuleList(stages)
        mean = torch.tensor(IMAGENET_MEAN if in_channels == 3 else [0.5] * in_channels).view(1, -1, 1, 1)
        std = torch.tensor(IMAGENET_STD if in_channels == 3 else [0.25] * in_channels).view(1, -1, 1, 1)
        self.register_buffer("mean", mean, persistent=False)
        self.register_buffer("std", std, persistent=False)

    def load_weights(self) -> bool:
        """Load ``weights`` (ImageNet, torchvision's layout) into the stages; False when none were given.

        Raises:
            ImageNetWeightsError: the file is missing, unreadable or of another layout (one line naming it).
        """
        if not self.weights:
            return False
        if self.width != 1.0 or self.in_channels != 3:
            raise ImageNetWeightsError(
                f"ImageNet weights {self.weights} need the encoder at width 1.0 with 3 input channels, got width "
                f"{self.width}, {self.in_channels} channels"
            )
        state = read_torchvision_vgg16(self.weights, self.stages, VGG16_BLOCKS)
        self.stages.load_state_dict(state)
        return True

    @property
    def total_stride(self) -> int:
        """Stride of the deepest stage; input height and width must be multiples of it."""
        return self.strides[-1]

    def _check(self, x: Tensor) -> None:
        if x.ndim != 4 or x.shape[1] != self.in_channels:
            raise ValueError(f"expected images of shape (N, {self.in_channels}, H, W), got {tuple(x.shape)}")
        height, width = x.shape[-2:]
        if height % self.total_stride or width % self.total_stride:
            raise ValueError(f"image height and width must be multiples of {self.total_stride}, got {height}x{width}")

    def forward(self, x: Tensor) -> list[Tensor]:
        """Encode images.

        Args:
            x: images, (N, in_channels, H, W), float in [0, 1]; H and W multiples of ``total_stride``.
                A channels_last input stays channels_last.

        Returns:
            per-stage features, shallow first; stage ``i`` is (N, out_channels[i], H / strides[i], W / strides[i]).
        """
        if not is_tracing():  # shapes are constants in a trace; checking them there only warns
            self._check(x)
        x = (x - self.mean) / self.std
        feats = []
        for stage in self.stages:
            x = stage(x)
            feats.append(x)
        return feats
