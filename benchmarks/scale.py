"""Cost at scale: seconds per training step and peak memory of the paper's model against image size, frames and
width; data loading per sample (alignment cache / on the fly) against the step; the loader workers that keep a
step fed.

Usage::

    python benchmarks/scale.py                       # the full sweep on the CPU
    python benchmarks/scale.py --quick               # every measurement, tiny (a smoke test, as CI runs it)
    python benchmarks/scale.py --device cuda --batch 4 8   # on a GPU (GPU memory, steps per second)

Writes ``--out`` (default ``outputs/bench/scale.json``) and a markdown table beside it (``.md``). What is measured:

- **a training step** of `StamLaneModule` (forward, `LaneLoss`, backward, the paper's SGD step; ``model.bf16:
  auto``, as ``stamlane fit`` runs it) on a batch of random frames with four drawn lanes (a step's cost does not
  depend on what the frames show): the median of ``--steps`` timed steps after ``--warmup`` untimed ones (on the
  CPU the process time of the step, ``--threads`` threads: what it costs, not what the neighbours of a shared
  machine add; the wall times are kept beside it; on a GPU the synchronised wall time), each
  configuration in a fresh process, whose peak resident memory (CPU: ``ru_maxrss``, the whole process, torch
  included) or peak allocated GPU memory (``torch.cuda.max_memory_allocated``) is the configuration's. One axis
  varies at a time around the paper's model (VGG16-BN width 1.0, 4 frames, mixed C-S STAM, 256x512, batch 1):
  image size 80x256 / 256x512 / 368x640, frames 1-5, width 0.25 / 0.5 / 1.0, and ``--batch``;
- **loading a sample** (`TuSimpleClips.__getitem__`: decoding the T frames, alignment, warping, resizing, the
  targets) of a small synthetic set in TuSimple's layout (``stamlane synth --layout tusimple``) at TuSimple's
  1280x720, with the alignment read from ``stamlane align``'s cache or estimated on the fly (ORB + RANSAC): the
  median over the set's key frames, the first read of each clip (nothing memoised);
- **workers that keep a step fed**: ``ceil(batch x load / step)`` DataLoader workers load a batch in the time a
  step takes (each worker loads whole batches, one sample after another).

Timings on a shared machine are noisy: compare the ratios of one run, which are measured side by side.

A bad option is one line on stderr and exit status 2, before anything runs or is written (`_harness`): an ``--out``
that is a folder, lies under a file or cannot be written; with ``--replot`` an ``--out`` that is not this script's
JSON.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before torch: spinning OpenMP threads starve a shared CPU

import argparse
import functools
import importlib
import importlib.metadata
import math
import multiprocessing
import resource
import statistics
import tempfile
import time
from pathlib import Path

from _harness import BenchInputError, check_out_file, fail, machine, read_json_object, write_figure, write_result

PAPER = {"width": 1.0, "frames": 4, "size": (256, 512), "batch": 1}
"""The centre of every sweep: the paper's model (configs/tusimple_stam4.yaml) at batch 1."""
FULL = {
    "size": [(80, 256), (256, 512), (368, 640)],
    "frames": [1, 2, 3, 4, 5],
    "width": [0.25, 0.5, 1.0],
}
"""The values each axis takes in the full sweep (the others at `PAPER`'s)."""
QUICK_PAPER = {"width": 0.25, "frames": 2, "size": (64, 128), "batch": 1}
QUICK = {"size": [(32, 64)], "frames": [1], "width": [0.125]}
"""``--quick``: every kind of measurement, each tiny (what a smoke test runs)."""


def _peak_rss_mb() -> float:
    """Peak resident memory of this process, MB (``ru_maxrss`` is KiB on Linux)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _batch(batch: int, frames: int, size: tuple[int, int], device: str) -> dict:
    """A training batch of random frames (B, T, 3, H, W) and targets with four lanes (what the loss needs)."""
    import torch

    height, width = size
    generator = torch.Generator().manual_seed(0)
    instance = torch.zeros(batch, height, width, dtype=torch.long)
    for lane, x in enumerate(range(width // 5, width, width // 5)[:4], start=1):
        instance[:, height // 3 :, x : x + 3] = lane
    return {
        "frames": torch.rand(batch, frames, 3, height, width, generator=generator).to(device),
        "binary": (instance > 0).long().to(device),
        "instance": instance.to(device),
    }


def _step_cost(config: dict) -> dict:
    """Seconds per training step (median of ``steps`` after ``warmup``) and peak memory of one configuration; runs
    in a fresh process (`measure_step`)."""
    import torch

    from stamlane.models import STAM, LaneDecoder, VGGEncoder
    from stamlane.training.losses import LaneLoss
    from stamlane.training.module import StamLaneModule, paper_sgd

    torch.set_num_threads(config["threads"])
    torch.manual_seed(0)
    device = config["device"]
    size = tuple(config["size"])
    module = StamLaneModule(  # configs/tusimple_stam4.yaml's model
        VGGEncoder(config["width"]),
        functools.partial(STAM, mode="mixed", order="cs", reduction=16, kernel_size=7, reading="gates"),
        functools.partial(LaneDecoder, embed_dim=4),
        LaneLoss(delta_v=0.5, delta_d=1.5),
        num_frames=config["frames"],
        image_size=size,
    ).to(device)
    module.train()
    optimizer = paper_sgd(module.parameters())
    batch = _batch(config["batch"], config["frames"], size, device)
    if device == "cuda":
        torch.cuda.reset_peak_memory_stats()

    def step() -> tuple[float, float]:
        start, cpu = time.perf_counter(), time.process_time()
        optimizer.zero_grad(set_to_none=True)
        logits, embedding = module._run(batch)
        module._losses(batch, logits, embedding)["loss"].backward()
        optimizer.step()
        if device == "cuda":
            torch.cuda.synchronize()
        return time.perf_counter() - start, time.process_time() - cpu

    for _ in range(config["warmup"]):
        step()
    times = [step() for _ in range(config["steps"])]
    wall, cpu = [t[0] for t in times], [t[1] for t in times]
    out = {
        **config,
        # on the CPU the process time: what the step costs the threads that run it, whatever else the machine
        # runs (wall time on a shared CPU measures the neighbours too); on a GPU the wall time, synchronised
        "step_s": statistics.median(cpu if device == "cpu" else wall),
        "step_wall_s": wall,
        "step_cpu_s": cpu,
        "bf16": bool(module.bf16),
        "params_m": sum(p.numel() for p in module.parameters()) / 1e6,
        "peak_rss_mb": _peak_rss_mb(),
    }
    if device == "cuda":
        out["peak_gpu_mb"] = torch.cuda.max_memory_allocated() / 2**20
        out["gpu"] = torch.cuda.get_device_name()
    return out


def measure_step(config: dict) -> dict:
    """`_step_cost` in a fresh process, so that its peak memory is this configuration's alone: forked on the CPU
    from a parent that has imported torch and the model but run nothing (the child starts where a spawned one
    would be after its imports, in a fraction of the time), spawned for CUDA (a forked CUDA context is unusable)."""
    method = "spawn" if config["device"] == "cuda" else "fork"
    if method == "fork":  # imported once here, inherited by every child
        importlib.import_module("stamlane.models")
        importlib.import_module("stamlane.training.module")
    with multiprocessing.get_context(method).Pool(1) as pool:
        return pool.apply(_step_cost, (config,))


def make_set(root: Path, size: tuple[int, int], clips: int, frames: int) -> None:
    """A small synthetic set in TuSimple's layout at ``size`` (H, W), ``clips`` val clips of ``frames`` frames, and
    its alignment cache (``stamlane align``, the last frame of each clip)."""
    from stamlane.align.cli import main as align_main
    from stamlane.synth.config import SynthConfig
    from stamlane.synth.dataset import generate_dataset
    from stamlane.synth.layout import SplitCounts

    config = SynthConfig(height=size[0], width=size[1], num_frames=frames)
    generate_dataset(root, SplitCounts(val=clips), config=config, progress=False, layout="tusimple", visibility=False)
    status = align_main([str(root), "--cache", str(root / "alignment"), "--num-frames", str(frames), "--quiet"])
    if status != 0:
        raise RuntimeError(f"stamlane align failed on {root} (status {status})")


def measure_loading(root: Path, frames: int, size: tuple[int, int], threads: int) -> dict[str, dict]:
    """Median seconds (process time) to load one sample (`TuSimpleClips.__getitem__`) with the alignment from the
    cache and on the fly, every clip read once (a fresh dataset per mode: nothing memoised)."""
    import cv2
    import torch

    from stamlane.data.layouts import TuSimpleClips
    from stamlane.data.options import ClipOptions

    torch.set_num_threads(threads)
    cv2.setNumThreads(threads)
    out = {}
    for align in ("cache", "fly"):
        clip = ClipOptions(num_frames=frames, image_size=size, align=align, cache_dir=str(root / "alignment"))
        dataset = TuSimpleClips(root, ["label_data_0531.json"], clip=clip)
        times, walls = [], []
        for i in range(len(dataset)):
            start, cpu = time.perf_counter(), time.process_time()
            dataset[i]
            walls.append(time.perf_counter() - start)
            times.append(time.process_time() - cpu)
        out[align] = {"load_s": statistics.median(times), "samples": len(times), "failures": dataset.aligner.failures}
        out[align]["load_wall_s"] = statistics.median(walls)
    return out


def workers_to_feed(load_s: float, step_s: float, batch: int) -> int:
    """DataLoader workers that load a batch of ``batch`` samples (``load_s`` each) while a step (``step_s``) runs."""
    return max(1, math.ceil(batch * load_s / step_s))


def _sweep(centre: dict, axes: dict[str, list], batches: list[int]) -> list[dict]:
    """Configurations: ``centre``, then each axis's values with the others at the centre, then each batch size."""
    configs = [dict(centre)]
    for axis, values in (*axes.items(), ("batch", batches)):
        for value in values:
            config = dict(centre, **{axis: value})
            if config not in configs:
                configs.append(config)
    return configs


def _table(rows: list[dict], centre: dict) -> str:
    base = next(r for r in rows if all(r[k] == v for k, v in centre.items()))
    memory = "peak GPU MB" if "peak_gpu_mb" in base else "peak RSS MB"
    lines = [
        f"| width | frames | image | batch | s / step | x first row | {memory} | bf16 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        mem = r.get("peak_gpu_mb", r["peak_rss_mb"])
        lines.append(
            f"| {r['width']:g} | {r['frames']} | {r['size'][0]}x{r['size'][1]} | {r['batch']} | {r['step_s']:.2f} | "
            f"{r['step_s'] / base['step_s']:.2f} | {mem:.0f} | {'yes' if r['bf16'] else 'no'} |"
        )
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="every measurement, tiny (a smoke test)")
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda"), help="where the steps run")
    parser.add_argument("--batch", type=int, nargs="+", default=None, help="batch sizes besides 1 (default 2)")
    parser.add_argument("--steps", type=int, default=2, help="timed steps per configuration (median)")
    parser.add_argument("--warmup", type=int, default=1, help="untimed steps first")
    parser.add_argument("--threads", type=int, default=1, help="torch intra-op threads (default 1: a shared CPU)")
    parser.add_argument("--only", choices=("steps", "loading"), default=None, help="one of the two parts alone")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/scale.json"))
    parser.add_argument("--replot", action="store_true", help="only rewrite the table and plot of --out's json")
    return parser


def main(argv: list[str] | None = None) -> int:
    from stamlane.safety.guard import GuardError

    args = _parser().parse_args(argv)
    try:
        check_out_file(args.out, side=(".md", ".png"))  # before any work: --out and the files beside it
        if args.replot:
            payload = read_json_object(args.out, "--out", keys=("centre", "device", "cpu", "cores", "threads"))
            print(report(payload, args.out))
            return 0
    except (GuardError, BenchInputError) as err:
        return fail("scale.py", err)
    except (KeyError, TypeError, ValueError, IndexError) as err:  # parsed, but not what this script writes
        return fail("scale.py", f"--out {args.out} is not a scale.py result ({type(err).__name__}: {err})")
    if args.steps < 1 or args.warmup < 0 or args.threads < 1 or (args.batch and min(args.batch) < 1):
        return fail("scale.py", "--steps, --threads and --batch must be >= 1, --warmup >= 0")
    if args.device == "cuda":
        import torch

        if not torch.cuda.is_available():
            return fail("scale.py", "--device cuda but torch sees no CUDA device")
    centre, axes = (QUICK_PAPER, QUICK) if args.quick else (PAPER, FULL)
    batches = args.batch if args.batch is not None else ([2] if not args.quick else [])
    started = time.perf_counter()
    payload: dict = {
        **machine(),
        "device": args.device,
        "torch": importlib.metadata.version("torch"),
        "threads": args.threads,
        "quick": args.quick,
        "steps": args.steps,
        "warmup": args.warmup,
        "centre": {**centre, "size": list(centre["size"])},
    }
    rows: list[dict] = []
    if args.only in (None, "steps"):
        for config in _sweep(centre, axes, batches):
            config = {**config, "device": args.device, "threads": args.threads}
            config |= {"steps": args.steps, "warmup": args.warmup}
            row = measure_step(config)
            rows.append(row)
            print(
                f"width {row['width']:g}, {row['frames']} frames, {row['size'][0]}x{row['size'][1]}, batch "
                f"{row['batch']}: {row['step_s']:.3f} s/step, peak {row.get('peak_gpu_mb', row['peak_rss_mb']):.0f} MB",
                flush=True,
            )
        payload["steps_table"] = rows
    if args.only in (None, "loading"):
        source = (180, 320) if args.quick else (720, 1280)
        with tempfile.TemporaryDirectory(prefix="scale-") as tmp:
            make_set(Path(tmp), source, clips=2 if args.quick else 4, frames=centre["frames"])
            loading = measure_loading(Path(tmp), centre["frames"], tuple(centre["size"]), args.threads)
        payload["loading"] = {"source_size": list(source), **loading}
        step = next((r for r in rows if all(r[k] == v for k, v in centre.items())), None)
        for align, result in loading.items():
            line = f"loading a sample ({align}, {source[1]}x{source[0]} frames): {result['load_s']:.3f} s"
            if step is not None:
                feed = {
                    b: workers_to_feed(result["load_s"], r["step_s"], b) for b, r in _by_batch(rows, centre).items()
                }
                result["load_over_step"] = result["load_s"] / step["step_s"]
                result["workers_to_feed"] = feed
                line += f" = {result['load_over_step']:.3f} of a step; workers to keep a step fed: {feed}"
            print(line, flush=True)
    payload["seconds"] = time.perf_counter() - started
    write_result(args.out, payload, indent=2, quiet=True)
    print("\n" + report(payload, args.out))
    print(f"\nwrote {args.out} ({payload['seconds']:.0f} s)")
    return 0


def report(payload: dict, out: Path) -> str:
    """Write the markdown table (``out`` with ``.md``) and, where matplotlib is installed, the curves (``.png``)
    of a run's ``payload``; returns the table."""
    centre = {**payload["centre"], "size": tuple(payload["centre"]["size"])}
    rows = [{**r, "size": tuple(r["size"])} for r in payload.get("steps_table", [])]
    clock = "CPU seconds (process time)" if payload["device"] == "cpu" else "seconds"
    lines = [
        f"{payload['cpu']} ({payload['cores']} cores, shared), {payload['device']}, {payload['threads']} thread(s); "
        f"{clock} per step, median of {payload['steps']} after {payload['warmup']} warm-up",
        "",
    ]
    if rows:
        lines += [_table(rows, centre), ""]
    loading = payload.get("loading")
    if loading:
        h, w = loading["source_size"]
        lines += [f"| loading a sample ({w}x{h} frames) | s | of a step | workers to feed a step, per batch |"]
        lines += ["|---|---|---|---|"]
        for align in ("cache", "fly"):
            r = loading[align]
            feed = ", ".join(f"batch {b}: {n}" for b, n in r.get("workers_to_feed", {}).items())
            lines += [
                f"| alignment {align} | {r['load_s']:.3f} | {r.get('load_over_step', float('nan')):.3f} | {feed} |"
            ]
    text = "\n".join(lines) + "\n"
    from stamlane.safety.guard import write_atomic

    write_atomic(out.with_suffix(".md"), text)
    if rows:
        _plot(rows, centre, out.with_suffix(".png"), lines[0])
    return text


def _plot(rows: list[dict], centre: dict, path: Path, title: str) -> None:
    """Seconds per step and peak memory against each axis (the others at ``centre``)."""
    try:
        import matplotlib
    except ImportError:
        return
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes_of = {
        "size": ("image pixels (M)", lambda v: v[0] * v[1] / 1e6),
        "frames": ("frames", float),
        "width": ("width", float),
        "batch": ("batch", float),
    }
    fig, axes = plt.subplots(2, 4, figsize=(16, 6.5))
    for col, (axis, (label, value)) in enumerate(axes_of.items()):
        mine = sorted(
            (r for r in rows if all(r[k] == centre[k] for k in centre if k != axis)), key=lambda r: value(r[axis])
        )
        xs = [value(r[axis]) for r in mine]
        axes[0, col].plot(xs, [r["step_s"] for r in mine], "o-")
        axes[1, col].plot(xs, [r.get("peak_gpu_mb", r["peak_rss_mb"]) / 1024 for r in mine], "o-", color="C1")
        axes[0, col].set_title(f"s / step against {axis}")
        axes[1, col].set_xlabel(label)
        axes[1, col].set_ylabel("peak memory (GB)")
        for ax in axes[:, col]:
            ax.set_ylim(bottom=0)
            ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    write_figure(fig, path, dpi=80)


def _by_batch(rows: list[dict], centre: dict) -> dict[int, dict]:
    """The paper model's row of each batch size (width, frames and size at the centre)."""
    keys = ("width", "frames", "size")
    return {r["batch"]: r for r in rows if all(r[k] == centre[k] for k in keys)}


if __name__ == "__main__":
    raise SystemExit(main())
