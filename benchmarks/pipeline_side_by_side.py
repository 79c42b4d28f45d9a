"""The parts of README command 1 that the data path changes, timed side by side at the demo's sizes, with the
alignment cache (`stamlane.data.alignment`) and without it (every dataset estimating its clips afresh, as before
the cache), and the set rendered by one and by two processes; the weights and lanes compared bit for bit.

    python benchmarks/pipeline_side_by_side.py [--test 12] [--train 6] [--repeats 3] [--steps 20]
                                               [--out outputs/benchmarks/pipeline_side_by_side.json]

1. The set (640x360, 20-frame clips: ``--train`` train clips, ``--test`` test clips, 2 val clips) rendered with
   ``workers=1`` and ``workers=2``: seconds each, and every file compared byte for byte.
2. A prediction pass of the test split (``stamlane predict`` with the shipped 4-frame weights, key frames 8, 11,
   .., 20: 5 a clip), in turn ``afresh`` (the cache switched off) and ``cached`` (read from the cache the first
   pass filled), ``--repeats`` each: medians, and the lanes of both compared.
3. A training run of the demo's 4-frame model (``configs/demo.yaml`` with the CPU recipe's key-frame corruption,
   ``--steps`` steps, DataLoader worker as configured), once into the empty cache, then afresh and cached in turn
   (``--repeats`` - 1 each): medians, and the final weights compared bit for bit.

Timings on a shared machine are noisy: read the ratios of runs made in turn, not the seconds alone.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before torch: spinning OpenMP threads starve a shared CPU

import argparse
import contextlib
import json
import shutil
import sys
import tempfile
import time
import warnings
from collections.abc import Iterator
from pathlib import Path

from _harness import (
    BenchInputError,
    fail,
    guard_out,
    in_turn,
    load_1min,
    machine,
    medians,
    read_json_object,
    write_result,
)

REPO = Path(__file__).resolve().parents[1]
MODES = ("afresh", "cached")  # the alignment cache switched off, and read from the cache the first pass filled


@contextlib.contextmanager
def cache_off() -> Iterator[None]:
    """Every `PairCache` answers nothing and keeps nothing: each dataset estimates its clips (the behaviour before
    the cache). DataLoader workers are forked, so they inherit it."""
    from stamlane.align.cache import PairCache

    get, put = PairCache.get, PairCache.put
    PairCache.get, PairCache.put = (lambda self, key: None), (lambda self, key, alignment: None)
    try:
        yield
    finally:
        PairCache.get, PairCache.put = get, put


def render(root: Path, train: int, test: int, workers: int) -> float:
    from stamlane.synth import generate_dataset
    from stamlane.synth.layout import SplitCounts

    start = time.perf_counter()
    counts = {"train": train, "val": 2, "test": test, "challenging": 0}
    generate_dataset(root, SplitCounts(**counts), seed=0, progress=False, workers=workers)
    return time.perf_counter() - start


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _stamlane(*args: str) -> float:
    from stamlane.cli import main

    argv, sys.argv = sys.argv, ["stamlane"]
    start = time.perf_counter()
    try:
        code = main(list(args))
    finally:
        sys.argv = argv
    if code:
        raise SystemExit(f"stamlane {args[0]} failed with status {code}")
    return time.perf_counter() - start


def predict(root: Path, out: Path) -> tuple[float, list[dict]]:
    seconds = _stamlane(
        "predict",
        "--ckpt_path=stam4-synthetic",
        f"--data.root={root}",
        "--data.predict_labels=[test.json]",
        f"--predictions.output_dir={out}",
        "--predictions.max_overlays=0",
        "--predictions.verbose=false",
        "--trainer.logger=false",
        "--trainer.enable_progress_bar=false",
    )
    lines = (out / "predictions.json").read_text().splitlines()
    return seconds, [{k: v for k, v in json.loads(line).items() if k != "run_time"} for line in lines]


def fit(root: Path, out: Path, steps: int) -> tuple[float, dict]:
    import torch

    from stamlane.experiments.recipes import KEY_CORRUPTION
    from stamlane.training.runs import flags_of

    seconds = _stamlane(
        "fit",
        "--config",
        str(REPO / "configs" / "demo.yaml"),
        f"--data.root={root}",
        *flags_of(KEY_CORRUPTION),
        "--seed_everything=0",
        f"--trainer.max_steps={steps}",
        f"--trainer.val_check_interval={steps}",
        "--trainer.limit_val_batches=2",
        "--trainer.enable_progress_bar=false",
        "--trainer.enable_model_summary=false",
        f"--trainer.default_root_dir={out}",
        f"--trainer.logger.init_args.save_dir={out}",
    )
    (ckpt,) = out.rglob("last.ckpt")
    return seconds, torch.load(ckpt, weights_only=True)["state_dict"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--train", type=int, default=6)
    parser.add_argument("--test", type=int, default=12)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument(
        "--skip", nargs="*", default=[], choices=("render", "predict", "fit"), help="parts not run (kept in --out)"
    )
    parser.add_argument("--out", type=Path, default=Path("outputs/benchmarks/pipeline_side_by_side.json"))
    args = parser.parse_args(argv)

    if (refused := guard_out("pipeline_side_by_side.py", args.out)) is not None:  # before any work
        return refused
    try:  # the parts skipped keep their earlier results: read (and checked) before any part runs
        earlier = read_json_object(args.out, "--out") if args.skip and args.out.exists() else {}
    except BenchInputError as err:
        return fail("pipeline_side_by_side.py", err)
    import torch

    torch.set_num_threads(max(1, os.cpu_count() or 1))  # as the demo
    warnings.filterwarnings("ignore")
    result: dict = machine() | {"load_1min_at_start": load_1min()}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        root = tmp / "one"
        if "render" not in args.skip:
            one = render(root, args.train, args.test, 1)
            two = render(tmp / "two", args.train, args.test, 2)
            same = _files(root) == _files(tmp / "two")
            result["render"] = {"clips": args.train + args.test + 2, "workers_1_s": round(one, 2)}
            result["render"] |= {"workers_2_s": round(two, 2), "same_bytes": same}
            print(f"set: 1 worker {one:.1f} s, 2 workers {two:.1f} s (x{one / two:.2f}); the same bytes: {same}")
            shutil.rmtree(tmp / "two")
        else:
            render(root, args.train, args.test, 2)
        if "predict" not in args.skip:
            with cache_off():  # imports and first-call costs out of the timings
                predict(root, tmp / "pred-warm-up")
            cold, first = predict(root, tmp / "pred-cold")  # fills the cache
            lanes = {}

            def pass_(mode: str, r: int) -> float:
                with cache_off() if mode == "afresh" else contextlib.nullcontext():
                    seconds, lanes[mode] = predict(root, tmp / f"pred-{mode}-{r}")
                return seconds

            times = in_turn(pass_, MODES, args.repeats)
            same = lanes["afresh"] == lanes["cached"] == first
            med = medians(times)
            result["predict"] = {"images": len(first), "repeats": args.repeats, "cold_s": round(cold, 2)}
            result["predict"] |= {"times_s": times, "same_lanes": same}
            print(
                f"prediction pass of {len(first)} images: afresh {med['afresh']:.1f} s, cached {med['cached']:.1f} s "
                f"(x{med['afresh'] / med['cached']:.2f}), first pass into the empty cache {cold:.1f} s; "
                f"the same lanes: {same}"
            )
        if "fit" not in args.skip:
            cold, _ = fit(root, tmp / "fit-cold", args.steps)  # fills the cache with the train split's pairs
            weights = {}

            def run(mode: str, r: int) -> float:
                with cache_off() if mode == "afresh" else contextlib.nullcontext():
                    seconds, weights[mode] = fit(root, tmp / f"fit-{mode}-{r}", args.steps)
                return seconds

            times = in_turn(run, MODES, max(1, args.repeats - 1))
            same = all(torch.equal(weights["afresh"][k], weights["cached"][k]) for k in weights["afresh"])
            med = medians(times)
            result["fit"] = {"steps": args.steps, "train_clips": args.train, "cold_s": round(cold, 2)}
            result["fit"] |= {"times_s": times, "same_weights": same}
            print(
                f"training run of {args.steps} steps: afresh {med['afresh']:.1f} s, cached {med['cached']:.1f} s "
                f"(x{med['afresh'] / med['cached']:.2f}), first run into the empty cache {cold:.1f} s; the same final "
                f"weights, bit for bit: {same}"
            )
    write_result(args.out, earlier | result)  # the parts skipped keep their earlier results
    return 0


if __name__ == "__main__":
    sys.exit(main())
