"""``stamlane export``: a checkpoint to ONNX, with the parity against PyTorch measured and printed.

    stamlane export --ckpt_path RUN/checkpoints/last.ckpt [--output model.onnx] [--opset 17] [--streaming DIR]

Writes the whole clip model (input ``clip`` (B, T, 3, H, W) float32 RGB in [0, 1], key frame last, history
pre-aligned; outputs ``logits`` (B, 2, H, W) and ``embedding`` (B, E, H, W); see `stamlane.stream.export`) to
``--output`` (default: the checkpoint's path with ``.onnx``), and with ``--streaming DIR`` also the two graphs of
the streaming predictor. The network is built from the checkpoint alone, from the closed registry (`stamlane.registry`:
nothing the file names is imported). Parity: onnxruntime and PyTorch run on the same random clip and the largest absolute differences are
printed; without onnxruntime (``pip install "stamlane[export]"``) the files are written and parity is skipped.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
from stamlane_eval.cli_tools import OneLineParser, format_wxh, parse_or_status

from stamlane.safety.boundary import expected_errors, one_line
from stamlane.safety.guard import check_outputs

__all__ = ["build_parser", "main", "parity"]


def build_parser() -> OneLineParser:
    p = OneLineParser(prog="stamlane export", description=__doc__.split("\n")[0])
    p.add_argument("--ckpt_path", required=True, type=Path, help="a checkpoint of `stamlane fit`")
    p.add_argument("--output", type=Path, default=None, help="the .onnx file (default: the checkpoint's, .onnx)")
    p.add_argument("--opset", type=int, default=None, help="ONNX opset (default 17; >= 16 for GridSample)")
    p.add_argument("--streaming", type=Path, default=None, help="also write encoder/fuse_decode graphs here")
    return p


def parity(net: object, path: Path, num_frames: int, image_size: tuple[int, int], seed: int = 0) -> dict:
    """Largest absolute difference between onnxruntime on ``path`` and PyTorch on one random clip.

    Returns:
        ``{"logits": float, "embedding": float}``; empty when onnxruntime is not installed.
    """
    import torch

    try:
        import onnxruntime as ort
    except ImportError:
        return {}
    clip = torch.rand(1, num_frames, 3, *image_size, generator=torch.Generator().manual_seed(seed))
    with torch.no_grad():
        logits, embedding = net.eval()(clip)  # type: ignore[operator]
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    onnx_logits, onnx_embedding = session.run(["logits", "embedding"], {"clip": clip.numpy()})
    return {
        "logits": float(np.abs(onnx_logits - logits.numpy()).max()),
        "embedding": float(np.abs(onnx_embedding - embedding.numpy()).max()),
    }


ONNX_HINT = 'pip install "stamlane[export]"'
"""How the ONNX packages are installed (the ``export`` extra)."""


def _need_onnx() -> None:
    """Refuse at once, with the install line, where the packages ``torch.onnx.export`` needs are missing."""
    import importlib.util

    missing = [name for name in ("onnx", "onnxscript") if importlib.util.find_spec(name) is None]
    if missing:
        raise ValueError(f"exporting to ONNX needs {' and '.join(missing)}: {ONNX_HINT}")


def main(argv: list[str] | None = None) -> int:
    args = parse_or_status(build_parser(), argv)
    if isinstance(args, int):
        return args
    from stamlane.safety.checkpoints import CheckpointError
    from stamlane.stream.export import DEFAULT_OPSET, export_all, export_clip
    from stamlane.training.module import StamLaneModule

    opset = args.opset if args.opset is not None else DEFAULT_OPSET
    output = args.output or args.ckpt_path.with_suffix(".onnx")
    try:
        if not 16 <= opset <= 21:
            raise ValueError(f"--opset must be in 16..21, got {opset}")
        tmp = output.with_name(f".{output.stem}.tmp.onnx")  # written whole, then renamed over the output
        check_outputs([output, tmp], [args.ckpt_path], folders=[args.streaming], protected=[args.ckpt_path])
        _need_onnx()
        if output.suffix != ".onnx":
            raise ValueError(f"--output must end in .onnx, got {output}")
        module = StamLaneModule.from_checkpoint(args.ckpt_path)
        num_frames, image_size = module.num_frames, module.hparams.get("image_size")
        if num_frames is None or image_size is None:
            raise ValueError(f"checkpoint {args.ckpt_path} records no num_frames / image_size")
        size = (int(image_size[0]), int(image_size[1]))
        output.parent.mkdir(parents=True, exist_ok=True)
        export_clip(module.net, tmp, int(num_frames), size, opset)
        os.replace(tmp, output)
        written = [output]
        if args.streaming is not None:
            written += list(export_all(module.net, args.streaming, int(num_frames), size, opset).values())
    except expected_errors(CheckpointError) as err:
        print(f"stamlane export: {one_line(err)}", file=sys.stderr)
        return 2
    print(f"stamlane export: {', '.join(map(str, written))} (T={num_frames}, {format_wxh(size)}, opset {opset})")
    diff = parity(module.net, output, int(num_frames), size)
    if diff:
        print(
            f"  parity with PyTorch on a random clip: max |logits| diff {diff['logits']:.2e}, "
            f"max |embedding| diff {diff['embedding']:.2e}"
        )
    else:
        print('  parity not measured: onnxruntime is not installed (pip install "stamlane[export]")')
    return 0


if __name__ == "__main__":
    sys.exit(main())
