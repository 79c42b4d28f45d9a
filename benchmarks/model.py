"""Model cost: parameters, FLOPs and CPU forward time of LaneNet for every fusion, plus the bf16 speed-up.

Usage::

    python benchmarks/model.py                      # widths 1.0 and 0.25, 4x3x256x512 clip, every fusion
    python benchmarks/model.py --widths 0.25 --fusions stam-mixed-cs-features key_frame_only --repeats 5

Prints a markdown table and writes json to ``--out`` (default ``outputs/bench/model.json``). FLOPs are
``torch.utils.flop_counter`` counts (2 x multiply-accumulates of convolutions and matrix products;
element-wise ops, pooling and normalisation are not counted). Forward time is the median of ``--repeats``
timed runs after one untimed run, batch 1, fp32, eval mode, ``--threads`` intra-op threads. The training-step
ratio times forward + `LaneLoss` + backward + SGD step at width 0.25 (fp32 vs bf16 autocast + channels_last).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before torch: spinning OpenMP threads starve a shared CPU

import argparse
import functools
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import torch
from _harness import fail, guard_out, machine, option_problem, write_result
from torch import nn
from torch.utils.flop_counter import FlopCounterMode
from tqdm import tqdm

from stamlane.models import (
    STAM,
    STPSA,
    ConvLSTMFusion,
    CosineWeightedSum,
    KeyFrameOnly,
    LaneDecoder,
    LaneNet,
    SimpleAdd,
    STDANet,
    VGGEncoder,
)
from stamlane.training.losses import LaneLoss


def _fusions() -> dict[str, Callable[[int], nn.Module]]:
    table: dict[str, Callable[[int], nn.Module]] = {
        "key_frame_only": KeyFrameOnly,
        "simple_add": SimpleAdd,
        "convlstm": ConvLSTMFusion,
        "cosine": CosineWeightedSum,
        "stdanet": STDANet,
        "stpsa": STPSA,
    }
    for reading in ("gates", "features"):
        for mode, order in (("parallel", "cs"), ("serial", "cs"), ("serial", "sc"), ("mixed", "cs"), ("mixed", "sc")):
            name = f"stam-{mode}" + ("" if mode == "parallel" else f"-{order}") + f"-{reading}"
            table[name] = functools.partial(STAM, mode=mode, order=order, reading=reading)
    return table


FUSIONS = _fusions()


def _flops(module: nn.Module, *inputs: torch.Tensor) -> int:
    with torch.no_grad(), FlopCounterMode(display=False) as counter:
        module(*inputs)
    return counter.get_total_flops()


def _timings(fn: Callable[[], object], repeats: int) -> list[float]:
    fn()  # warm-up (allocator, oneDNN primitive cache)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return times


@functools.cache
def _base_flops(width: float, clip_shape: tuple[int, ...]) -> int:
    """FLOPs of encoder + decoder (the model with the parameter- and FLOP-free key-frame-only fusion)."""
    model = LaneNet(VGGEncoder(width), KeyFrameOnly, LaneDecoder).eval()
    return _flops(model, torch.rand(clip_shape))


def measure_forward(width: float, fusion: str, clip_shape: tuple[int, ...], repeats: int) -> dict:
    """Parameters, FLOPs and fp32 forward time (median and min of ``repeats``) of LaneNet on one clip (B, T, 3, H, W)."""
    torch.manual_seed(0)
    model = LaneNet(VGGEncoder(width), FUSIONS[fusion], LaneDecoder).eval()
    clip = torch.rand(clip_shape)
    channels = model.encoder.out_channels[-1]
    stride = model.encoder.strides[-1]
    feats = torch.rand(clip_shape[0], clip_shape[1], channels, clip_shape[3] // stride, clip_shape[4] // stride)
    with torch.no_grad():
        times = _timings(lambda: model(clip), repeats)
        fusion_times = _timings(lambda: model.fusion(feats), max(repeats, 5))
    fusion_flops = _flops(model.fusion, feats)
    return {
        "width": width,
        "fusion": fusion,
        "params": sum(p.numel() for p in model.parameters()),
        "fusion_params": sum(p.numel() for p in model.fusion.parameters()),
        "gflops": (_base_flops(width, clip_shape) + fusion_flops) / 1e9,
        "fusion_gflops": fusion_flops / 1e9,
        "forward_ms": 1e3 * statistics.median(times),
        "forward_min_ms": 1e3 * min(times),
        "fusion_forward_ms": 1e3 * statistics.median(fusion_times),
    }


def _synthetic_targets(batch: int, height: int, width: int) -> tuple[torch.Tensor, torch.Tensor]:
    instance = torch.zeros(batch, height, width, dtype=torch.long)
    for lane, x in enumerate(range(width // 5, width, width // 5)[:4], start=1):
        instance[:, height // 3 :, x : x + 3] = lane
    return (instance > 0).long(), instance


def _train_step_seconds(
    width: float, fusion: str, clip_shape: tuple[int, ...], repeats: int, bf16: bool, channels_last: bool
) -> float:
    torch.manual_seed(0)
    model = LaneNet(VGGEncoder(width), FUSIONS[fusion], LaneDecoder).train()
    if channels_last:
        model = model.to(memory_format=torch.channels_last)
    optimizer = torch.optim.SGD(model.parameters(), lr=1e-3, momentum=0.9)
    loss_fn = LaneLoss()
    clip = torch.rand(clip_shape)
    binary, instance = _synthetic_targets(clip_shape[0], clip_shape[3], clip_shape[4])

    def step() -> None:
        optimizer.zero_grad(set_to_none=True)
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            logits, embedding = model(clip)
        loss_fn(logits, embedding, binary, instance)["loss"].backward()
        optimizer.step()

    return statistics.median(_timings(step, repeats))


TRAIN_VARIANTS = {  # name: (bf16 autocast, channels_last)
    "fp32": (False, False),
    "fp32_channels_last": (False, True),
    "bf16": (True, False),
    "bf16_channels_last": (True, True),
}


def measure_train_step_ratio(width: float, fusion: str, clip_shape: tuple[int, ...], repeats: int) -> dict:
    """Median training-step time (forward, LaneLoss, backward, SGD step) for fp32 / bf16 autocast, with and
    without channels_last; ``speedup`` = fp32 / (bf16 + channels_last)."""
    step_ms = {
        name: 1e3 * _train_step_seconds(width, fusion, clip_shape, repeats, bf16, channels_last)
        for name, (bf16, channels_last) in tqdm(TRAIN_VARIANTS.items(), desc="train step", unit="variant")
    }
    return {
        "width": width,
        "fusion": fusion,
        "clip_shape": list(clip_shape),
        "step_ms": step_ms,
        "speedup": step_ms["fp32"] / step_ms["bf16_channels_last"],
    }


def _table(rows: list[dict]) -> str:
    lines = [
        "| width | fusion | params (M) | fusion params (k) | GFLOPs | fusion GFLOPs | forward median / min (ms) | fusion alone (ms) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['width']:g} | {r['fusion']} | {r['params'] / 1e6:.2f} | {r['fusion_params'] / 1e3:.1f} | "
            f"{r['gflops']:.1f} | {r['fusion_gflops']:.2f} | {r['forward_ms']:.0f} / {r['forward_min_ms']:.0f} | {r['fusion_forward_ms']:.1f} |"
        )
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--widths", type=float, nargs="+", default=[1.0, 0.25], help="encoder width multipliers")
    parser.add_argument(
        "--fusions", nargs="+", default=list(FUSIONS), help=f"fusions to time, from: {' '.join(FUSIONS)}"
    )
    parser.add_argument("--clip", type=int, nargs=4, default=[4, 3, 256, 512], metavar=("T", "C", "H", "W"))
    parser.add_argument("--repeats", type=int, default=3, help="timed forward runs per model (median)")
    parser.add_argument(
        "--train-clip", type=int, nargs=5, default=[4, 4, 3, 128, 256], metavar=("B", "T", "C", "H", "W")
    )
    parser.add_argument("--train-width", type=float, default=0.25)
    parser.add_argument("--train-repeats", type=int, default=5, help="timed training steps per precision (0: skip)")
    parser.add_argument("--threads", type=int, default=torch.get_num_threads(), help="torch intra-op threads")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/model.json"))
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)

    if (refused := guard_out("model.py", args.out)) is not None:  # before any work
        return refused
    if (problem := option_problem(vars(args), choices={"fusions": list(FUSIONS)})) is not None:
        return fail("model.py", problem)
    t, c, h, w = args.clip
    if c != 3 or h % 16 or w % 16 or t < 1 or args.repeats < 1 or min(args.widths) <= 0:
        return fail(
            "model.py", f"need --clip T 3 H W with H, W multiples of 16, --repeats >= 1, widths > 0; got {args.clip}"
        )
    torch.set_num_threads(args.threads)
    info = machine()
    rows = []
    jobs = [(width, fusion) for width in args.widths for fusion in args.fusions]
    for width, fusion in tqdm(jobs, desc="forward", unit="model"):
        rows.append(measure_forward(width, fusion, (1, t, c, h, w), args.repeats))
    print(f"\nLaneNet, one {t}x{c}x{h}x{w} clip, fp32 eval, {args.threads} threads, {info['cpu']}\n")
    print(_table(rows))
    train = None
    if args.train_repeats > 0:
        fusion = "stam-mixed-cs-features"
        train = measure_train_step_ratio(args.train_width, fusion, tuple(args.train_clip), args.train_repeats)
        steps = ", ".join(f"{name} {ms:.0f} ms" for name, ms in train["step_ms"].items())
        print(
            f"\ntraining step (median of {args.train_repeats}), width {args.train_width:g}, "
            f"clip {'x'.join(map(str, args.train_clip))}, {fusion}: {steps}; fp32 / bf16+channels_last = {train['speedup']:.2f}x"
        )
    payload = {
        **info,
        "torch": torch.__version__,
        "threads": args.threads,
        "clip": [1, t, c, h, w],
        "forward": rows,
        "train_step": train,
    }
    print()
    write_result(args.out, payload, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
