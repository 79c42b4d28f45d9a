"""``stamlane demo``: README command 1 — the experiment engine on three models of synthetic clips, and pictures.

    stamlane demo [--out outputs/demo] [--data DIR] [--seeds 1] [--pretrain-steps 1200] [--finetune-steps 300]
                  [--bf16 auto|true|false] [--no-noalign] [--single-clean] [--rows ID ...] [--all-probes]
                  [--splits test challenging challenging-frames] [--reveal-probes key warped_key ...]
                  [--max-overlays 12] [--quick] [-- <stamlane fit arguments of every run>]

Generates the default synthetic set when missing, then runs `stamlane.experiments.engine` with the CPU recipe
(the single-frame network from scratch, then each model from its weights: every model gets the same steps on the
same data) on the 4-frame pre-aligned STAM model, the single frame and the 4-frame model without alignment (and
``--rows`` of the paper's tables), scores their final weights on the clean ``test``, the ``challenging`` and the
two reveal splits in TuSimple F1 and IoU F1 with intervals over clips and seeds, probes each multi-frame model's
history (the key frame copied into every history slot everywhere; on the reveal splits also the matched null,
the history reversed, another clip's history and exact alignment; ``--all-probes``: another clip's history on
every split), and writes ``summary.json``, ``tables.md``, ``val_f1.png``, ``history_use.png``,
``history_use_vs_headroom.png`` and ``comparison.jpg`` (the challenging key frames where the models differ most,
one column per model, with the ground truth and each model's score) to ``--out``, and prints the tables.
``--splits`` scores fewer splits (the reveal splits always, where the set has them; ``challenging-frames`` is the
frame-after-frame scoring) and ``--reveal-probes`` fewer probes on the reveal splits: the paper's tables on
``reveal`` need ``--splits reveal --reveal-probes key`` (docs/results.md).
Arguments after ``--`` go to every run's ``stamlane fit`` after the model's config (``-- --trainer.accelerator=gpu``
trains and predicts on a GPU; the run store is locked to them like every setting).
``--quick`` is a smoke run on a tiny set (its numbers mean nothing; the tests run it).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from stamlane_eval.cli_tools import OneLineParser, parse_or_status

from stamlane.experiments import workspace
from stamlane.experiments.engine import REVEAL_PROBES, Experiment
from stamlane.experiments.recipes import CONFIG_DIR, RECIPES, Recipe, Row
from stamlane.experiments.runner import TEMPORAL_SPLIT, check_fit_arguments
from stamlane.experiments.store import ExperimentError
from stamlane.safety.boundary import run_command
from stamlane.safety.guard import atomic_path

__all__ = ["MODELS", "OUTPUTS", "PAIRS", "SINGLE_CLEAN", "SPLITS", "build_parser", "main", "pairs"]

MODELS = (
    Row("stam4", "4 frames, pre-aligned, STAM", ("demo.yaml",), paper="f4_mixed_cs_features"),
    Row("single", "1 frame (baseline)", ("demo_single.yaml",), paper="f1_keyonly"),
    Row("stam4_noalign", "4 frames, no alignment, STAM", ("demo_noalign.yaml",), paper="f4_noalign_mixed_cs_features"),
)
SINGLE_CLEAN = Row("single_clean", "1 frame, no key-frame corruption", ("demo_single.yaml",), recipe_args=False)
"""``--single-clean``: the single frame trained without the recipe's key-frame corruption, which it cannot undo."""
PAIRS: tuple[tuple[str, str], ...] = (("stam4", "single"), ("stam4_noalign", "single"), ("stam4", "stam4_noalign"))
PAIRS += (("stam4", "single_clean"), ("single", "single_clean"))
"""The demo's comparisons, A against B: what the history frames bring, with and without alignment; what the
key-frame corruption costs a single frame and whether STAM is ahead of one trained without it."""
SPLITS = ("test", "challenging", TEMPORAL_SPLIT)
"""The splits the demo scores by default besides the reveal splits: the clean and the challenging key frames, and
the challenging clips frame after frame (temporal stability)."""
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

    p = OneLineParser(prog="stamlane demo", description=__doc__.split("\n")[0], epilog=workspace.FIT_ARGUMENTS_HELP)
    p.add_argument("--out", type=Path, default=Path("outputs/demo"), help="output folder (default outputs/demo)")
    p.add_argument("--data", type=Path, help=f"synthetic set (default {DEFAULT_SYNTHETIC_ROOT}; made if missing)")
    p.add_argument("--seeds", type=int, default=1, help="training seeds per model (default 1)")
    p.add_argument("--pretrain-steps", type=int, default=1200, help="stage 1: single-frame steps from scratch")
    p.add_argument("--finetune-steps", type=int, default=300, help="stage 2: steps of each model from stage 1")
    workspace.add_bf16_argument(p)
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
    p.add_argument(
        "--splits",
        nargs="+",
        type=workspace.split_name,
        default=list(SPLITS),
        metavar="SPLIT",
        help="label files scored besides the reveal splits (default: test challenging challenging-frames)",
    )
    p.add_argument(
        "--reveal-probes",
        nargs="+",
        choices=REVEAL_PROBES,
        default=list(REVEAL_PROBES),
        metavar="PROBE",
        help=f"history probes on the reveal splits (default all: {' '.join(REVEAL_PROBES)})",
    )
    p.add_argument("--max-overlays", type=int, default=12, help="overlay pictures per model and split")
    p.add_argument("--quick", action="store_true", help="a smoke run on a tiny set (tests)")
    return p


def differing_frames(accuracy: Sequence[dict[str, float]], count: int) -> list[str]:
    """The ``count`` key frames where models differ most: the largest spread (best minus worst) of their per-image
    accuracy, ties by name, one frame per clip (folder) before a clip's second; frames some model lacks are left
    out.

    Args:
        accuracy: per model, key frame name -> its per-image accuracy.
        count: how many frames.
    """
    common = set.intersection(*(set(a) for a in accuracy)) if accuracy else set()
    spread = {name: max(a[name] for a in accuracy) - min(a[name] for a in accuracy) for name in common}
    ranked = sorted(spread, key=lambda name: (-spread[name], name))
    firsts: dict[str, str] = {}  # clip -> its frame where the models differ most
    for name in ranked:
        firsts.setdefault(name.rpartition("/")[0], name)
    chosen = list(firsts.values())
    return (chosen + [name for name in ranked if name not in chosen])[:count]


def _comparison(experiment: Experiment, rows: list[Row], path: Path, count: int = 3) -> Path | None:
    """``count`` challenging key frames with each seed-0 model's lanes, one column per model (named in the header),
    one row per frame (named with its factor and the accuracies' spread above it): the frames where the models'
    per-image TuSimple accuracies (``per_image.jsonl``) differ most, drawn with the ground truth and each model's
    score (`stamlane.predict.overlay`); None when a model's predictions are missing."""
    import cv2
    from stamlane_eval.io import read_tusimple, tusimple_points

    from stamlane.experiments.split_scores import PER_IMAGE
    from stamlane.predict.overlay import draw_lanes, draw_legend, label_strip, text_scale
    from stamlane.safety.budget import MAX_RECORD_BYTES
    from stamlane.safety.guard import read_inside
    from stamlane.safety.images import read_image
    from stamlane.synth import FACTORS

    store = experiment.store
    folders = [store.pred_dir(store.run_name(r.name, experiment.seeds[0]), "challenging") for r in rows]
    if not all((f / PER_IMAGE).is_file() and (f / "predictions.json").is_file() for f in folders):
        return None
    scored = [  # records of the run folders: read only inside them, bounded
        {r["raw_file"]: r for r in map(json.loads, read_inside(f / PER_IMAGE, f, MAX_RECORD_BYTES).splitlines())}
        for f in folders
    ]
    frames = differing_frames([{name: r["acc"] for name, r in s.items()} for s in scored], count)
    if not frames:
        return None
    predicted = [{p["raw_file"]: p for p in read_tusimple(f / "predictions.json")} for f in folders]
    truth = {g["raw_file"]: g for g in read_tusimple(experiment.root / "challenging.json")}
    factor_of = {}
    for factor in FACTORS:
        labels = experiment.root / f"challenging-{factor}.json"
        if labels.is_file() and labels.stat().st_size:  # a factor without a clip has an empty label file
            factor_of.update({g["raw_file"]: factor for g in read_tusimple(labels)})
    grid = []
    image = None
    for name in frames:
        image = read_image(experiment.root / name)
        if image is None:
            return None
        gt = truth[name]
        gt_lanes = [lane for lane in tusimple_points(gt["lanes"], gt["h_samples"]) if len(lane) >= 2]
        cells = []
        for pred, score in zip(predicted, scored):
            lanes = [lane for lane in tusimple_points(pred[name]["lanes"], pred[name]["h_samples"]) if len(lane) >= 2]
            result = score[name]
            text = f"TuSimple acc {100 * result['acc']:.1f} %, {result['matched']}/{result['n_gt']} lanes"
            cells.append(draw_legend(draw_lanes(image, lanes, gt_lanes), score=text, predictions=False))
        accs = [100 * s[name]["acc"] for s in scored]
        what = f"{name}  ({factor_of[name]})" if name in factor_of else name
        scale = text_scale(image)
        row_label = f"{what}: accuracy {min(accs):.0f}-{max(accs):.0f} % across the models"
        strip = label_strip(image.shape[1] * len(cells), [row_label], round(60 * scale), scale)
        grid += [strip, np.concatenate(cells, axis=1)]
    if image is None:  # no frame to show
        return None
    scale = text_scale(image)
    header = label_strip(image.shape[1] * len(rows), [r.label for r in rows], round(70 * scale), 1.2 * scale)
    legend = "coloured lines: each model's lanes (one colour per lane);  yellow band in black: the ground truth"
    key = label_strip(header.shape[1], [legend], round(60 * scale), scale)
    with atomic_path(path) as tmp:
        cv2.imwrite(str(tmp), np.concatenate([header, key, *grid], axis=0), [cv2.IMWRITE_JPEG_QUALITY, 85])
    return path


def run(args: argparse.Namespace, extra: Sequence[str] = ()) -> None:
    """The demo of ``args``; ``extra``: ``stamlane fit`` arguments of every run."""
    import torch

    torch.set_num_threads(1 if args.quick else max(1, os.cpu_count() or 1))
    rows = [m for m in MODELS if not ((args.no_noalign or args.quick) and m.name == "stam4_noalign")]
    rows += [SINGLE_CLEAN] if args.single_clean else []
    have = {m.name for m in rows} | {m.paper for m in rows}
    rows += [Row.paper_row(r) for r in dict.fromkeys(args.rows) if r not in have]
    workspace.check_data(args.data, quick=args.quick)
    if extra:  # before the data are made: a fit argument every run would refuse is said now
        check_fit_arguments(CONFIG_DIR / rows[0].configs[0], extra)
    steps = (3, 2) if args.quick else (args.pretrain_steps, args.finetune_steps)
    recipe = replace(RECIPES["cpu"], pretrain_steps=steps[0], steps=steps[1])
    bf16 = workspace.bf16_of(args.bf16, quick=args.quick)
    outputs = [args.out / name for name in OUTPUTS]  # the experiment never writes among the frames and labels
    # a second demo on --out is refused
    with workspace.claimed_out(args.out, outputs, [args.data], protected=[args.data]):
        _run(args, rows, recipe, bf16, tuple(extra))


def _run(args: argparse.Namespace, rows: list[Row], recipe: Recipe, bf16: bool, extra: tuple[str, ...]) -> None:
    from stamlane.experiments.plots import plot_history_use, plot_reveal, plot_val_curves
    from stamlane.experiments.tables import tables
    from stamlane.safety.guard import write_atomic

    start = time.perf_counter()
    root = workspace.prepare_data(args.data, args.out, quick=args.quick)
    print(f"[stamlane] synthetic set {root} ready in {(time.perf_counter() - start) / 60:.1f} min", flush=True)
    splits = tuple(s for s in dict.fromkeys(args.splits) if s != TEMPORAL_SPLIT)
    missing = [s for s in splits if not (root / f"{s}.json").is_file()]
    if missing:
        raise ExperimentError(f"--splits: {root} has no {missing[0]}.json")
    experiment = Experiment(
        rows,
        recipe,
        list(range(args.seeds)),
        root,
        args.out,
        bf16=bf16,
        extra=extra,
        splits=splits,
        reveal_probes=tuple(dict.fromkeys(args.reveal_probes)),
        all_probes=args.all_probes,
        temporal=TEMPORAL_SPLIT in args.splits,
        quick=args.quick,
        max_overlays=args.max_overlays,
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
    """Entry point of ``stamlane demo`` (``argv`` without the subcommand)."""
    argv, extra = workspace.fit_arguments(list(sys.argv[1:] if argv is None else argv))
    args = parse_or_status(build_parser(), argv)
    if isinstance(args, int):
        return args
    if not set(args.splits) - {TEMPORAL_SPLIT}:
        print(f"stamlane demo: --splits must name a split besides {TEMPORAL_SPLIT}", file=sys.stderr)
        return 2
    for option in ("seeds", "pretrain_steps", "finetune_steps"):
        if getattr(args, option) < 1:
            print(
                f"stamlane demo: --{option.replace('_', '-')} must be >= 1, got {getattr(args, option)}",
                file=sys.stderr,
            )
            return 2

    def demo() -> int:
        run(args, extra)
        return 0

    return run_command("stamlane demo", demo, ExperimentError)


if __name__ == "__main__":
    sys.exit(main())
