"""Time ``stamlane.predict.postprocess.decode_lanes`` per frame at the network resolution (docs/method.md §5).

Synthetic heads: ``--lanes`` curved lanes ``--width`` px wide over the lower part of an H x W frame,
embeddings drawn around cluster means 3.0 apart (the loss's ``2 * delta_d``) with spread ``--spread``,
plus ``--noise`` false-positive pixels. Prints a table of median / p90 wall ms and median CPU ms (process time: what the frame costs when the
machine is shared) per frame and writes
``--out`` (json).

    python benchmarks/postprocess.py --size 256 512 --repeats 50
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from _harness import guard_out, machine, write_result

from stamlane.predict.postprocess import PostprocessConfig, decode_lanes


def synthetic_heads(
    height: int, width: int, lanes: int, lane_width: int, spread: float, noise: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(H, W)`` lane probability and ``(4, H, W)`` embeddings of ``lanes`` curved lanes."""
    rng = np.random.default_rng(seed)
    prob = np.zeros((height, width), dtype=np.float32)
    emb = rng.normal(0.0, 1.0, size=(4, height, width)).astype(np.float32)
    means = 3.0 * np.eye(4, dtype=np.float32)[: min(lanes, 4)]
    if lanes > 4:
        means = np.concatenate([means, -3.0 * np.eye(4, dtype=np.float32)[: lanes - 4]])
    top = int(0.4 * height)
    for i in range(lanes):
        for y in range(top, height):
            t = (y - top) / (height - top)
            x_c = width * (0.5 + (i - (lanes - 1) / 2) * 0.08 * (1 + 2.5 * t)) + 10 * t**2
            x0, x1 = int(x_c - lane_width / 2), int(x_c + lane_width / 2) + 1
            x0, x1 = max(x0, 0), min(x1, width)
            if x0 >= x1:
                continue
            prob[y, x0:x1] = 0.95
            emb[:, y, x0:x1] = means[i][:, None] + rng.normal(0.0, spread, size=(4, x1 - x0))
    ys, xs = rng.integers(0, height, noise), rng.integers(0, width, noise)
    prob[ys, xs] = 0.95
    return prob, emb


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", type=int, nargs=2, default=(256, 512), metavar=("H", "W"))
    parser.add_argument("--lanes", type=int, default=4)
    parser.add_argument("--width", type=int, default=5, help="lane width in network pixels")
    parser.add_argument("--spread", type=float, default=0.25, help="embedding std around the lane mean")
    parser.add_argument("--noise", type=int, default=300, help="false-positive lane pixels")
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--max-points", type=int, nargs="+", default=[1000, 2000, 3000])
    parser.add_argument("--out", type=Path, default=Path("outputs/benchmarks/postprocess.json"))
    args = parser.parse_args(argv)

    if (refused := guard_out("postprocess.py", args.out)) is not None:  # before any work
        return refused

    height, width = args.size
    prob, emb = synthetic_heads(height, width, args.lanes, args.width, args.spread, args.noise, seed=0)
    n_pixels = int((prob > 0.5).sum())
    rows = []
    for max_points in args.max_points:
        config = PostprocessConfig(max_points=max_points)
        decode_lanes(prob, emb, config=config)  # warm-up
        times, cpu = [], []
        for _ in range(args.repeats):
            start, start_cpu = time.perf_counter(), time.process_time()
            lanes = decode_lanes(prob, emb, config=config)
            times.append((time.perf_counter() - start) * 1000.0)
            cpu.append((time.process_time() - start_cpu) * 1000.0)
        rows.append(
            {
                "max_points": max_points,
                "median_ms": float(np.median(times)),
                "median_cpu_ms": float(np.median(cpu)),
                "p90_ms": float(np.percentile(times, 90)),
                "lanes_found": len(lanes),
            }
        )
    print(f"decode_lanes at {height}x{width}, {n_pixels} lane pixels, {args.lanes} lanes, {args.repeats} repeats")
    print(f"{'max_points':>10} {'median ms':>10} {'p90 ms':>8} {'CPU ms':>7} {'lanes':>6}")
    for row in rows:
        print(
            f"{row['max_points']:>10} {row['median_ms']:>10.1f} {row['p90_ms']:>8.1f} "
            f"{row['median_cpu_ms']:>7.1f} {row['lanes_found']:>6}"
        )
    result = {**machine(), "size": [height, width], "lane_pixels": n_pixels, "lanes": args.lanes, "rows": rows}
    write_result(args.out, result, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
