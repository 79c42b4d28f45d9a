"""Prediction passes with and without the frame store (`stamlane.data.frame_store`), side by side at the demo's sizes.

    python benchmarks/frame_store.py [--test 12] [--repeats 5] [--passes 3] [--out outputs/benchmarks/frame_store.json]

On a set of the demo's frame size (640x360, 20-frame clips, ``--test`` test clips, key frames 8, 11, .., 20: 5 a
clip), with the demo's clip options (4 frames, ORB alignment ``fly``, 80x256, the sky cut) and loader (batch 4, one
worker); the alignment cache is filled first, so both sides read their homographies from it. In turn:

1. ``--repeats`` times, the data of a prediction pass alone (a new `ClipDataModule`'s predict loader iterated to
   the end, as a pass reads it): with ``memory_mb: 0`` (every pass decodes, aligns and resizes its frames, as before
   the store) and from the store the first stored pass filled; every batch compared bit for bit.
2. ``--passes`` times, a whole ``stamlane predict`` pass with the shipped 4-frame weights in this process (as
   ``stamlane demo`` runs its passes), without and with the store; the lanes compared.

Prints and keeps the medians, the first stored pass (which fills the store by ``min(4, cores)`` threads before its
loader starts) and the machine's load. Timings on a shared machine are noisy: read the ratios of passes in turn.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before torch: spinning OpenMP threads starve a shared CPU

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

from _harness import guard_out, in_turn, load_1min, machine, medians, ratio, write_result


def predict(root: Path, out: Path, memory_mb: int) -> tuple[float, list[dict]]:
    """One ``stamlane predict`` pass in this process: seconds and the lanes (without the timings)."""
    from stamlane.cli import main

    argv, sys.argv = sys.argv, ["stamlane"]
    start = time.perf_counter()
    try:
        code = main(
            [
                "predict",
                "--ckpt_path=stam4-synthetic",
                f"--data.root={root}",
                "--data.predict_labels=[test.json]",
                f"--data.loader.memory_mb={memory_mb}",
                f"--predictions.output_dir={out}",
                "--predictions.max_overlays=0",
                "--predictions.verbose=false",
                "--trainer.logger=false",
                "--trainer.enable_progress_bar=false",
            ]
        )
    finally:
        sys.argv = argv
    if code:
        raise SystemExit(f"stamlane predict failed with status {code}")
    seconds = time.perf_counter() - start
    lines = (out / "predictions.json").read_text().splitlines()
    return seconds, [{k: v for k, v in json.loads(line).items() if k != "run_time"} for line in lines]


def data_pass(root: Path, memory_mb: int) -> tuple[float, list]:
    """The data of one prediction pass: seconds to iterate a new datamodule's predict loader, and its batches."""
    from stamlane.data.datamodule import ClipDataModule
    from stamlane.data.options import ClipOptions, LoaderOptions

    start = time.perf_counter()
    clip = ClipOptions(num_frames=4, image_size=(80, 256), crop_top=0.4, align="fly")  # configs/demo.yaml
    data = ClipDataModule(str(root), clip=clip, loader=LoaderOptions(4, 1, memory_mb), predict_labels=["test.json"])
    data.setup("predict")
    batches = [(b["frames"], b["key_from_hist"]) for b in data.predict_dataloader()]
    return time.perf_counter() - start, batches


def _same(a: list, b: list) -> bool:
    import torch

    return len(a) == len(b) and all(torch.equal(x, y) for pa, pb in zip(a, b) for x, y in zip(pa, pb))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--test", type=int, default=12, help="test clips (5 key frames each)")
    parser.add_argument("--repeats", type=int, default=5, help="data passes of each kind")
    parser.add_argument("--passes", type=int, default=3, help="whole prediction passes of each kind")
    parser.add_argument("--out", type=Path, default=Path("outputs/benchmarks/frame_store.json"))
    args = parser.parse_args(argv)

    if (refused := guard_out("frame_store.py", args.out)) is not None:  # before any work
        return refused
    import torch

    from stamlane.data.frame_store import FRAME_STORE
    from stamlane.synth import generate_dataset
    from stamlane.synth.layout import SplitCounts

    torch.set_num_threads(max(1, os.cpu_count() or 1))  # as the demo
    warnings.filterwarnings("ignore")
    result: dict = machine() | {"load_1min_at_start": load_1min()}
    memory = {"afresh": 0, "stored": 1024}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "set"
        generate_dataset(root, SplitCounts(test=args.test), seed=0, progress=False)
        _, lanes = predict(root, Path(tmp) / "warm-up", 0)  # imports, first calls and the alignment cache out
        FRAME_STORE.clear()
        first, reference = data_pass(root, memory["stored"])  # fills the store
        same = same_lanes = True

        def data(mode: str, _: int) -> float:
            nonlocal same
            seconds, batches = data_pass(root, memory[mode])
            same = same and _same(batches, reference)
            return round(seconds, 3)

        def whole(mode: str, r: int) -> float:
            nonlocal same_lanes
            seconds, got = predict(root, Path(tmp) / f"{mode}-{r}", memory[mode])
            same_lanes = same_lanes and got == lanes
            return round(seconds, 3)

        times = {"data": in_turn(data, list(memory), args.repeats), "pass": in_turn(whole, list(memory), args.passes)}
    result |= {"images": len(lanes), "stored_mb": round(FRAME_STORE.used / 2**20, 1)}
    for name, count in (("data", args.repeats), ("pass", args.passes)):
        med = medians(times[name])
        result[name] = {"times_s": times[name], "median_s": med, "ratio": ratio(times[name], "afresh", "stored")}
        what = "the data of a prediction pass" if name == "data" else "a whole prediction pass"
        print(
            f"{what} ({len(lanes)} images): afresh {med['afresh']:.2f} s, from the store {med['stored']:.2f} s "
            f"(x{result[name]['ratio']:.2f}; medians of {count} in turn)"
        )
    result |= {"first_stored_data_s": round(first, 3), "same_batches": same, "same_lanes": same_lanes}
    result["load_1min_at_end"] = load_1min()
    print(
        f"the first stored data pass (filling the store) {first:.2f} s; the same batches: {same}, the same lanes: "
        f"{same_lanes}; load {result['load_1min_at_start']} -> {result['load_1min_at_end']}"
    )
    write_result(args.out, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
