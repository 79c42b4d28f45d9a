"""ImageNet weights for the VGG16 encoder: a torchvision ``vgg16_bn`` or ``vgg16`` state-dict file a user downloaded.

torchvision's files (``vgg16_bn-6c64b313.pth``, ``vgg16-397923af.pth``) are plain state dicts: ``features.N.weight``
/ ``features.N.bias`` of the 13 convolutions (with a bias), for ``vgg16_bn`` also ``features.N+1.*`` of the batch
norm after each, and the classifier (not used). `VGGEncoder`'s convolutions have no bias (a batch norm follows), so:

- ``vgg16_bn``: the conv weights and the batch norms are copied; each conv bias ``b`` moves into its batch norm's
  running mean (``mean - b``), the same function in evaluation (in training the batch mean absorbs it anyway);
- ``vgg16`` (no batch norm): the conv weights are copied and each batch norm starts as ``y + b`` in evaluation
  (weight 1, bias ``b``, running mean 0, running variance ``1 - eps``).

Both give the encoder torchvision's features at width 1.0 with RGB input standardised by the ImageNet mean and
standard deviation, as `VGGEncoder` does. The file is read with ``torch.load(weights_only=True)`` (tensors only, no
code); a file of another layout is refused in one line (`ImageNetWeightsError`).
"""

from __future__ import annotations

import pickle
import struct
import zipfile
from pathlib import Path

import torch
from torch import Tensor, nn

__all__ = ["ImageNetWeightsError", "read_torchvision_vgg16", "torchvision_conv_indices"]


class ImageNetWeightsError(ValueError):
    """A weights file that is not torchvision's vgg16_bn / vgg16 for this encoder; the message names it, one line."""


_UNREADABLE = (RuntimeError, EOFError, OSError, pickle.UnpicklingError, zipfile.BadZipFile, ValueError, struct.error)
_MAX_BYTES = 1 << 30
"""Largest file read (torchvision's vgg16_bn file is 528 MiB)."""


def torchvision_conv_indices(blocks: tuple[tuple[int, int], ...], batch_norm: bool) -> list[int]:
    """The ``features`` index of each convolution in torchvision's VGG (``make_layers``): conv, [bn,] relu per conv,
    a max-pool after each block.

    Args:
        blocks: ``(channels, convs)`` per block (`stamlane.models.encoder.VGG16_BLOCKS`).
        batch_norm: the ``_bn`` variant (3 modules a conv, else 2).

    Returns:
        13 indices for VGG16: ``[0, 3, 7, 10, 14, 17, 20, 24, 27, 30, 34, 37, 40]`` with batch norm,
        ``[0, 2, 5, 7, 10, 12, 14, 17, 19, 21, 24, 26, 28]`` without.
    """
    per_conv = 3 if batch_norm else 2
    out, index = [], 0
    for _, convs in blocks:
        for _ in range(convs):
            out.append(index)
            index += per_conv
        index += 1  # the block's max-pool
    return out


def _read(path: Path) -> dict[str, Tensor]:
    if not path.is_file():
        raise ImageNetWeightsError(f"ImageNet weights {path} do not exist (or are not a file)")
    if path.stat().st_size > _MAX_BYTES:
        raise ImageNetWeightsError(f"ImageNet weights {path} are larger than {_MAX_BYTES >> 20} MiB")
    try:
        content = torch.load(path, map_location="cpu", weights_only=True)
    except _UNREADABLE as err:
        first = str(err).strip().splitlines()[0][:200] if str(err).strip() else type(err).__name__
        raise ImageNetWeightsError(f"ImageNet weights {path} are not a readable torch file: {first}") from None
    if isinstance(content, dict) and isinstance(content.get("state_dict"), dict):
        content = content["state_dict"]
    if not isinstance(content, dict) or not all(isinstance(v, Tensor) for v in content.values()):
        raise ImageNetWeightsError(f"ImageNet weights {path} are not a state dict of tensors (torchvision's layout)")
    return content


def read_torchvision_vgg16(
    path: str | Path, stages: nn.ModuleList, blocks: tuple[tuple[int, int], ...]
) -> dict[str, Tensor]:
    """The state dict of an encoder's ``stages`` from a torchvision ``vgg16_bn`` or ``vgg16`` file (module docstring).

    Args:
        path: the torchvision state-dict file.
        stages: the encoder's stages (`VGGEncoder.stages`): stage ``s`` is ``[max-pool (s > 0)], (conv, bn, relu)*``.
        blocks: ``(channels, convs)`` per block.

    Returns:
        ``{"<stage>.<layer>.<name>": tensor}`` for every conv and batch norm of ``stages`` (load with
        ``stages.load_state_dict``).

    Raises:
        ImageNetWeightsError: unreadable, not a state dict, a key missing or of another shape (another network,
            another width): the first such key and the counts in one line.
    """
    path = Path(path)
    source = _read(path)
    batch_norm = "features.1.running_mean" in source
    indices = iter(torchvision_conv_indices(blocks, batch_norm))
    out: dict[str, Tensor] = {}
    problems: list[str] = []

    def take(key: str, shape: torch.Size) -> Tensor:
        value = source.get(key)
        if value is None:
            problems.append(f"{key} missing")
            return torch.zeros(shape)
        if value.shape != shape:
            problems.append(f"{key} of shape {tuple(value.shape)}, the encoder's is {tuple(shape)}")
            return torch.zeros(shape)
        return value.float()

    for s, stage in enumerate(stages):
        layers = list(stage.children())  # a Sequential: its layers in order
        for j, layer in enumerate(layers):
            if not isinstance(layer, nn.Conv2d):
                continue
            norm = layers[j + 1]
            assert isinstance(norm, nn.BatchNorm2d)
            assert norm.running_mean is not None and norm.running_var is not None  # track_running_stats=True
            i = next(indices)
            weight = take(f"features.{i}.weight", layer.weight.shape)
            bias = take(f"features.{i}.bias", torch.Size([layer.out_channels]))
            out[f"{s}.{j}.weight"] = weight
            n = f"{s}.{j + 1}"
            if batch_norm:
                for name in ("weight", "bias", "running_var"):
                    out[f"{n}.{name}"] = take(f"features.{i + 1}.{name}", getattr(norm, name).shape)
                out[f"{n}.running_mean"] = take(f"features.{i + 1}.running_mean", norm.running_mean.shape) - bias
            else:
                out[f"{n}.weight"] = torch.ones_like(norm.weight)
                out[f"{n}.bias"] = bias
                out[f"{n}.running_mean"] = torch.zeros_like(norm.running_mean)
                out[f"{n}.running_var"] = torch.full_like(norm.running_var, 1.0 - norm.eps)
            out[f"{n}.num_batches_tracked"] = torch.zeros((), dtype=torch.long)
    if problems:
        kind = "vgg16_bn" if batch_norm else "vgg16"
        raise ImageNetWeightsError(
            f"ImageNet weights {path} do not fit the encoder as torchvision's {kind} (width 1.0, 3 input channels): "
            f"{len(problems)} problems, the first: {problems[0]}"
        )
    return out
