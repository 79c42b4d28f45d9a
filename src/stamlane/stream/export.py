"""ONNX export of the network as three graphs: per-frame encoder, fusion + decoder, whole clip model.

The streaming split (`stamlane.stream.predictor`) needs two graphs:

``encoder.onnx``
    input ``frames`` (N, 3, H, W) float32 RGB in [0, 1] (N dynamic); outputs ``stage0 .. stage{S-1}``, the
    per-stage features shallow first, ``stage{i}`` (N, C_i, H / s_i, W / s_i).
``fuse_decode.onnx``
    inputs ``history`` (B, T-1, C, h, w): the cached deepest-stage features, oldest first; ``grid``
    (B, T-1, h, w, 2): for each, where every key cell samples it (``stamlane.models.feature_warp.sampling_grid``
    in ``grid_sample``'s normalised coordinates; see `identity_grid`); ``key_stage0 .. key_stage{S-1}``: the
    key frame's encoder outputs. The history is warped in the graph (ONNX ``GridSample``, bilinear, zeros,
    ``align_corners=0``), stacked with the key frame's deepest stage, fused and decoded. Outputs ``logits``
    (B, 2, H, W) and ``embedding`` (B, E, H, W). For T = 1 there are no ``history`` / ``grid`` inputs.

and ``clip.onnx`` is the whole clip model (the paper's pipeline on pre-aligned images): input ``clip``
(B, T, 3, H, W), outputs ``logits``, ``embedding``.

Every graph is exported in eval mode (batch norm with its running statistics); the network's own mode is left
as it was. T and (H, W) are fixed at export (the fusion unrolls over T); the batch is dynamic. Opset 17 (``GridSample``
needs >= 16). The TorchScript exporter is used (``dynamo=False``): it exports these graphs
far faster than the dynamo exporter (docs/method.md).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from stamlane.models import LaneNet
from stamlane.safety.guard import make_folder

__all__ = [
    "DEFAULT_OPSET",
    "EncoderGraph",
    "FuseDecodeGraph",
    "export_all",
    "export_clip",
    "export_encoder",
    "export_fuse_decode",
    "identity_grid",
]

DEFAULT_OPSET = 17
"""ONNX opset of the exported graphs (``GridSample`` exists from 16)."""


def identity_grid(batch: int, num_hist: int, size: tuple[int, int]) -> Tensor:
    """The ``grid`` input that leaves history features where they are: ``(B, T-1, h, w, 2)`` float32."""
    height, width = size
    ys = (torch.arange(height, dtype=torch.float32) + 0.5) * (2.0 / height) - 1.0
    xs = (torch.arange(width, dtype=torch.float32) + 0.5) * (2.0 / width) - 1.0
    grid = torch.stack(torch.meshgrid(xs, ys, indexing="xy"), dim=-1)  # (h, w, 2) as (x, y)
    return grid.expand(batch, num_hist, height, width, 2).contiguous()


class EncoderGraph(nn.Module):
    """The shared per-frame encoder as a graph with one output per stage.

    Args:
        net: the network; its ``encode`` is exported.
    """

    def __init__(self, net: LaneNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, frames: Tensor) -> tuple[Tensor, ...]:
        """(N, 3, H, W) in [0, 1] -> per-stage features, shallow first, each (N, C_i, H / s_i, W / s_i)."""
        return tuple(self.net.encode(frames))


class FuseDecodeGraph(nn.Module):
    """Warp the cached history features, fuse them with the key frame's, decode (the streaming half).

    Args:
        net: the network; its ``fuse_and_decode`` is exported.
        num_frames: T, frames fused (key frame included).
    """

    def __init__(self, net: LaneNet, num_frames: int) -> None:
        super().__init__()
        if num_frames < 1:
            raise ValueError(f"num_frames must be >= 1, got {num_frames}")
        self.net = net
        self.num_frames = num_frames

    def forward(self, *inputs: Tensor) -> tuple[Tensor, Tensor]:
        """``(history (B, T-1, C, h, w), grid (B, T-1, h, w, 2), *key_stages)`` -> ``(logits, embedding)``.

        ``key_stages`` are the key frame's encoder outputs, shallow first; for T = 1 only they are given.
        """
        if self.num_frames > 1:
            history, grid, key_stages = inputs[0], inputs[1], inputs[2:]
            warped = torch.unflatten(
                F.grid_sample(
                    history.flatten(0, 1),
                    grid.flatten(0, 1),
                    mode="bilinear",
                    padding_mode="zeros",
                    align_corners=False,
                ),
                0,
                history.shape[:2],
            )
            last = torch.cat([warped, key_stages[-1][:, None]], dim=1)
        else:
            key_stages = inputs
            last = key_stages[-1][:, None]
        return self.net.fuse_and_decode(last, list(key_stages[:-1]))


def _export(
    module: nn.Module, args: tuple[Tensor, ...], path: Path, inputs: list[str], outputs: list[str], opset: int
) -> Path:
    if opset < 16:
        raise ValueError(f"opset must be >= 16 (GridSample), got {opset}")
    make_folder(path.parent)
    dynamic = {name: {0: "batch"} for name in [*inputs, *outputs]}
    # a wrapper left in training mode is traced in training mode (batch-norm statistics updated) and the
    # exporter's mode restore then puts the whole wrapped network back into training mode
    modes = [(m, m.training) for m in module.modules()]
    module.eval()
    try:
        _run_export(module, args, path, inputs, outputs, dynamic, opset)
    finally:
        for m, training in modes:
            m.training = training
    return path


def _run_export(
    module: nn.Module,
    args: tuple[Tensor, ...],
    path: Path,
    inputs: list[str],
    outputs: list[str],
    dynamic: dict[str, dict[int, str]],
    opset: int,
) -> None:
    with warnings.catch_warnings(), torch.no_grad():
        warnings.simplefilter("ignore")  # TorchScript-exporter deprecation and tracer notices
        torch.onnx.export(
            module,
            args,
            str(path),
            opset_version=opset,
            input_names=inputs,
            output_names=outputs,
            dynamic_axes=dynamic,
            dynamo=False,
        )


def _eval_encode(net: LaneNet, frames: Tensor) -> list[Tensor]:
    """``net.encode`` in eval mode (example inputs of the trace), leaving the net's mode as it was."""
    was_training = net.training
    net.eval()
    try:
        return net.encode(frames)
    finally:
        net.train(was_training)


def _encoder_strides(net: LaneNet) -> list[int]:
    """The encoder's strides, shallow first (any nn.Module with the attribute: read untyped, as nn.Module types an
    attribute Tensor | Module)."""
    strides: list[int] = getattr(net.encoder, "strides")  # noqa: B009
    return strides


def _check_size(net: LaneNet, image_size: tuple[int, int]) -> tuple[int, int]:
    stride = int(_encoder_strides(net)[-1])
    if len(image_size) != 2 or any(int(s) < stride or int(s) % stride for s in image_size):
        raise ValueError(f"image_size must be (H, W), positive multiples of {stride}, got {image_size!r}")
    return int(image_size[0]), int(image_size[1])


def export_encoder(net: LaneNet, path: str | Path, image_size: tuple[int, int], opset: int = DEFAULT_OPSET) -> Path:
    """Export the per-frame encoder to ``path`` (see the module docstring); returns the path."""
    height, width = _check_size(net, image_size)
    num_stages = len(_encoder_strides(net))
    frames = torch.rand(1, 3, height, width)
    names = [f"stage{i}" for i in range(num_stages)]
    return _export(EncoderGraph(net), (frames,), Path(path), ["frames"], names, opset)


def export_fuse_decode(
    net: LaneNet, path: str | Path, num_frames: int, image_size: tuple[int, int], opset: int = DEFAULT_OPSET
) -> Path:
    """Export history warp + fusion + decoder for ``num_frames`` frames to ``path``; returns the path."""
    height, width = _check_size(net, image_size)
    with torch.no_grad():
        key_stages = _eval_encode(net, torch.rand(1, 3, height, width))
    names = [f"key_stage{i}" for i in range(len(key_stages))]
    args: tuple[Tensor, ...] = tuple(key_stages)
    if num_frames > 1:
        deepest = key_stages[-1]
        history = deepest[:, None].repeat(1, num_frames - 1, 1, 1, 1)
        grid = identity_grid(1, num_frames - 1, (deepest.shape[-2], deepest.shape[-1]))
        args = (history, grid, *args)
        names = ["history", "grid", *names]
    return _export(FuseDecodeGraph(net, num_frames), args, Path(path), names, ["logits", "embedding"], opset)


def export_clip(
    net: LaneNet, path: str | Path, num_frames: int, image_size: tuple[int, int], opset: int = DEFAULT_OPSET
) -> Path:
    """Export the whole clip model (input ``clip`` (B, T, 3, H, W), pre-aligned) to ``path``; returns the path."""
    height, width = _check_size(net, image_size)
    if num_frames < 1:
        raise ValueError(f"num_frames must be >= 1, got {num_frames}")
    clip = torch.rand(1, num_frames, 3, height, width)
    return _export(net, (clip,), Path(path), ["clip"], ["logits", "embedding"], opset)


def export_all(
    net: LaneNet, out_dir: str | Path, num_frames: int, image_size: tuple[int, int], opset: int = DEFAULT_OPSET
) -> dict[str, Path]:
    """Write ``encoder.onnx``, ``fuse_decode.onnx`` and ``clip.onnx`` under ``out_dir``; returns their paths."""
    out = Path(out_dir)
    return {
        "encoder": export_encoder(net, out / "encoder.onnx", image_size, opset),
        "fuse_decode": export_fuse_decode(net, out / "fuse_decode.onnx", num_frames, image_size, opset),
        "clip": export_clip(net, out / "clip.onnx", num_frames, image_size, opset),
    }
