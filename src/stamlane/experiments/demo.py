"""``stamlane demo``: README command 1 — the experiment engine on three models of synthetic clips, and pictures.

    stamlane demo [--out outputs/demo] [--data DIR] [--seeds 1] [--pretrain-steps 1200] [--finetune-steps 300]
                  [--bf16 auto|true|false] [--no-noalign] [--single-clean] [--rows ID ...] [--all-probes]
                  [--max-overlays 12] [--quick]

Generates the default synthetic set when missing, then runs `stamlane.experiments.engine` with the CPU recipe
(the single-frame network from scratch, then each model from its weights: every model gets the same steps on the
same data) on the 4-frame pre-aligned STAM model, the single frame and the 4-frame model without alignment (and
``--rows`` of the paper's tables), scores their final weights on the clean ``test``, the ``challenging`` and the
two reveal splits in TuSimple F1 and IoU F1 with intervals over clips and seeds, probes each multi-frame model's
history (the key frame copied into every history slot everywhere; on the reveal splits also the matched null,
the history reversed, another clip's history and exact alignment; ``--all-probes``: another clip's history on
every split), and writes ``summary.json``, ``tables.md``, ``val_f1.png``, ``history_use.png``,
``history_use_vs_headroom.png`` and ``comparison.jpg`` (the same challenging key frames, one column per model) to
``--out``, and prints the tables. ``--quick`` is a seconds-long smoke run on a tiny set (its numbers mean
nothing; the tests run it).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from stamlane_eval.cli_tools import OneLineParser, parse_or_status

from stamlane.experiments.engine import Experiment
from stamlane.experiments.recipes import RECIPES, Recipe, Row
from stamlane.experiments.store import ExperimentError
from stamlane.experiments.workspace import add_bf16_argument, bf16_of, check_data, claimed_out, prepare_data
from stamlane.safety.boundary import run_command

__all__ = ["MODELS", "OUTPUTS", "PAIRS", "SINGLE_CLEAN", "build_parser", "main", "pairs"]

MODELS = (
    Row("stam4", "4 frames, pre-aligned, STAM", ("demo.yaml",), paper="f4_mixed_cs_features"),
    Row("single", "1 frame (baseline)", ("demo_single.yaml",), paper="f1_keyonly"),
    Row("stam4_noalign", "4 frames, no alignment, STAM", ("demo_noalign.yaml",), paper="f4_noalign_mixed_cs_features"),
)
SINGLE_CLEAN = Row("single_clean", "1 frame, no key-frame corruption", ("demo_single.yaml",), recipe_args=False)
"""``--single-clean``: the single frame trained without the recipe's key-frame corruption, which it cannot undo."""
PAIRS = (("stam4", "single"), ("stam4_noalign", "single"), ("stam4", "stam4_noalign"))
PAIRS += (("stam4", "single_clean"), ("single", "single_clean"))
"""The demo's comparisons, A against B: what the history frames bring, with and without alignment; what the
key-frame corruption costs a single frame and whether STAM is ahead of one trained without it."""
OUTPUTS = ("summary.json", "tables.md", "val_f1.png", "history_use.png", "comparison.jpg")
"""The files the demo writes at the top of ``--out`` (the runs and predictions go in folders beside them)."""


def pairs(rows: list[Row]) -> list[tuple[str, str]]:
    """`PAIRS` among ``rows``, each paper row asked for against the single frame and pre-aligned STAM, and the rows
    of a table with a baseline against it (`stamlane.experiments.table_index.baseline_pairs`)."""
    from stamlane.experiments.table_index import baseline_pairs

    names = {r.name for r in rows}
    found = [*PAIRS, *((r.name, other) for r in rows if r.paper and r not in MODELS for other in ("single", "stam4"))]
    found += baseline_pairs({r.paper: r.name for r in rows if r.paper})
    return [(a, b) for a, b in dict.fromkeys(found) if a in names and b in names]


def build_parser() -> argparse.ArgumentParser:
    from stamlane.synth.layout import DEFAULT_SYNTHETIC_ROOT

    p = OneLineParser(prog="stamlane demo", description=__doc__.split("\n")[0])
    p.add_argument("--out", type=Path, default=Path("outputs/demo"), help="output folder (default outputs/demo)")
    p.add_argument("--data", type=Path, help=f"synthetic set (default {DEFAULT_SYNTHETIC_ROOT}; made if missing)")
    p.add_argument("--seeds", type=int, default=1, help="training seeds per model (default 1)")
    p.add_argument("--pretrain-steps", type=int, default=1200, help="stage 1: single-frame steps from scratch")
    p.add_argument("--finetune-steps", type=int, default=300, help="stage 2: steps of each model from stage 1")
    add_bf16_argument(p)
    p.add_argument("--no-noalign", action="store_true", help="skip the 4-frame model without alignment")
    p.add_argument("--single-clean", action="store_true", help="also the single frame without key-frame corruption")
    p.add_argument(
        "--rows",
        nargs="+",
        default=[],
        metavar="ID",
        help="also rows of the paper's tables (configs/paper/rows/<ID>.yaml) on the demo's recipe",
    )
    p.add_argument(
        "--all-probes",
        action="store_true",
        help="probe the history with another clip's on the test and challenging splits too (the reveal splits "
        "always are): a third prediction of their key frames by every multi-frame model",
    )
    p.add_argument("--max-overlays", type=int, default=12, help="overlay pictures per model and split")
    p.add_argument("--quick", action="store_true", help="a seconds-long smoke run on a tiny set (tests)")
    return p


def _comparison(experiment: Experiment, rows: list[Row], path: Path, count: int = 3) -> Path | None:
    """The same ``count`` challenging key frames with each seed-0 model's lanes, one column per model."""
    import cv2

    store = experiment.store
    folders = [store.pred_dir(store.run_name(r.name, experiment.seeds[0]), "challenging") / "overlays" for r in rows]
    frames = sorted(p.relative_to(folders[0]) for p in folders[0].rglob("*.jpg"))[:count]
    grid = []
    for frame in frames:
        cells = [cv2.imread(str(folder / frame)) for folder in folders]
        if any(c is None for c in cells):
            return None
        for cell, row in zip(cells, rows):
            cv2.putText(cell, row.label, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 2, cv2.LINE_AA)
        grid.append(np.concatenate(cells, axis=1))
    if not grid:
        return None
    cv2.imwrite(str(path), np.concatenate(grid, axis=0), [cv2.IMWRITE_JPEG_QUALITY, 85])
    return path


def run(args: argparse.Namespace) -> None:
    import torch

    torch.set_num_threads(1 if args.quick else max(1, os.cpu_count() or 1))
    rows = [m for m in MODELS if not ((args.no_noalign or args.quick) and m.name == "stam4_noalign")]
    rows += [SINGLE_CLEAN] if args.single_clean else []
    have = {m.name for m in rows} | {m.paper for m in rows}
    rows += [Row.paper_row(r) for r in dict.fromkeys(args.rows) if r not in have]
    check_data(args.data, quick=args.quick)
    steps = (3, 2) if args.quick else (args.pretrain_steps, args.finetune_steps)
    recipe = replace(RECIPES["cpu"], pretrain_steps=steps[0], steps=steps[1])
    bf16 = bf16_of(args.bf16, quick=args.quick)
    outputs = [args.out / name for name in OUTPUTS]  # the experiment never writes among the frames and labels
    with claimed_out(args.out, outputs, [args.data], protected=[args.data]):  # a second demo on --out is refused
        _run(args, rows, recipe, bf16)


def _run(args: argparse.Namespace, rows: list[Row], recipe: Recipe, bf16: bool) -> None:
    from stamlane.experiments.report import plot_history_use, plot_reveal, plot_val_curves, tables
    from stamlane.safety.guard import write_atomic

    start = time.perf_counter()
    root = prepare_data(args.data, args.out, quick=args.quick)
    print(f"[stamlane] synthetic set {root} ready in {(time.perf_counter() - start) / 60:.1f} min", flush=True)
    experiment = Experiment(
        rows,
        recipe,
        list(range(args.seeds)),
        root,
        args.out,
        bf16=bf16,
        quick=args.quick,
        max_overlays=args.max_overlays,
        all_probes=args.all_probes,
    )
    summary = experiment.run(pairs(rows))
    runs = [("pretrain", "stage 1 (1 frame)", 0), *((r.name, r.label, recipe.pretrain_steps) for r in rows)]
    plot_val_curves(args.out, runs, experiment.seeds, args.out / "val_f1.png")
    pictures = {
        "val_f1_plot": args.out / "val_f1.png",
        "history_use": plot_history_use(summary, args.out / "history_use.png"),
        "history_use_vs_headroom": plot_reveal(summary, args.out / "history_use_vs_headroom.png"),
        "comparison": _comparison(experiment, rows, args.out / "comparison.jpg"),
    }
    summary.pictures = {k: str(v) for k, v in pictures.items() if v}
    summary.write(args.out / "summary.json")
    text = tables(summary)
    write_atomic(args.out / "tables.md", text + "\n")
    print(text)
    weights = experiment.store.last_ckpt(experiment.store.run_name("<model>", "<seed>"))
    print(
        f"[stamlane] wrote {args.out}/summary.json, tables.md, the pictures, and predictions under "
        f"{experiment.store.predictions}; final weights: {weights}"
    )


def main(argv: list[str] | None = None) -> int:
    args = parse_or_status(build_parser(), argv)
    if isinstance(args, int):
        return args
    for option in ("seeds", "pretrain_steps", "finetune_steps"):
        if getattr(args, option) < 1:
            print(
                f"stamlane demo: --{option.replace('_', '-')} must be >= 1, got {getattr(args, option)}",
                file=sys.stderr,
            )
            return 2
    return run_command("stamlane demo", lambda: run(args) or 0, ExperimentError)


if __name__ == "__main__":
    sys.exit(main())
