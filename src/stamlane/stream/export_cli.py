"""``stamlane export``: a checkpoint to ONNX, its preprocessing in the file, the float32 parity measured and printed.

    stamlane export --ckpt_path RUN/checkpoints/last.ckpt [--output model.onnx] [--opset 17] [--streaming DIR]

Writes the whole clip model (input ``clip`` (B, T, 3, H, W) float32 RGB in [0, 1], key frame last, history
pre-aligned; outputs ``logits`` (B, 2, H, W) and ``embedding`` (B, E, H, W); see `stamlane.stream.export`) to
``--output`` (default: the checkpoint's path with ``.onnx``), and with ``--streaming DIR`` also the two graphs of
the streaming predictor. Each file carries in its ``metadata_props`` how to feed it and read it (crop, size,
colour order, T, alignment, post-processing, the checkpoint's SHA-256: `stamlane.stream.metadata`), read from the
checkpoint. The network is built from the checkpoint alone, from the closed registry (`stamlane.training.registry`: nothing
the file names is imported). Parity: onnxruntime and PyTorch, both in float32, run on the same random clip and
the largest absolute differences are printed. Needs the ``export`` extra (onnx, onnxscript, onnxruntime); without
it, one line with the install command and exit status 2, before anything is read.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import numpy as np
from stamlane_eval.cli_tools import OneLineParser, check_input_file, format_wxh, parse_or_status

from stamlane.safety.boundary import run_command
from stamlane.safety.budget import check_stream_buffers
from stamlane.safety.guard import atomic_path, check_outputs, temporary_name
from stamlane.safety.owner import claim, mark
from stamlane.weights import resolve

__all__ = ["EXPORT_PACKAGES", "ONNX_HINT", "build_parser", "main", "parity"]

EXPORT_PACKAGES = ("onnx", "onnxscript", "onnxruntime")
"""What ``stamlane export`` needs: onnx and onnxscript to write the graph (``torch.onnx.export``), onnxruntime for
the parity (an export whose parity was not measured is not offered)."""

ONNX_HINT = 'pip install "stamlane[export]"'
"""How the packages are installed (the ``export`` extra)."""

STREAMING_GRAPHS = ("encoder", "fuse_decode")
"""The graphs ``--streaming DIR`` writes, as ``DIR/<name>.onnx``."""


def build_parser() -> OneLineParser:
    p = OneLineParser(prog="stamlane export", description=__doc__.split("\n")[0])
    p.add_argument(
        "--ckpt_path", required=True, type=Path, help="a checkpoint of `stamlane fit`, or a shipped model's name"
    )
    p.add_argument(
        "--output",
        type=Path,
        default=None,
        help="the .onnx file (default: the checkpoint's, .onnx; a shipped model's: NAME.onnx here)",
    )
    p.add_argument("--opset", type=int, default=None, help="ONNX opset (default 17; >= 16 for GridSample)")
    p.add_argument("--streaming", type=Path, default=None, help="also write encoder/fuse_decode graphs here")
    return p


def missing_packages() -> list[str]:
    """The packages of `EXPORT_PACKAGES` that cannot be imported."""
    missing = []
    for name in EXPORT_PACKAGES:
        try:
            found = importlib.util.find_spec(name) is not None
        except ValueError:  # in sys.modules as None (blocked), or without a spec
            found = False
        missing += [] if found else [name]
    return missing


def parity(net: Any, path: Path, num_frames: int, image_size: tuple[int, int], seed: int = 0) -> dict[str, float]:
    """Largest absolute difference between onnxruntime on ``path`` and PyTorch on one random clip, both float32.

    Returns:
        ``{"logits": float, "embedding": float}``.
    """
    import onnxruntime as ort
    import torch

    clip = torch.rand(1, num_frames, 3, *image_size, generator=torch.Generator().manual_seed(seed))
    with torch.no_grad():
        logits, embedding = net.eval()(clip)
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    onnx_logits, onnx_embedding = session.run(["logits", "embedding"], {"clip": clip.numpy()})
    return {
        "logits": float(np.abs(onnx_logits - logits.numpy()).max()),
        "embedding": float(np.abs(onnx_embedding - embedding.numpy()).max()),
    }


def _export(args: Any) -> int:
    missing = missing_packages()
    if missing:
        raise ValueError(f"exporting to ONNX needs {', '.join(missing)} (the export extra): {ONNX_HINT}")
    from stamlane.stream.export import DEFAULT_OPSET

    opset = args.opset if args.opset is not None else DEFAULT_OPSET
    if not 16 <= opset <= 21:
        raise ValueError(f"--opset must be in 16..21, got {opset}")
    shipped = resolve(str(args.ckpt_path))
    if shipped != str(args.ckpt_path):  # a shipped model: its .onnx here, never inside the installed package
        args.output = args.output or Path(f"{args.ckpt_path}.onnx")
        args.ckpt_path = Path(shipped)
    output = args.output or args.ckpt_path.with_suffix(".onnx")
    check_input_file(args.ckpt_path, "checkpoint")  # before torch is imported: a missing file said at once
    outputs = [output]
    if args.streaming is not None:
        outputs += [args.streaming / f"{name}.onnx" for name in STREAMING_GRAPHS]
    check_outputs(
        [*outputs, *map(temporary_name, outputs)],
        [args.ckpt_path],
        folders=[args.streaming],
        protected=[args.ckpt_path],
    )
    if output.suffix != ".onnx":
        raise ValueError(f"--output must end in .onnx, got {output}")
    if args.streaming is not None:  # the folder holds one checkpoint's graphs (stamlane.safety.owner)
        owner = {"command": "export", "model": str(args.ckpt_path.resolve())}
        mark(claim(args.streaming, owner, "--streaming"), owner)
    return _write(args, opset, outputs)


def _write(args: Any, opset: int, outputs: list[Path]) -> int:
    import time

    from stamlane.stream.export import export_clip, export_encoder, export_fuse_decode
    from stamlane.stream.metadata import annotate, deployment_metadata
    from stamlane.training.stored import StoredModel

    start = time.perf_counter()
    model = StoredModel.open(args.ckpt_path)  # the checkpoint read once, the network from the closed registry
    module = model.module
    common = deployment_metadata(module, model.settings.clip, args.ckpt_path, opset)
    num_frames, size = common["num_frames"], tuple(common["image_size"])
    net: Any = module.net  # the buffers of tracing a clip, counted before one is made (a checkpoint's recorded size)
    shape = (net.encoder.out_channels, net.encoder.strides, int(getattr(net.decoder, "embed_dim", 4)))
    check_stream_buffers(num_frames, size, *shape, f"export of {args.ckpt_path}", clips=True)
    writers = {
        "clip": lambda path: export_clip(module.net, path, num_frames, size, opset),
        "encoder": lambda path: export_encoder(module.net, path, size, opset),
        "fuse_decode": lambda path: export_fuse_decode(module.net, path, num_frames, size, opset),
    }
    for graph, path in zip(("clip", *STREAMING_GRAPHS), outputs):
        with atomic_path(path) as tmp:  # written whole (graph and metadata), then renamed over the output
            writers[graph](tmp)
            annotate(tmp, graph, common)
    seconds = time.perf_counter() - start
    size_mb = outputs[0].stat().st_size / 1e6
    print(
        f"stamlane export: {', '.join(map(str, outputs))} (T={num_frames}, {format_wxh(size)}, opset {opset}, "
        f"{size_mb:.1f} MB, {seconds:.1f} s; preprocessing and decoding settings in the metadata)"
    )
    diff = parity(module.net, outputs[0], num_frames, size)
    print(
        f"  parity with PyTorch, float32 both, on a random clip: max |logits| diff {diff['logits']:.2e}, "
        f"max |embedding| diff {diff['embedding']:.2e}"
    )
    if module.bf16:
        print(
            "  note: stamlane predict / stream run this model in bfloat16 autocast on this CPU; their logits differ "
            "from this float32 graph's by more than the parity above (docs/streaming.md, 'float32 and bfloat16')"
        )
    return 0


def main(argv: list[str] | None = None) -> int:
    args = parse_or_status(build_parser(), argv)
    if isinstance(args, int):
        return args
    return run_command("stamlane export", lambda: _export(args))  # a CheckpointError is a ValueError


if __name__ == "__main__":
    sys.exit(main())
