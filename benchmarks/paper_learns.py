"""Does the paper's configuration learn? ``configs/tusimple_stam4.yaml`` (VGG16-BN width 1.0, 4 pre-aligned frames,
mixed C-S STAM, SGD lr 0.05 momentum 0.9, poly schedule), trained from scratch on a synthetic set in TuSimple's own
layout, read by the config's own label files; the train loss, validation loss and validation TuSimple F1 of each
variant, step by step.

Usage::

    python benchmarks/paper_learns.py                   # the three runs of RUNS (what docs/results/paper-learns holds)
    python benchmarks/paper_learns.py --runs stable-128x256 &  python benchmarks/paper_learns.py --runs \
        paper-256x512 stable-256x512                    # the same, in two processes (one set of files at the end)
    python benchmarks/paper_learns.py --quick           # 4 steps of each variant on a tiny set (a smoke test)

Each run is one ``stamlane fit`` of the paper config with the layer of its variant (``VARIANTS``) and the same
command-line overrides (its number of steps and input size, the batch, where the data and logs go,
``model.report_run_time false`` so that validation F1 does not depend on the CPU's speed, one DataLoader process),
run one after the other with ``--threads`` torch threads; one seed. The set is generated first when ``--root`` holds none
(``stamlane synth --layout tusimple``) and aligned (``stamlane align``, the config's ``align: cache``).

Writes into ``--out`` (default ``outputs/bench/paper-learns``): ``<run>.json`` as each run ends, then ``curve.csv``
(run, step, train loss, validation loss, validation F1, learning rate), ``paper-learns.json`` (the commands,
settings, CPU, seconds and the first / last numbers of each run) and ``curve.png`` (the three curves) of every run
in the folder (``--combine-only``: those alone, from the runs' files).

A bad input is one line on stderr and exit status 2 before any run (`_harness`): an ``--out`` that is a file or lies
inside ``--root``, a ``--size`` that is no ``WxH``, a ``--root`` whose ``dataset.json`` is not a set's (no
``config``), a run file in ``--out`` that is not this script's (combined: nothing is written), no run file to
combine; a ``stamlane synth`` / ``align`` / ``fit`` that refuses its input ends the script with its own line.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import subprocess
import sys
import time
from pathlib import Path

from _harness import BenchInputError, check_out_folder, fail, machine, read_json_object, write_figure, write_result

REPO = Path(__file__).resolve().parents[1]
STAMLANE = [sys.executable, "-c", "import sys; from stamlane.cli import main; sys.exit(main())"]
"""``stamlane`` of this interpreter (the console script need not be on ``PATH``)."""
PAPER_CONFIG = REPO / "configs" / "tusimple_stam4.yaml"
VARIANTS = {
    "paper": [],
    "stable": [str(REPO / "configs" / "common" / "stable_sgd.yaml")],
}
"""The overlays (``--config`` files after the paper's) of each variant: the paper's optimiser as it is, and the
shipped configuration that does not diverge without ImageNet weights."""


class StepFailed(RuntimeError):
    """A ``stamlane`` subcommand that failed: ``code`` its exit status, ``line`` its last line on stderr."""

    def __init__(self, what: str, code: int, stderr: str) -> None:
        lines = stderr.strip().splitlines()
        self.code, self.line = code, lines[-1] if lines else ""
        self.tail = stderr[-2000:]
        super().__init__(f"{what} failed ({code}): {self.line}")


def _stamlane(what: str, command: list[str], env: dict[str, str] | None = None) -> None:
    result = subprocess.run(command, env=env, capture_output=True, text=True)
    if result.returncode != 0:
        raise StepFailed(what, result.returncode, result.stderr)


def check_set(root: Path) -> bool:
    """Whether ``root`` holds a set (its ``dataset.json``, checked), False where there is none yet.

    Raises:
        BenchInputError: ``root`` is a file, or its ``dataset.json`` is not a set's (not JSON, no ``config``).
    """
    if os.path.lexists(root) and not root.is_dir():
        raise BenchInputError(f"--root {root} is a file, not a folder")
    info = root / "dataset.json"
    if not os.path.lexists(info):
        return False
    config = read_json_object(info, "--root's dataset.json", keys=("config",))["config"]
    if not isinstance(config, dict):
        raise BenchInputError(f"--root's dataset.json {info}: config is not an object (not a synthetic set?)")
    return True


def make_set(root: Path, clips: int, size: str, frames: int) -> None:
    """A synthetic set in TuSimple's layout (train / val / test 80 / 10 / 10 % of ``clips``) and its alignment cache
    for the config's 4 frames, unless ``root`` already holds one (its ``dataset.json`` checked first).

    Raises:
        BenchInputError: a ``dataset.json`` that is not a set's.
        StepFailed: ``stamlane synth`` or ``align`` failed.
    """
    if not check_set(root):
        command = [
            *STAMLANE,
            *("synth", "--out", str(root), "--layout", "tusimple", "--clips", str(clips), "--size", size),
            *("--frames", str(frames), "--challenging-clips", "0", "--reveal-clips", "0"),
            *("--reveal-traffic-clips", "0", "--quiet"),
        ]
        _stamlane("stamlane synth", command)
    if not (root / "alignment").is_dir():
        _stamlane(
            "stamlane align",
            [*STAMLANE, "align", str(root), "--cache", str(root / "alignment"), "--num-frames", "4", "--quiet"],
        )


def fit_command(
    variant: str, args: argparse.Namespace, logs: Path, steps: int, val_every: int, size: tuple[int, int], name: str
) -> list[str]:
    """The ``stamlane fit`` command of ``variant``: ``steps`` steps at input ``size``, validated every
    ``val_every``, logged under ``logs/name``."""
    configs = [str(PAPER_CONFIG), *VARIANTS[variant]]
    return [
        *STAMLANE,
        "fit",
        *(f"--config={c}" for c in configs),
        f"--data.root={args.root}",
        f"--data.clip.cache_dir={args.root / 'alignment'}",
        f"--data.clip.image_size=[{size[0]}, {size[1]}]",
        f"--data.loader.batch_size={args.batch}",
        "--data.loader.num_workers=0",
        f"--trainer.max_steps={steps}",
        f"--trainer.val_check_interval={val_every}",
        "--trainer.log_every_n_steps=1",
        "--trainer.num_sanity_val_steps=0",
        f"--trainer.logger.init_args.save_dir={logs}",
        f"--trainer.logger.init_args.name={name}",
        f"--trainer.default_root_dir={logs}",
        "--model.report_run_time=false",
        f"--seed_everything={args.seed}",
    ]


def read_metrics(csv_path: Path) -> list[dict]:
    """Rows of Lightning's CSV log (``metrics.csv``), one per step with what was logged at it (floats; NaN where a
    value was logged as non-finite, absent where nothing was)."""
    by_step: dict[int, dict] = {}
    with csv_path.open() as f:
        for row in csv.DictReader(f):
            step = int(row["step"])
            merged = by_step.setdefault(step, {"step": step})
            for key, value in row.items():
                if key not in ("step", "epoch") and value not in ("", None):
                    merged[key] = float(value)
    return [by_step[s] for s in sorted(by_step)]


def curve_rows(name: str, metrics: list[dict]) -> list[dict]:
    """``curve.csv``'s rows of a run: training step (1-based, after the step), train loss, validation loss and
    F1 (validation runs after the step it is logged at), learning rate."""
    lr_key = next((k for m in metrics for k in m if k.startswith("lr-")), None)
    rows = []
    for m in metrics:
        rows.append(
            {
                "run": name,
                "step": m["step"] + 1 if "train/loss" in m else m["step"],
                "train_loss": m.get("train/loss"),
                "val_loss": m.get("val/loss"),
                "val_f1": m.get("val/tusimple_f1"),
                "lr": m.get(lr_key) if lr_key else None,
            }
        )
    return rows


def summarise(rows: list[dict]) -> dict:
    """First and last train loss (means of the first and last fifth of the steps), validation numbers, and whether
    the run diverged (a non-finite loss, or a train or validation loss 100x its first)."""
    train = [r["train_loss"] for r in rows if r["train_loss"] is not None]
    val = [(r["step"], r["val_loss"], r["val_f1"]) for r in rows if r["val_loss"] is not None]
    fifth = max(1, len(train) // 5)
    finite = [x for x in train if math.isfinite(x)]
    first = sum(train[:fifth]) / fifth if train else None
    out = {
        "steps": len(train),
        "train_loss_first_fifth": first,
        "train_loss_last_fifth": sum(train[-fifth:]) / fifth if train else None,
        "train_loss_max": max(finite) if finite else None,
        "val": [{"step": s, "loss": loss, "tusimple_f1": f1} for s, loss, f1 in val],
    }
    non_finite = len(finite) < len(train) or any(not math.isfinite(v[1]) for v in val)
    blown = bool(first) and (max(finite, default=0) > 100 * first or any(v[1] > 100 * first for v in val))
    out["diverged"] = non_finite or blown
    return out


def plot(rows: list[dict], path: Path, title: str) -> None:
    """``curve.png``: train loss (log scale), validation loss (log scale) and validation F1 against the step."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for name in dict.fromkeys(r["run"] for r in rows):
        mine = [r for r in rows if r["run"] == name]
        train = [(r["step"], r["train_loss"]) for r in mine if r["train_loss"] is not None]
        val = [(r["step"], r["val_loss"], r["val_f1"]) for r in mine if r["val_loss"] is not None]
        if train:
            axes[0].plot(*zip(*train), label=name, lw=1)
        if val:
            steps, losses, f1 = zip(*val)
            axes[1].plot(steps, losses, "o-", label=name)
            axes[2].plot(steps, f1, "o-", label=name)
    for ax, name, log in zip(axes, ("train loss", "validation loss", "validation TuSimple F1"), (True, True, False)):
        ax.set_xlabel("step")
        ax.set_title(name)
        if log:
            ax.set_yscale("log")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    write_figure(fig, path, dpi=90)


RUNS = {
    "paper-256x512": ("paper", (256, 512), 12, 6),
    "stable-256x512": ("stable", (256, 512), 12, 6),
    "stable-128x256": ("stable", (128, 256), 200, 25),
}
"""The runs of the benchmark: name -> (variant, network input (H, W), steps, steps between validations). The two
variants side by side at the paper's input for as many steps as the paper's diverges in, and the stable one at a
quarter of the pixels for as many steps as a shared 2-core CPU affords, to see its validation F1 rise."""
QUICK_RUNS = {"paper-quick": ("paper", (64, 128), 4, 2), "stable-quick": ("stable", (64, 128), 4, 2)}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", type=Path, default=Path("outputs/bench/paper-learns-data"), help="the set")
    parser.add_argument("--clips", type=int, default=60, help="clips of a generated set (80/10/10 %%)")
    parser.add_argument("--size", default="640x360", help="frame size of a generated set")
    parser.add_argument("--frames", type=int, default=20, help="frames per clip of a generated set")
    parser.add_argument("--runs", nargs="+", default=list(RUNS), choices=[*RUNS, *QUICK_RUNS], help="which of RUNS")
    parser.add_argument("--batch", type=int, default=1, help="batch size (the paper: 4)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="torch threads (OMP_NUM_THREADS)")
    parser.add_argument("--quick", action="store_true", help="a tiny set, 64x128, 4 steps a variant (a smoke test)")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/paper-learns"))
    parser.add_argument("--combine-only", action="store_true", help="only combine the runs' files in --out")
    return parser


def run(name: str, args: argparse.Namespace, env: dict[str, str]) -> dict:
    """Train run ``name`` (`RUNS`); its summary, also written to ``<out>/<name>.json`` with its curve rows.

    Raises:
        StepFailed: ``stamlane fit`` failed or logged nothing.
    """
    variant, size, steps, every = {**RUNS, **QUICK_RUNS}[name]
    logs = (args.out / "runs").resolve()
    command = fit_command(variant, args, logs, steps, every, size, name)
    start = time.perf_counter()
    _stamlane(f"{name}: stamlane fit", command, env)
    seconds = time.perf_counter() - start
    versions = sorted((logs / name).glob("version_*/metrics.csv"), key=lambda p: p.stat().st_mtime)
    if not versions:
        raise StepFailed(f"{name}: stamlane fit", 1, f"no metrics.csv under {logs / name}")
    rows = curve_rows(name, read_metrics(versions[-1]))
    summary = {
        "variant": variant,
        "overlays": [str(Path(c).relative_to(REPO)) for c in VARIANTS[variant]],
        "image_size": list(size),
        "batch": args.batch,
        "steps": steps,
        "val_every": every,
        "seed": args.seed,
        "threads": args.threads,
        "command": " ".join(["stamlane", *command[len(STAMLANE) :]]),
        "seconds": seconds,
        **summarise(rows),
    }
    write_result(args.out / f"{name}.json", finite({"summary": summary, "rows": rows}), allow_nan=False, quiet=True)
    val = ", ".join(f"step {v['step']}: loss {v['loss']:.3g} F1 {v['tusimple_f1']:.3f}" for v in summary["val"])
    print(
        f"{name}: {summary['steps']} steps in {seconds:.0f} s; train loss {summary['train_loss_first_fifth']:.3g} -> "
        f"{summary['train_loss_last_fifth']:.3g} (first / last fifth){' DIVERGED' if summary['diverged'] else ''}; "
        f"{val}",
        flush=True,
    )
    return summary


def finite(value: object) -> object:
    """``value`` with every non-finite float (a diverged run's loss) as None: JSON has no Infinity or NaN, and
    ``summary["diverged"]`` says what happened."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [finite(v) for v in value]
    return value


CURVE_FIELDS = ["run", "step", "train_loss", "val_loss", "val_f1", "lr"]


def read_runs(out: Path, allow_none: bool = False) -> tuple[list[dict], dict[str, dict]]:
    """The curve rows and summaries of every run file (``<name>.json``) in ``out``, each checked whole first.

    Raises:
        BenchInputError: a run file that is not this script's (not JSON, no ``rows`` list of curve rows or no
            ``summary`` object), or no run file at all.
    """
    rows, runs = [], {}
    for name in [*RUNS, *QUICK_RUNS]:
        path = out / f"{name}.json"
        if not os.path.lexists(path):
            continue
        record = read_json_object(path, "run file", keys=("rows", "summary"))
        mine, summary = record["rows"], record["summary"]
        good = isinstance(mine, list) and all(isinstance(r, dict) and set(r) == set(CURVE_FIELDS) for r in mine)
        if not good or not isinstance(summary, dict) or any(r["run"] != name for r in mine):
            raise BenchInputError(f"run file {path}: its rows or summary are not this script's (run {name})")
        rows += mine
        runs[name] = summary
    if not runs and not allow_none:
        raise BenchInputError(f"--out {out}: no run file to combine ({', '.join(f'{n}.json' for n in RUNS)})")
    return rows, runs


def combine(out: Path, info: dict) -> None:
    """``curve.csv``, ``paper-learns.json`` and ``curve.png`` of every run whose ``<name>.json`` is in ``out`` (runs
    made by several invocations, one after the other or side by side, end in one set of files)."""
    import io

    from stamlane.safety.guard import write_atomic

    rows, runs = read_runs(out)
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=CURVE_FIELDS)
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / "curve.csv", text.getvalue())
    write_result(out / "paper-learns.json", finite({**info, "runs": runs}), indent=2, allow_nan=False, quiet=True)
    title = (
        f"configs/tusimple_stam4.yaml from scratch (width 1.0, 4 frames, SGD lr 0.05), batch {info['batch']}, "
        f"synthetic TuSimple-layout set ({info['set']['size']}), seed {info['seed']} (one seed), {info['cpu']}"
    )
    plot(rows, out / "curve.png", title)


def main(argv: list[str] | None = None) -> int:
    from stamlane_eval.cli_tools import parse_wxh
    from stamlane_eval.io import MAX_IMAGE_SIDE

    from stamlane.safety.guard import GuardError

    args = _parser().parse_args(argv)
    if args.quick:
        quick = [name for name in args.runs if name in QUICK_RUNS]  # the quick runs asked for, else both
        args.clips, args.size, args.frames, args.runs = 3, "128x72", 5, quick or list(QUICK_RUNS)
    if min(args.batch, args.threads, args.clips, args.frames) < 1:
        return fail("paper_learns.py", "--batch, --threads, --clips and --frames must be >= 1")
    try:
        parse_wxh(args.size, MAX_IMAGE_SIDE)
    except argparse.ArgumentTypeError as err:
        return fail("paper_learns.py", f"--size: {err}")
    env = dict(os.environ, OMP_NUM_THREADS=str(args.threads), OMP_WAIT_POLICY="PASSIVE")
    args.root = args.root.resolve()
    try:
        check_out_folder(args.out, protected=[] if args.combine_only else [args.root])
        read_runs(args.out, allow_none=not args.combine_only)  # every run file checked before anything is written
        if not args.combine_only:
            check_set(args.root)
    except (GuardError, BenchInputError) as err:
        return fail("paper_learns.py", err)
    args.out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    info = {
        **machine(),
        "seed": args.seed,
        "batch": args.batch,
        "set": {"clips": args.clips, "size": args.size, "frames": args.frames, "layout": "tusimple"},
    }
    if args.combine_only:
        combine(args.out, info)
        print(f"wrote {args.out}/curve.csv, paper-learns.json, curve.png")
        return 0
    try:
        make_set(args.root, args.clips, args.size, args.frames)
        for name in args.runs:
            run(name, args, env)
        combine(args.out, info)
    except BenchInputError as err:
        return fail("paper_learns.py", err)
    except StepFailed as err:  # a refusal (2) is its one line; a crash shows what it printed
        if err.code != 2:
            print(f"paper_learns.py: {err}\n{err.tail}", file=sys.stderr)
            return 1
        return fail("paper_learns.py", err)
    print(f"wrote {args.out}/curve.csv, paper-learns.json, curve.png ({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
