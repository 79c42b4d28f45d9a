"""The alignment presets side by side (`stamlane.align.homography.ALIGN_PRESETS`): speed and accuracy per frame pair.

Pairs with a known homography, as `benchmarks/align.py` makes them but at the demo's and the stream's frame size:
the six real 1280x720 road frames of ``../shared/data/frames`` resized to ``--size`` (default 640x360) are the history
frames; each key frame is the history frame warped by a random ground-plane ego-motion of a pinhole camera of that
size (f = 500 px at 640 wide, 1.5 m high; forward 0.5-2 m, yaw ±2°, pitch ±0.5°), then a brightness / contrast change,
Gaussian noise and JPEG artefacts. Every preset estimates every pair with ``estimate_homography`` (both frames'
features included), one OpenCV thread; the presets take turns pair by pair so that a busy machine slows them alike.

Corner error and success as `benchmarks/align.py`: the key frame's ground-region corners (rows 0.45 H..H-1) taken
to the history frame by the truth and back by the estimate, mean distance in key pixels; success: ``ok`` and
error < 3 px. Time: CPU time of the working thread per pair, the median over pairs, per ``--repeats``.

    python benchmarks/align_presets.py [--pairs-per-frame 20] [--repeats 3] [--size 640 360]
        [--out docs/results/speed/align_presets.json]

Skips (exit 0, with a reason) where ``../shared/data/frames`` is absent.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import cv2
import numpy as np
from _harness import guard_out, load_1min, machine, write_result
from align import FRAMES, SUCCESS_PX, corner_error, degrade, random_motion

from stamlane.align.egomotion import RoadCamera, key_from_hist_motion
from stamlane.align.homography import ALIGN_PRESETS, default_horizon_row, estimate_homography

REPO = Path(__file__).resolve().parents[1]


def make_pairs(paths: list[Path], size: tuple[int, int], per_frame: int, seed: int) -> list[tuple]:
    """``(hist, key, truth)`` triples: each real frame resized to ``size`` (W, H), moved by a known ego-motion."""
    width, height = size
    scale = width / 1280
    camera = RoadCamera(width=width, height=height, focal=1000.0 * scale, horizon_row=280.0 * scale)
    rng = np.random.default_rng(seed)
    pairs = []
    for path in paths:
        hist = cv2.resize(cv2.imread(str(path)), size, interpolation=cv2.INTER_AREA)
        for _ in range(per_frame):
            truth = key_from_hist_motion(camera, *random_motion(rng))
            pairs.append((hist, degrade(cv2.warpPerspective(hist, truth, size), rng), truth))
    return pairs


def measure(pairs: list[tuple], presets: list[str]) -> dict[str, dict[str, list[float]]]:
    """Per preset: each pair's corner error, success (1 / 0) and thread CPU ms, the presets taking turns."""
    out: dict[str, dict[str, list[float]]] = {name: {"px": [], "success": [], "ms": []} for name in presets}
    for hist, key, truth in pairs:
        row = default_horizon_row(key.shape[0])
        for name in presets:
            start = time.thread_time()
            alignment = estimate_homography(hist, key, horizon_row=row, config=ALIGN_PRESETS[name])
            out[name]["ms"].append((time.thread_time() - start) * 1000.0)
            error = corner_error(alignment.key_from_hist, truth, key.shape[:2], row)
            out[name]["px"].append(error)
            out[name]["success"].append(float(alignment.ok and error < SUCCESS_PX))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames-dir", type=Path, default=FRAMES)
    p.add_argument("--pairs-per-frame", type=int, default=20)
    p.add_argument("--repeats", type=int, default=3, help="timed passes over every pair (accuracy: the first)")
    p.add_argument("--size", type=int, nargs=2, default=(640, 360), metavar=("W", "H"))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=REPO / "docs" / "results" / "speed" / "align_presets.json")
    args = p.parse_args(argv)

    if (refused := guard_out("align_presets.py", args.out)) is not None:  # before any work
        return refused
    paths = sorted(args.frames_dir.glob("*.jpg"))
    if not paths:
        print(f"skipped: no real frames in {args.frames_dir} (../shared absent)")
        return 0
    cv2.setNumThreads(1)
    record: dict = {"load_1min_at_start": load_1min()}
    pairs = make_pairs(paths, tuple(args.size), args.pairs_per_frame, args.seed)
    presets = list(ALIGN_PRESETS)
    runs = [measure(pairs, presets) for _ in range(args.repeats)]
    summary = {}
    for name in presets:
        px, success = np.array(runs[0][name]["px"]), runs[0][name]["success"]
        medians = [statistics.median(run[name]["ms"]) for run in runs]
        summary[name] = {
            "median_px": round(float(np.median(px)), 3),
            "p95_px": round(float(np.percentile(px, 95)), 3),
            "success": round(float(np.mean(success)), 4),
            "ms_per_pair": round(statistics.median(medians), 2),
            "ms_per_pair_runs": [round(m, 2) for m in medians],
        }
    base = summary["standard"]["ms_per_pair"]
    for name in presets:
        summary[name]["speedup"] = round(base / summary[name]["ms_per_pair"], 2)
    print(f"{len(pairs)} real-frame pairs at {args.size[0]}x{args.size[1]}, one thread, {args.repeats} runs")
    print("| preset | median px | p95 px | success | ms / pair | x standard |\n|---|---|---|---|---|---|")
    for name, s in summary.items():
        print(
            f"| {name} | {s['median_px']:.3f} | {s['p95_px']:.3f} | {100 * s['success']:.1f} % | "
            f"{s['ms_per_pair']:.1f} | {s['speedup']:.2f} |"
        )
    record |= {
        "size": list(args.size),
        "pairs": len(pairs),
        "repeats": args.repeats,
        "presets": {name: repr(ALIGN_PRESETS[name]) for name in presets},
        "summary": summary,
    }
    write_result(args.out, machine() | record)  # after the timings: machine() imports torch
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
