"""One run scored over several splits and probes: the model built once (`stamlane.training.runs.open_run`) against a
LightningCLI per prediction pass (stamlane before it), side by side.

    python benchmarks/run_passes.py --out outputs/bench/run_passes [--repeats 3] [--clips 8]

The run is the shipped 4-frame model (``stam4-synthetic``, copied into a run folder of a run store), the data a
synthetic set of the demo's format (``--clips`` test and val clips). `Runner.score` predicts and scores ``test`` with
its real history and four probes (``key``, ``other_clip``, ``warped_key``, ``exact``) and ``val`` with two: 7 passes.
Each repeat scores into a fresh store, after one untimed run that fills the data root's alignment cache. Give ``--src`` the ``src`` folder of another checkout (stamlane before runs were
opened once) to time that code in a subprocess, alternating with this one (in turn first and second); prints the median seconds of each and
their ratio, and writes ``<out>/run_passes.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from _harness import guard_out, in_turn, machine, medians, ratio, write_result

SPLITS = {"test": ("key", "other_clip", "warped_key", "exact"), "val": ("key",)}


def _run_folder(store: Path) -> Path:
    """The shipped 4-frame model as a finished run's folder (``config.yaml``, ``checkpoints/last.ckpt``)."""
    import torch

    from stamlane.weights import shipped_path

    run = store / "stam4-s0" / "run"
    (run / "checkpoints").mkdir(parents=True)
    shutil.copy(shipped_path("stam4-synthetic"), run / "checkpoints" / "last.ckpt")
    config = torch.load(run / "checkpoints" / "last.ckpt", weights_only=True)["stamlane_config"]
    (run / "config.yaml").write_text(config)
    return run


def score_once(root: Path, out: Path) -> float:
    """Seconds of one `Runner.score` of the run over `SPLITS` into the fresh store ``out``."""
    import torch

    from stamlane.experiments.runner import Runner, frames_of
    from stamlane.experiments.store import RunStore

    torch.set_num_threads(2)
    run = _run_folder(out)
    try:  # this checkout: a typed record
        from stamlane.training.runs import RunRecord

        record: object = RunRecord(run, run / "checkpoints" / "last.ckpt", frames_of(run), 0, 0.0)
    except ImportError:  # stamlane before runs were opened once: a dict
        record = {"run": str(run), "frames": frames_of(run)}
    runner = Runner(RunStore(out), root, max_overlays=0, say=lambda line: None)
    start = time.perf_counter()
    runner.score("stam4-s0", record, SPLITS)  # type: ignore[arg-type]
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/run_passes"))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--clips", type=int, default=8)
    parser.add_argument("--src", type=Path, default=None, help="another checkout's src folder, timed alternately")
    parser.add_argument("--one", nargs=2, type=Path, metavar=("ROOT", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)

    if (refused := guard_out("run_passes.py", args.out, folder=True)) is not None:  # before any work
        return refused
    if args.one:  # one timing, in this process (the subprocess of --src)
        print(json.dumps(score_once(*args.one)))
        return 0
    from stamlane.synth import generate_dataset
    from stamlane.synth.layout import SplitCounts

    root = args.out / "data"
    if not (root / "dataset.json").is_file():
        generate_dataset(root, SplitCounts(val=args.clips, test=args.clips), seed=0, workers=2)
    info = machine()
    codes = {"this": None, **({"other": args.src.resolve()} if args.src else {})}
    warm = args.out / "warm-up"  # the alignment cache of the data root filled first: every timed run reads it
    shutil.rmtree(warm, ignore_errors=True)
    subprocess.run([sys.executable, __file__, "--one", str(root), str(warm)], capture_output=True, check=True)

    def measure(name: str, i: int) -> float:
        out = args.out / f"{name}-{i}"
        shutil.rmtree(out, ignore_errors=True)
        src = codes[name]
        env = dict(os.environ, **({"PYTHONPATH": str(src)} if src else {}))
        command = [sys.executable, __file__, "--one", str(root), str(out)]
        done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
        seconds = float(json.loads(done.stdout.strip().splitlines()[-1]))
        print(f"{name} {i}: {seconds:.1f} s", flush=True)
        return seconds

    times = in_turn(measure, list(codes), args.repeats, alternate=True)
    result = {
        **info,
        "passes": sum(1 + len(p) for p in SPLITS.values()),
        "clips": args.clips,
        "seconds": times,
        "median": medians(times),
    }
    if "other" in times:
        result["ratio_other_over_this"] = ratio(times, "other", "this", digits=None)
    write_result(args.out / "run_passes.json", result, indent=2, quiet=True)
    print(json.dumps({k: v for k, v in result.items() if k != "seconds"}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
