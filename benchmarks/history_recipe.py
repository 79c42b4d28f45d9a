"""What makes the fusion read its history: recipe variants trained side by side, history use over training steps.

    python benchmarks/history_recipe.py [--out outputs/bench/history_recipe] [--variants NAME ...] [--seed 0]
                                        [--bf16 auto|true|false] [--data data/synthetic-v5]

Every variant trains the demo's 4-frame pre-aligned STAM model (``configs/demo.yaml``) in the demo's two stages
(the single-frame network from scratch, then the 4-frame model from its weights) or end to end, on the synthetic
set of format 5, and validates on its val split (clean and factor clips; never the test or challenging clips)
with `stamlane.training.history_use_monitor.HistoryUseMonitor`: the TuSimple F1 with the real history minus with the key frame
copied into every history slot, at every validation. A stage 1 shared by several variants is trained once.

After training, the final weights are scored on the val split three ways by the experiment engine (real
history, the key frame copied, another clip's history; `stamlane.experiments.engine.Experiment.predict`), per
factor: history use and the damage another clip's history does, with clip intervals.

Writes ``<out>/history_recipe.json`` (per variant: settings, minutes, per validation step the val F1, the
key-copied F1, the history use in F1 and in segmentation loss, and the final probes per view) and
``<out>/history_recipe.png`` (history use and val F1 over steps, one line per variant), and prints the last
validation of each variant. A finished variant is read back, not trained again.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONFIGS = REPO / "configs"


@dataclass(frozen=True)
class Stage:
    """One training run: its config, data and model overrides, and steps."""

    config: str
    steps: int
    overrides: tuple[str, ...] = ()

    def key(self) -> str:
        return json.dumps([self.config, self.steps, *self.overrides])


@dataclass(frozen=True)
class Variant:
    """A recipe: an optional stage 1 (single frame, whose final weights start the main run) and the main run."""

    name: str
    description: str
    main: Stage
    stage1: Stage | None = None
    notes: dict = field(default_factory=dict)


CLEAN = ("--data.train_labels=[train-clean.json]",)
FACTORS = ()  # train.json: the clean clips and as many factor clips
CORRUPT = ("--data.augment.key_corruption=0.5",)
VAL = ("--data.val_labels=[val.json]",)
TRUE = ("--data.clip.align=true",)  # the generator's exact homographies: alignment taken out of the question
STRIDE8 = ("--model.fuse_skip=true",)  # measured as --model.skip_fusion=STAM (reduction 4, features): the same network


def _two_stage(
    name: str,
    description: str,
    data: tuple[str, ...],
    steps2: int = 300,
    extra: tuple = (),
    stage1_data: tuple[str, ...] | None = None,
) -> Variant:
    return Variant(
        name,
        description,
        Stage("demo.yaml", steps2, (*data, *VAL, *extra)),
        Stage("demo_single.yaml", 1200, (*(data if stage1_data is None else stage1_data), *VAL)),
    )


VARIANTS = {
    v.name: v
    for v in (
        _two_stage("clean", "README command 1 before: clean clips, stage 2 of 300 steps", CLEAN),
        _two_stage("factors", "half the train clips with a challenging factor", FACTORS),
        _two_stage("factors_corrupt", "factor clips and the key frame corrupted in half the clips", FACTORS + CORRUPT),
        _two_stage("factors_corrupt_long", "the same with a stage 2 of 900 steps", FACTORS + CORRUPT, steps2=900),
        _two_stage(
            "factors_corrupt_lr10",
            "the same (300 steps) with the fusion's learning rate x10",
            FACTORS + CORRUPT,
            extra=("--model.fusion_lr_scale=10",),
        ),
        _two_stage("corrupt", "clean clips, the key frame corrupted in half of them", CLEAN + CORRUPT),
        _two_stage(
            "factors_corrupt_stride8",
            "factor clips and corruption, the stride-8 stage fused too (skip_fusion)",
            FACTORS + CORRUPT,
            extra=STRIDE8,
        ),
        _two_stage(
            "factors_corrupt_stride8_long", "the same with a stage 2 of 900 steps", FACTORS + CORRUPT, 900, STRIDE8
        ),
        _two_stage(
            "factors_corrupt2_stride8",
            "the key frame corrupted in stage 2 only (stage 1: factor clips, no corruption), stride-8 fusion",
            FACTORS + CORRUPT,
            extra=STRIDE8,
            stage1_data=FACTORS,
        ),
        _two_stage(
            "factors_blank2_stride8",
            "stage 2 only: the near road of the key frame blanked or the frame overexposed in half the clips",
            (*FACTORS, *CORRUPT, "--data.augment.key_corruption_kinds=[blank, glare]"),
            extra=STRIDE8,
            stage1_data=FACTORS,
        ),
        _two_stage(
            "factors_blank2",
            "the same without the stride-8 fusion",
            (*FACTORS, *CORRUPT, "--data.augment.key_corruption_kinds=[blank, glare]"),
            stage1_data=FACTORS,
        ),
        _two_stage(
            "factors_corrupt25_stride8",
            "the key frame corrupted in a quarter of the clips (both stages), stride-8 fusion",
            (*FACTORS, "--data.augment.key_corruption=0.25"),
            extra=STRIDE8,
        ),
        _two_stage(
            "factors_corrupt_true",
            "factor clips and corruption, exact alignment (the generator's homographies) in training and validation",
            FACTORS + CORRUPT,
            extra=TRUE,
        ),
        _two_stage(
            "factors_corrupt_stride8_true",
            "the same with the stride-8 stage fused too",
            FACTORS + CORRUPT,
            extra=(*TRUE, *STRIDE8),
        ),
        Variant(
            "end_to_end",
            "factor clips and corruption, the 4-frame model from scratch for 1,500 steps",
            Stage("demo.yaml", 1500, (*FACTORS, *CORRUPT, *VAL)),
        ),
    )
}


def _fit(stage: Stage, folder: Path, root: Path, seed: int, bf16: str, init: Path | None) -> Path:
    """Train ``stage`` into ``folder`` and return its run folder (config.yaml, metrics.csv, checkpoints)."""
    from stamlane.training.lightning_cli import StamLaneCLI

    val_every = max(1, stage.steps // (6 if init is None else 3))
    args = [
        "fit",
        "--config",
        str(CONFIGS / stage.config),
        f"--data.root={root}",
        f"--model.bf16={bf16}",
        f"--seed_everything={seed}",
        f"--trainer.max_steps={stage.steps}",
        f"--trainer.val_check_interval={val_every}",
        "--trainer.enable_progress_bar=false",
        f"--trainer.default_root_dir={folder}",
        f"--trainer.logger.save_dir={folder}",
        "--trainer.logger.name=.",
        "--trainer.logger.version=run",
        "--trainer.callbacks+=stamlane.training.history_use_monitor.HistoryUseMonitor",
        *([f"--model.init_weights={init}"] if init else []),
        *stage.overrides,
    ]
    argv, sys.argv = sys.argv, sys.argv[:1]
    try:
        cli = StamLaneCLI(args=args)
    finally:
        sys.argv = argv
    return Path(cli.trainer.logger.log_dir)


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


def probe(run: Path, root: Path, out: Path) -> dict:
    """The final weights of ``run`` on the val split with the real history, the key frame copied and another clip's
    history: per view (the split and each factor), the F1 and both differences with their clip intervals."""
    from dataclasses import asdict

    from stamlane.experiments.engine import RECIPES, Experiment
    from stamlane.experiments.metrics import TUSIMPLE
    from stamlane.experiments.scoring import read_per_image, score_split
    from stamlane.experiments.stats import Scores, views

    experiment = Experiment([], RECIPES["cpu"], [], root, out, max_overlays=0)
    scores = Scores()
    for source in ("real", "key", "other_clip"):
        pred = experiment.predict("final", run, "val", source)
        score_split(pred, root, "val", 4)
        per_image, clips = read_per_image(pred)
        scores.add("final" if source == "real" else f"final@{source}", "val", 0, per_image, clips)
    found = {}
    for view in views(root, scores.clips):
        value = scores.value("final", view, TUSIMPLE)
        found[view.name] = {
            "f1": value.mean,
            "f1_ci95": value.ci95,
            **{
                f"minus_{source}": asdict(scores.difference("probe", "final", f"final@{source}", view, TUSIMPLE))
                for source in ("key", "other_clip")
            },
        }
    return found


def run_variant(variant: Variant, out: Path, root: Path, seed: int, bf16: str, stage1_runs: dict) -> dict:
    folder = out / variant.name
    done = folder / "result.json"
    if done.is_file():
        result = json.loads(done.read_text())
        if "probes" not in result:  # a variant trained before the probes were: probed now, not trained again
            result["probes"] = probe(folder / "run", root, folder / "probes")
            done.write_text(json.dumps(result, indent=2))
        return result
    start = time.perf_counter()
    init, offset = None, 0
    if variant.stage1 is not None:
        key = variant.stage1.key()
        if key not in stage1_runs:
            stage1_dir = out / f"stage1-{hashlib.sha256(key.encode()).hexdigest()[:10]}"
            ckpt = stage1_dir / "run" / "checkpoints" / "last.ckpt"
            if not ckpt.is_file():
                print(f"[history_recipe] stage 1 for {variant.name}: {variant.stage1}", flush=True)
                _fit(variant.stage1, stage1_dir, root, seed, bf16, None)
            stage1_runs[key] = ckpt
        init, offset = stage1_runs[key], variant.stage1.steps
    print(f"[history_recipe] {variant.name}: {variant.description}", flush=True)
    run = _fit(variant.main, folder, root, seed, bf16, init)
    result = {
        "name": variant.name,
        "description": variant.description,
        "main": variant.main.__dict__ | {"overrides": list(variant.main.overrides)},
        "stage1": None if variant.stage1 is None else variant.stage1.key(),
        "seed": seed,
        "bf16": bf16,
        "minutes": round((time.perf_counter() - start) / 60, 2),
        "curve": _curve(run, offset),
        "probes": probe(run, root, folder / "probes"),
    }
    done.write_text(json.dumps(result, indent=2))
    return result


def _plot(results: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from stamlane.experiments.report import series_style

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
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    from stamlane.synth.generator import DEFAULT_SYNTHETIC_ROOT

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/history_recipe"))
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--bf16", choices=("auto", "true", "false"), default="auto")
    parser.add_argument("--data", type=Path, default=Path(DEFAULT_SYNTHETIC_ROOT))
    args = parser.parse_args()
    if not (args.data / "train-clean.json").is_file():
        parser.error(f"{args.data} is not a synthetic set of format 5 (no train-clean.json); generate it first")
    args.out.mkdir(parents=True, exist_ok=True)
    stage1_runs: dict = {}
    results = [run_variant(VARIANTS[v], args.out, args.data, args.seed, args.bf16, stage1_runs) for v in args.variants]
    (args.out / "history_recipe.json").write_text(json.dumps(results, indent=2))
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


if __name__ == "__main__":
    main()
