"""Benchmark of the synthetic clip generator: speed, and what each split offers the fusion.

Speed: clips rendered in memory (texture once per clip, one warp per frame, vehicles, shadows, labels)
and, separately, written as JPEG with labels and homographies, in frames per second on one process.
Content per split (normal settings and each challenging factor, ``SynthConfig.with_factor``): the fraction of labelled key-frame
lane points hidden by vehicles, the fraction of those visible in at least one ground-aligned history
frame (T = 4 at stride 1, 2 and 3), and the mean lane shift between the oldest history frame and the key
frame without alignment (what pre-alignment repairs). ``--set`` overrides ``SynthConfig`` fields (e.g.
``--set fps=10 grain=0 prefilter=0 vehicle_ahead=3,30`` for the first generator version).

    python benchmarks/synth.py [--clips 20] [--size 640x360] [--out outputs/bench/synth.json]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _harness import guard_out, machine, write_result
from stamlane_eval.cli_tools import parse_wxh
from synth_align import parse_overrides

from stamlane.synth.generator import FACTORS, SynthConfig, clip_statistics, generate_clip, write_clip


def content(clips: list, stride: int) -> dict[str, float]:
    tot = {"key_points": 0, "hidden": 0, "revealed": 0, "unaligned_shift": 0.0}
    for clip in clips:
        for k, v in clip_statistics(clip, num_frames=4, stride=stride).items():
            tot[k] += v
    return {
        "hidden_fraction": tot["hidden"] / max(tot["key_points"], 1),
        "revealed_fraction_of_hidden": tot["revealed"] / max(tot["hidden"], 1),
        "unaligned_shift_px": tot["unaligned_shift"] / max(len(clips), 1),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--clips", type=int, default=20)
    p.add_argument("--size", default="640x360", help="frame size WxH")
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--set", nargs="*", default=[], help="SynthConfig overrides, e.g. fps=10 grain=0")
    args = p.parse_args(argv)

    if (refused := guard_out("synth.py", args.out)) is not None:  # before any work
        return refused
    overrides = parse_overrides(args.set)
    h, w = parse_wxh(args.size)
    results: dict[str, dict] = {}
    splits = (
        ("normal", SynthConfig(width=w, height=h, **overrides)),
        *((name, SynthConfig.with_factor(name, width=w, height=h, **overrides)) for name in FACTORS),
    )
    for code, (name, cfg) in enumerate(splits):
        start = time.perf_counter()
        clips = [generate_clip(cfg, np.random.default_rng([0, code, i])) for i in range(args.clips)]
        render = time.perf_counter() - start
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            for i, clip in enumerate(clips):
                write_clip(clip, Path(tmp), f"c{i:04d}", cfg.jpeg_quality)
            write = time.perf_counter() - start
        frames = args.clips * cfg.num_frames
        results[name] = {
            "clips": args.clips,
            "frames": frames,
            "render_fps": frames / render,
            "render_and_write_fps": frames / (render + write),
            "stride1": content(clips, 1),
            "stride2": content(clips, 2),
            "stride3": content(clips, 3),
        }
    cfg = splits[0][1]
    print(f"synthetic clips {w}x{h}, {args.clips} clips of {cfg.num_frames} frames at {cfg.fps:g} fps per split")
    print(
        "| split | render fps | render+JPEG fps | hidden | revealed s1 | revealed s2 | revealed s3 "
        "| unaligned shift s1 / s2 / s3 (px) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, r in results.items():
        revealed = " | ".join(f"{100 * r[f'stride{k}']['revealed_fraction_of_hidden']:.1f} %" for k in (1, 2, 3))
        shifts = " / ".join(f"{r[f'stride{k}']['unaligned_shift_px']:.1f}" for k in (1, 2, 3))
        print(
            f"| {name} | {r['render_fps']:.1f} | {r['render_and_write_fps']:.1f} | "
            f"{100 * r['stride1']['hidden_fraction']:.1f} % | {revealed} | {shifts} |"
        )
    if args.out:
        write_result(args.out, results | {"machine": machine()}, indent=2)  # after the timings: machine() imports torch
    return 0


if __name__ == "__main__":
    sys.exit(main())
