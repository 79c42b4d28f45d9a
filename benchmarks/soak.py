"""Soak runs: memory stays bounded on long inputs.

    python benchmarks/soak.py stream --ckpt outputs/demo/stam4-s0/run/checkpoints/last.ckpt [--frames 10000]
    python benchmarks/soak.py eval [--tusimple-images 100000] [--culane-images 100000]

``stream``: `StreamingPredictor` (the loop of ``stamlane stream``: resize, ORB alignment, network, lane decoding)
on ``--frames`` frames cycled from the synthetic clips under ``--frames-root`` (scene cuts between clips, as in a
long drive with gaps), the resident memory (VmRSS) sampled every ``--every`` frames: it must stay flat (the
predictor keeps T-1 feature maps, nothing grows with the stream). Prints the first and last samples and the
largest growth after the warm-up.

``eval``: `stamlane_eval` on generated workloads of the given size (TuSimple json-lines and CULane
``.lines.txt``, ``benchmarks/eval_speed.py``'s generator), each in a fresh process: the peak resident memory
(ru_maxrss) of reading + scoring, against the stated bound: a few hundred bytes per TuSimple image (its records
and per-image results) and a bounded working set for CULane (one image's masks at a time).

Writes json to ``--out`` (default ``outputs/bench/soak.json``).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _harness import BenchInputError, fail, guard_out, machine, read_json_object, write_result
from eval_speed import make_culane, make_tusimple  # a benchmark script beside this one


def rss_mib() -> float:
    """Current resident memory of this process (MiB), from /proc/self/status."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def soak_stream(args: argparse.Namespace) -> dict:
    import cv2
    import torch

    from stamlane.data.clips import frame_order
    from stamlane.stream.predictor import StreamingPredictor
    from stamlane.training.stored import StoredModel

    torch.set_num_threads(args.threads)
    predictor = StreamingPredictor.from_stored(StoredModel.open(args.ckpt))
    clips = sorted(p for p in Path(args.frames_root).glob("*") if p.is_dir())[: args.clips]
    paths = [f for clip in clips for f in sorted(clip.glob("*.jpg"), key=lambda p: frame_order(p.name))]
    if not paths:
        raise SystemExit(f"soak: no frames under {args.frames_root}")
    images = [cv2.imread(str(p)) for p in paths]  # decoded once: the loop measures the predictor, not the disk
    samples: list[tuple[int, float]] = [(0, rss_mib())]
    start = time.perf_counter()
    for k in range(args.frames):
        predictor(images[k % len(images)])
        if (k + 1) % args.every == 0:
            samples.append((k + 1, rss_mib()))
            print(f"frame {k + 1}: VmRSS {samples[-1][1]:.1f} MiB", file=sys.stderr, flush=True)
    seconds = time.perf_counter() - start
    warm = [m for n, m in samples if n >= args.every]  # after the first block (allocator, caches warmed up)
    report = {
        "frames": args.frames,
        "frames_per_s": args.frames / seconds,
        "rss_mib": samples,
        "rss_first_block_mib": warm[0],
        "rss_last_mib": warm[-1],
        "growth_after_first_block_mib": max(warm) - warm[0],
    }
    print(
        f"stream soak: {args.frames} frames at {report['frames_per_s']:.1f} frames/s; VmRSS after the first "
        f"{args.every} frames {warm[0]:.1f} MiB, at the end {warm[-1]:.1f} MiB, largest growth "
        f"{report['growth_after_first_block_mib']:.1f} MiB"
    )
    return report


def _peak_child(code: str) -> tuple[float, float]:
    """Run ``code`` in a fresh Python; its peak resident memory (MiB) and wall time (s)."""
    wrapper = code + "\nimport resource, sys\nprint(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", wrapper], check=True, capture_output=True, text=True).stdout
    return int(out.strip().splitlines()[-1]) / 1024, time.perf_counter() - start


def soak_eval(args: argparse.Namespace) -> dict:
    report: dict = {}
    baseline, _ = _peak_child("import stamlane_eval.tusimple, stamlane_eval.culane, stamlane_eval.io")
    report["import_peak_mib"] = baseline
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.tusimple_images:
            (folder / "ts").mkdir()
            pred, gt = make_tusimple(folder / "ts", args.tusimple_images)
            code = (
                "from stamlane_eval import io, tusimple\n"
                f"r = tusimple.evaluate(io.read_tusimple({str(pred)!r}), io.read_tusimple({str(gt)!r}))\n"
            )
            peak, seconds = _peak_child(code)
            size = (pred.stat().st_size + gt.stat().st_size) / 2**20
            report["tusimple"] = {"images": args.tusimple_images, "peak_mib": peak, "files_mib": size, "s": seconds}
            per_image = (peak - baseline) * 2**20 / args.tusimple_images
            print(
                f"TuSimple {args.tusimple_images} images ({size:.0f} MiB of json): peak {peak:.0f} MiB "
                f"({baseline:.0f} MiB after the imports; {per_image / 1024:.1f} KiB per image), {seconds:.1f} s"
            )
        if args.culane_images:
            pred_dir, gt_dir, listing = make_culane(folder / "cu", args.culane_images)
            code = (
                "from stamlane_eval import culane, io\n"
                f"entries = io.culane_entries({str(gt_dir)!r}, {str(listing)!r})\n"
                f"preds = (io.read_culane_lines(io.culane_lines_path({str(pred_dir)!r}, e)) for e in entries)\n"
                f"gts = (io.read_culane_lines(io.culane_lines_path({str(gt_dir)!r}, e)) for e in entries)\n"
                "r = culane.evaluate(list(preds), list(gts))\n"
            )
            peak, seconds = _peak_child(code)
            report["culane"] = {"images": args.culane_images, "peak_mib": peak, "s": seconds}
            print(
                f"CULane {args.culane_images} images: peak {peak:.0f} MiB ({baseline:.0f} after imports), {seconds:.1f} s"
            )
    return report


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="what", required=True)
    s = sub.add_parser("stream", help="streaming memory over many frames")
    s.add_argument("--ckpt", required=True, type=Path)
    s.add_argument("--frames", type=int, default=10000)
    s.add_argument("--every", type=int, default=500, help="frames between memory samples")
    s.add_argument("--frames-root", type=Path, default=Path("data/synthetic-v4/clips"))
    s.add_argument("--clips", type=int, default=20, help="clips cycled through")
    s.add_argument("--threads", type=int, default=1)
    e = sub.add_parser("eval", help="evaluator peak memory on large workloads")
    e.add_argument("--tusimple-images", type=int, default=100000)
    e.add_argument("--culane-images", type=int, default=100000)
    for sp in (s, e):
        sp.add_argument("--out", type=Path, default=Path("outputs/bench/soak.json"))
    args = p.parse_args(argv)

    if (refused := guard_out("soak.py", args.out)) is not None:  # before any work
        return refused
    try:  # the results of the other part, kept: read (and checked) before this one runs
        old = read_json_object(args.out, "--out") if args.out.exists() else {}
    except BenchInputError as err:
        return fail("soak.py", err)
    report = soak_stream(args) if args.what == "stream" else soak_eval(args)
    report["maxrss_self_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    write_result(args.out, old | {args.what: report | {"machine": machine()}})
    return 0


if __name__ == "__main__":
    sys.exit(main())
