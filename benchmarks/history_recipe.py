"""What makes the fusion read its history: recipe variants trained side by side, history use over training steps.

    python benchmarks/history_recipe.py [--out outputs/bench/history_recipe] [--variants NAME ...] [--seed 0]
                                        [--bf16 auto|true|false] [--data data/synthetic-v5]

Every variant is a recipe (`stamlane.experiments.recipes.Recipe`) of the demo's 4-frame pre-aligned STAM model
(``configs/demo.yaml``): the demo's two stages (the single-frame network from scratch, then the 4-frame model from
its weights) or end to end, on the synthetic set of format 5, validated on its val split (clean and factor clips;
never the test or challenging clips) with `stamlane.training.history_use_monitor.HistoryUseMonitor`: the TuSimple
F1 with the real history minus with the key frame copied into every history slot, at every validation. The runs
are trained and scored by the experiments' runner (`stamlane.experiments.runner.Runner`), into its run store
(``<out>/<row>-s<seed>/run``): a stage 1 shared by several variants is trained once (its row is named by its
settings), and a finished run is reused, not trained again.

After training, the final weights are scored on the val split three ways (real history, the key frame copied,
another clip's history; `Runner.score`), per factor: history use and the damage another clip's history does, with
clip intervals.

Writes ``<out>/history_recipe.json`` (per variant: its recipe, minutes, per validation step the val F1, the
key-copied F1, the history use in F1 and in segmentation loss, and the final probes per view) and
``<out>/history_recipe.png`` (history use and val F1 over steps, one line per variant), and prints the last
validation of each variant.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from _harness import fail, guard_out, write_figure, write_result

from stamlane.experiments.recipes import PRETRAIN, Recipe, Row
from stamlane.experiments.runner import Runner
from stamlane.training.runs import RunRecord, flags_of

MODEL = Row("stam4", "4 frames, pre-aligned, STAM", ("demo.yaml",))
PROBED = ("key", "other_clip")
"""The history probes of the final weights on val."""
Options = dict[str, Any]
"""A recipe's options over the configs, keyed by dotted names (`stamlane.training.runs.RunSpec`)."""
CLEAN: Options = {"data.train_labels": ["train-clean.json"]}
FACTORS: Options = {}  # train.json: the clean clips and as many factor clips
CORRUPT: Options = {"data.augment.key_corruption": 0.5}
VAL: Options = {"data.val_labels": ["val.json"]}
MONITOR: Options = {"trainer.callbacks+": "stamlane.training.history_use_monitor.HistoryUseMonitor"}
TRUE: Options = {"data.clip.align": True}  # the generator's exact homographies: alignment taken out of the question
STRIDE8: Options = {"model.fuse_skip": True}  # measured as --model.skip_fusion=STAM (reduction 4, features): the same


def _two_stage(
    name: str,
    description: str,
    data: Options,
    steps2: int = 300,
    extra: Options | None = None,
    stage1_data: Options | None = None,
) -> Recipe:
    """Stage 1 (1,200 single-frame steps on ``stage1_data``, default ``data``), then 300 steps of the model."""
    return Recipe(
        name,
        steps=steps2,
        pretrain_steps=1200,
        pretrain=PRETRAIN,
        row_overrides={**data, **VAL, **MONITOR, **(extra or {})},
        pretrain_overrides={**(data if stage1_data is None else stage1_data), **VAL, **MONITOR},
        val_checks=6,
        description=description,
    )


VARIANTS = {
    v.name: v
    for v in (
        _two_stage("clean", "README command 1 before: clean clips, stage 2 of 300 steps", CLEAN),
        _two_stage("factors", "half the train clips with a challenging factor", FACTORS),
        _two_stage(
            "factors_corrupt", "factor clips and the key frame corrupted in half the clips", {**FACTORS, **CORRUPT}
        ),
        _two_stage("factors_corrupt_long", "the same with a stage 2 of 900 steps", {**FACTORS, **CORRUPT}, steps2=900),
        _two_stage(
            "factors_corrupt_lr10",
            "the same (300 steps) with the fusion's learning rate x10",
            {**FACTORS, **CORRUPT},
            extra={"model.fusion_lr_scale": 10},
        ),
        _two_stage("corrupt", "clean clips, the key frame corrupted in half of them", {**CLEAN, **CORRUPT}),
        _two_stage(
            "factors_corrupt_stride8",
            "factor clips and corruption, the stride-8 stage fused too (skip_fusion)",
            {**FACTORS, **CORRUPT},
            extra=STRIDE8,
        ),
        _two_stage(
            "factors_corrupt_stride8_long", "the same with a stage 2 of 900 steps", {**FACTORS, **CORRUPT}, 900, STRIDE8
        ),
        _two_stage(
            "factors_corrupt2_stride8",
            "the key frame corrupted in stage 2 only (stage 1: factor clips, no corruption), stride-8 fusion",
            {**FACTORS, **CORRUPT},
            extra=STRIDE8,
            stage1_data=FACTORS,
        ),
        _two_stage(
            "factors_blank2_stride8",
            "stage 2 only: the near road of the key frame blanked or the frame overexposed in half the clips",
            {**FACTORS, **CORRUPT, "data.augment.key_corruption_kinds": ["blank", "glare"]},
            extra=STRIDE8,
            stage1_data=FACTORS,
        ),
        _two_stage(
            "factors_blank2",
            "the same without the stride-8 fusion",
            {**FACTORS, **CORRUPT, "data.augment.key_corruption_kinds": ["blank", "glare"]},
            stage1_data=FACTORS,
        ),
        _two_stage(
            "factors_corrupt25_stride8",
            "the key frame corrupted in a quarter of the clips (both stages), stride-8 fusion",
            {**FACTORS, "data.augment.key_corruption": 0.25},
            extra=STRIDE8,
        ),
        _two_stage(
            "factors_corrupt_true",
            "factor clips and corruption, exact alignment (the generator's homographies) in training and validation",
            {**FACTORS, **CORRUPT},
            extra=TRUE,
        ),
        _two_stage(
            "factors_corrupt_stride8_true",
            "the same with the stride-8 stage fused too",
            {**FACTORS, **CORRUPT},
            extra={**TRUE, **STRIDE8},
        ),
        Recipe(
            "end_to_end",
            steps=1500,
            row_overrides={**FACTORS, **CORRUPT, **VAL, **MONITOR},
            val_checks=6,
            description="factor clips and corruption, the 4-frame model from scratch for 1,500 steps",
        ),
    )
}


def _curve(run: Path, offset: int) -> list[dict]:
    """Per validation: step, val F1, key-copied F1, history use (F1 and segmentation loss)."""
    rows = list(csv.DictReader((run / "metrics.csv").open()))
    names = {
        "val/tusimple_f1": "f1",
        "val/keycopy_tusimple_f1": "keycopy_f1",
        "val/history_use_f1": "history_use_f1",
        "val/history_use_seg_loss": "history_use_seg_loss",
        "val/history_prob_change": "prob_change",
    }
    found: dict[int, dict] = {}
    for row in rows:
        for column, name in names.items():
            if row.get(column):
                found.setdefault(int(row["step"]) + 1 + offset, {})[name] = float(row[column])
    return [{"step": step, **values} for step, values in sorted(found.items())]


def probe(runner: Runner, name: str, record: RunRecord) -> dict:
    """The final weights of run ``name`` on the val split with the real history, the key frame copied and another
    clip's history: per view (the split and each factor), the F1 and both differences with their clip intervals."""
    from dataclasses import asdict

    from stamlane.experiments.intervals import Scores, views
    from stamlane.experiments.metrics import TUSIMPLE_F1

    if runner.score(name, record, {"val": PROBED}):
        runner.store.mark(name, record)
    scores = Scores()
    for key in ("val", *(f"val@{source}" for source in PROBED)):
        per_image, clips = runner.scored(name, record, key)
        scores.add(key.replace("val", "final", 1), "val", 0, per_image, clips)
    found = {}
    for view in views(runner.root, scores.clips):
        value = scores.value("final", view, TUSIMPLE_F1)
        found[view.name] = {
            "f1": value.mean,
            "f1_ci95": value.ci95,
            **{
                f"minus_{source}": asdict(scores.difference("probe", "final", f"final@{source}", view, TUSIMPLE_F1))
                for source in PROBED
            },
        }
    return found


def run_variant(runner: Runner, recipe: Recipe, seed: int) -> dict:
    """Train (or reuse) the variant's runs, probe its final weights, and read its curves."""
    settings = {"data": str(runner.root.resolve()), "bf16": runner.bf16, "extra": []}
    init, offset, minutes = None, 0, 0.0
    stage1 = recipe.pretraining()
    if stage1 is not None:  # named by what it is: variants with the same stage 1 share its run
        key = json.dumps([*PRETRAIN.configs, stage1.steps, *flags_of(stage1.overrides)])
        row = replace(PRETRAIN, name=f"stage1-{hashlib.sha256(key.encode()).hexdigest()[:10]}")
        first = runner.train(row, seed, stage1, settings | {"stage": key}, label=f"stage 1 of {recipe.name}")
        init, offset, minutes = first.last_ckpt, stage1.steps, first.train_minutes
    row = replace(MODEL, name=recipe.name)
    record = runner.train(row, seed, recipe.training(row), settings | recipe.settings(), init, recipe.name)
    name = runner.store.run_name(row.name, seed)
    return {
        "name": recipe.name,
        "description": recipe.description,
        "recipe": recipe.settings(),
        "seed": seed,
        "bf16": runner.bf16,
        "minutes": round(minutes + record.train_minutes, 2),
        "curve": _curve(record.run, offset),
        "probes": probe(runner, name, record),
    }


def _plot(results: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from stamlane.experiments.plots import series_style

    fig, axes = plt.subplots(1, 2, figsize=(13, 4))
    for k, r in enumerate(results):  # colour-blind-safe colours, then markers and line styles: no two alike
        points = [p for p in r["curve"] if "history_use_f1" in p]
        steps = [p["step"] for p in points]
        axes[0].plot(steps, [100 * p["history_use_f1"] for p in points], **series_style(k), label=r["name"])
        axes[1].plot(steps, [100 * p["f1"] for p in points], **series_style(k), label=r["name"])
    axes[0].axhline(0, color="grey", linewidth=0.8)
    axes[0].set_ylabel("history use: val F1 real - key frame copied (points)")
    axes[1].set_ylabel("val F1 (TuSimple, %)")
    for ax in axes:
        ax.set_xlabel("training step (stage 1 + stage 2)")
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=8, loc="center left", bbox_to_anchor=(1.02, 0.5))  # beside the curves, not on them
    fig.suptitle("4 frames, pre-aligned STAM: what makes the fusion read its history (synthetic val split)")
    fig.tight_layout()
    write_figure(fig, path, dpi=110)


def _say(line: str) -> None:
    print(f"[history_recipe] {line}", flush=True)


def main(argv: list[str] | None = None) -> int:
    from stamlane.experiments.store import RunStore
    from stamlane.experiments.workspace import add_bf16_argument, bf16_of
    from stamlane.synth.layout import DEFAULT_SYNTHETIC_ROOT

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/history_recipe"))
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--seed", type=int, default=0)
    add_bf16_argument(parser)
    parser.add_argument("--data", type=Path, default=Path(DEFAULT_SYNTHETIC_ROOT))
    args = parser.parse_args(argv)

    if (refused := guard_out("history_recipe.py", args.out, folder=True)) is not None:  # before any work
        return refused
    if not (args.data / "train-clean.json").is_file():
        return fail(
            "history_recipe.py",
            f"{args.data} is not a synthetic set of format 5 (no train-clean.json); generate it first",
        )
    args.out.mkdir(parents=True, exist_ok=True)
    runner = Runner(RunStore(args.out), args.data, bf16=bf16_of(args.bf16), progress=False, max_overlays=0, say=_say)
    results = [run_variant(runner, VARIANTS[v], args.seed) for v in args.variants]
    write_result(args.out / "history_recipe.json", results, indent=2, quiet=True)
    _plot(results, args.out / "history_recipe.png")
    print(
        f"{'variant':<24} {'minutes':>7} {'step':>5} {'val F1':>7} {'key copied':>10} {'history use':>11} {'loss gap':>9}"
    )
    for r in results:
        last = r["curve"][-1] if r["curve"] else {}
        print(
            f"{r['name']:<24} {r['minutes']:>7.1f} {last.get('step', 0):>5} {100 * last.get('f1', 0):>7.1f} "
            f"{100 * last.get('keycopy_f1', 0):>10.1f} {100 * last.get('history_use_f1', 0):>+11.1f} "
            f"{last.get('history_use_seg_loss', 0):>+9.4f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
