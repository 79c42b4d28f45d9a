"""``stamlane demo``: README command 1 — synthetic clips, train, evaluate with stamlane-eval, pictures.

    stamlane demo [--out outputs/demo] [--minutes-per-model 8] [--no-noalign] [--quick]

1. generates the synthetic set at ``data/synthetic`` when missing (``stamlane.data``);
2. trains the 4-frame pre-aligned STAM model (``configs/demo.yaml``), the single-frame baseline
   (``configs/demo_single.yaml``) and the 4-frame model without alignment (``configs/demo_noalign.yaml``)
   for the SAME number of steps (the paper compares at equal iterations): the number that fits the
   4-frame model in ``--minutes-per-model`` (calibrated from a short timed run; ``--steps`` sets it);
   the single-frame model, ~2-3x cheaper per step, takes less time;
3. predicts the synthetic ``val`` and ``challenging`` splits with each model (TuSimple json-lines +
   overlay pictures under ``<out>/predictions/<model>/<split>``) and scores them with
   ``stamlane_eval.tusimple`` against the split's label file, as ``stamlane-eval tusimple`` would;
4. writes ``<out>/val_f1.png`` (validation F1 over training, every model), ``<out>/comparison.jpg`` (the
   same challenging key frames side by side, one column per model), ``<out>/summary.json``
   (per model: frames, alignment, steps, minutes, accuracy / FP / FN / F1 per split) and prints a table.

``--quick`` is a seconds-long smoke run on a tiny generated set (used by the tests; 2 models, 3 steps);
its numbers mean nothing.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["DemoModel", "main"]

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs"


@dataclass(frozen=True)
class DemoModel:
    """One model of the demo: its name, config file and a one-line description."""

    name: str
    config: str
    label: str


MODELS = (
    DemoModel("stam4", "demo.yaml", "4 frames, pre-aligned, STAM"),
    DemoModel("single", "demo_single.yaml", "1 frame (baseline)"),
    DemoModel("stam4_noalign", "demo_noalign.yaml", "4 frames, no alignment, STAM"),
)
SPLITS = ("test", "challenging")
"""The splits the demo scores: the clean test split and the challenging one (val only picks checkpoints)."""
QUICK_OVERRIDES = [
    "--data.image_size=[64, 128]",
    "--model.encoder.width=0.125",
    "--model.bf16=false",
    "--model.channels_last=false",
    "--data.batch_size=2",
    "--data.num_workers=0",
]


class DemoError(Exception):
    """A known failure of the demo: printed as one line, exit status 2."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="stamlane demo", description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path("outputs/demo"), help="output folder")
    parser.add_argument(
        "--data", type=Path, default=None, help="synthetic set (default data/synthetic; made if missing)"
    )
    parser.add_argument("--minutes-per-model", type=float, default=8.0, help="training budget of the 4-frame model")
    parser.add_argument("--steps", type=int, default=None, help="training steps of every model (default: calibrated)")
    parser.add_argument("--seeds", type=int, default=1, help="training seeds per model (F1 as mean ± std)")
    parser.add_argument("--no-noalign", action="store_true", help="skip the 4-frame model without alignment")
    parser.add_argument("--quick", action="store_true", help="seconds-long smoke run on a tiny set (tests)")
    parser.add_argument("--max-overlays", type=int, default=12, help="overlay pictures per model and split")
    return parser


def _require_pieces() -> None:
    missing = []
    for module in ("stamlane.models", "stamlane.losses", "stamlane.data.datamodule", "stamlane_eval.tusimple"):
        try:
            __import__(module)
        except ImportError as err:
            missing.append(f"{module} ({err})")
    if missing:
        raise DemoError("the demo needs pieces that are not installed yet: " + "; ".join(missing))


def _make_data(root: Path | None, out: Path, quick: bool) -> Path:
    from stamlane.data import SynthConfig, generate_dataset
    from stamlane.data.datamodule import DEFAULT_SYNTHETIC_ROOT, ClipDataModule

    if quick:
        root = root or out / "quick_data"
        if not (root / "dataset.json").is_file():
            cfg = SynthConfig(width=256, height=144, num_frames=4)
            generate_dataset(root, train=4, val=2, test=2, challenging=2, seed=0, config=cfg, progress=False)
        return root
    if root is None:
        ClipDataModule(root=None).prepare_data()  # generates data/synthetic when missing (progress bar)
        return Path(DEFAULT_SYNTHETIC_ROOT)
    if root.exists() and not root.is_dir():
        raise DemoError(f"--data {root} is not a folder")
    if not (root / "train.json").is_file():  # the default set's settings, generated at the given place
        ClipDataModule(root=None).generate_synthetic(root)
    return root


def _step_timer() -> Any:
    """A Lightning callback recording the wall time of each training step (batch start to batch end)."""
    import lightning.pytorch as pl

    class StepTimer(pl.Callback):
        def __init__(self) -> None:
            self.times: list[float] = []
            self._start = 0.0

        def on_train_batch_start(self, *args: Any) -> None:
            self._start = time.perf_counter()

        def on_train_batch_end(self, *args: Any) -> None:
            self.times.append(time.perf_counter() - self._start)

    return StepTimer()


def _cli(args: list[str], **kwargs: Any) -> Any:
    from stamlane.lightning_cli import StamLaneCLI

    argv, sys.argv = sys.argv, sys.argv[:1]  # LightningCLI warns when given args beside the demo's own argv
    try:
        return StamLaneCLI(args=args, **kwargs)
    finally:
        sys.argv = argv


def _common(model: DemoModel, root: Path, out: Path, quick: bool) -> list[str]:
    return [
        "--config",
        str(CONFIG_DIR / model.config),
        f"--data.root={root}",
        "--trainer.enable_progress_bar=false" if quick else "--trainer.enable_progress_bar=true",
        *(QUICK_OVERRIDES if quick else []),
    ]


def _calibrate(model: DemoModel, root: Path, out: Path, quick: bool) -> float:
    """Median seconds per training step of ``model`` (a short timed run, thrown away)."""
    timer = _step_timer()
    steps = 3 if quick else 12
    args = [
        "fit",
        *_common(model, root, out, quick),
        f"--trainer.max_steps={steps}",
        "--trainer.limit_val_batches=0",
        "--trainer.logger=false",
        "--trainer.enable_checkpointing=false",
        "--trainer.callbacks=[]",
        "--trainer.enable_model_summary=false",
        "--trainer.enable_progress_bar=false",
        f"--trainer.default_root_dir={out / 'calibration'}",
    ]
    _cli(args, trainer_defaults={"callbacks": [timer]})
    times = sorted(timer.times[2:] or timer.times)  # the first steps pay for warm-up and alignment
    return times[len(times) // 2]


def _train(model: DemoModel, root: Path, out: Path, steps: int, quick: bool, seed: int) -> Path:
    """Fit ``model`` for ``steps`` steps with ``seed``; returns its run folder (config.yaml, metrics.csv,
    checkpoints: ``last.ckpt`` holds the final weights)."""
    val_every = max(1, steps // 6)
    name = f"{model.name}-s{seed}"
    args = [
        "fit",
        *_common(model, root, out, quick),
        f"--seed_everything={seed}",
        f"--trainer.max_steps={steps}",
        f"--trainer.val_check_interval={val_every}",
        f"--trainer.log_every_n_steps={max(1, min(25, val_every))}",
        f"--trainer.default_root_dir={out / name}",
        f"--trainer.logger.save_dir={out}",
        f"--trainer.logger.name={name}",
        "--trainer.logger.version=run",
    ]
    cli = _cli(args)
    return Path(cli.trainer.logger.log_dir)


def _predict(name: str, run: Path, out: Path, split: str, max_overlays: int) -> Path:
    """Predict ``split`` with the FINAL weights (``last.ckpt``) of run ``name`` (model and seed); returns the
    predictions folder ``<out>/predictions/<name>/<split>``."""
    pred_dir = out / "predictions" / name / split
    args = [
        "predict",
        "--config",
        str(run / "config.yaml"),
        f"--ckpt_path={run / 'checkpoints' / 'last.ckpt'}",
        f"--data.predict_labels=[{split}.json]",
        "--trainer.logger=false",
        "--trainer.callbacks=[]",
        "--trainer.enable_progress_bar=false",
        f"--predictions.output_dir={pred_dir}",
        f"--predictions.max_overlays={max_overlays}",
    ]
    _cli(args)
    return pred_dir


def _score(pred_dir: Path, labels: Path) -> tuple[dict, np.ndarray, list[str]]:
    """Score ``pred_dir/predictions.json`` against ``labels`` as ``stamlane-eval tusimple`` does and write
    ``pred_dir/per_image.jsonl``. Returns the numbers, the per-image ``(fp, fn)`` rates in LABEL order and
    each image's clip (the bootstrap's unit)."""
    from stamlane_eval.io import read_tusimple
    from stamlane_eval.tusimple import evaluate

    preds, gts = read_tusimple(pred_dir / "predictions.json"), read_tusimple(labels)
    result = evaluate(preds, gts)
    by_name = {p["raw_file"]: r for p, r in zip(preds, result.per_image)}
    rows = []
    for gt in gts:
        r = by_name[gt["raw_file"]]
        rows.append({"raw_file": gt["raw_file"], "clip": _clip_of(gt["raw_file"]), **asdict(r)})
    _write_atomic(pred_dir / "per_image.jsonl", "".join(json.dumps(row) + "\n" for row in rows))
    rates = np.array([[row["fp"], row["fn"]] for row in rows], dtype=np.float64)
    scores = {k: result.as_dict()[k] for k in ("accuracy", "fp", "fn", "f1", "images")}
    return scores, rates, [row["clip"] for row in rows]


def _clip_of(raw_file: str) -> str:
    """The clip of a key frame: its folder (``clips/test-0007/20.jpg`` -> ``clips/test-0007``)."""
    return raw_file.rsplit("/", 1)[0]


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _val_curve(run: Path) -> list[tuple[int, float]]:
    rows = list(csv.DictReader((run / "metrics.csv").open()))
    return [(int(r["step"]) + 1, float(r["val/tusimple_f1"])) for r in rows if r.get("val/tusimple_f1")]


def _plot(curves: dict[str, list[tuple[int, float]]], labels: dict[str, str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for name, points in curves.items():
        if points:
            steps, f1 = zip(*points)
            ax.plot(steps, f1, marker="o", label=labels[name])
    ax.set_xlabel("training step")
    ax.set_ylabel("validation F1 (TuSimple, paper's)")
    ax.set_title("synthetic clips, same number of steps per model")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _comparison(
    out: Path, names: list[str], labels: list[str], split: str = "challenging", rows: int = 3
) -> Path | None:
    """``<out>/comparison.jpg``: the same ``rows`` key frames of ``split``, one column per run, labelled."""
    import cv2

    first = out / "predictions" / names[0] / split / "overlays"
    frames = sorted(p.relative_to(first) for p in first.rglob("*.jpg"))[:rows]
    if not frames:
        return None
    grid = []
    for frame in frames:
        cells = []
        for name, label in zip(names, labels):
            image = cv2.imread(str(out / "predictions" / name / split / "overlays" / frame))
            if image is None:
                return None
            cv2.putText(image, label, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 2, cv2.LINE_AA)
            cells.append(image)
        grid.append(np.concatenate(cells, axis=1))
    path = out / "comparison.jpg"
    cv2.imwrite(str(path), np.concatenate(grid, axis=0), [cv2.IMWRITE_JPEG_QUALITY, 85])
    return path


def _aggregate(entry: dict, rates: dict[str, list[np.ndarray]], clips: dict[str, list[str]]) -> None:
    """Per split: F1 mean and std over the seeds, and the 95 % interval (clips resampled) of the F1 of the
    seed-averaged per-image rates."""
    from stamlane_eval.stats import bootstrap, f1_of_rates

    for split in SPLITS:
        f1 = np.array([run[split]["f1"] for run in entry["runs"]])
        ci = bootstrap(np.mean(rates[split], axis=0), f1_of_rates, groups=clips[split])
        entry[split] = {
            "f1_mean": float(f1.mean()),
            "f1_std": float(f1.std(ddof=1)) if len(f1) > 1 else None,
            "f1_ci95": [ci.low, ci.high],
            "seeds": len(f1),
        }


PAIRS = (("stam4", "single"), ("stam4_noalign", "single"), ("stam4", "stam4_noalign"))
"""The demo's comparisons, A against B: what the history frames bring, with and without alignment."""


def _compare(summary: dict, rates: dict, clips: dict) -> list[dict]:
    """Paired bootstrap of every pair in ``PAIRS`` present, per split: F1(A) - F1(B) on the same images."""
    from stamlane_eval.stats import f1_of_rates, paired_bootstrap

    present = {m["name"] for m in summary["models"]}
    found = []
    for a, b in PAIRS:
        if a not in present or b not in present:
            continue
        for split in SPLITS:
            est = paired_bootstrap(
                np.mean(rates[a][split], axis=0),
                np.mean(rates[b][split], axis=0),
                f1_of_rates,
                groups=clips[split],
            )
            found.append({"a": a, "b": b, "split": split, "f1_diff": est.value, "ci95": [est.low, est.high]})
    return found


def _table(summary: dict) -> str:
    """The printed results: F1 (%) per model and split as mean [95 % CI] (± seed std), then the differences."""
    head = f"{'model':<32} {'frames':>6} {'steps':>6} {'seeds':>5}"
    for split in SPLITS:
        head += f" | {split + ' F1 % [95% CI]':>30}"
    lines = [head, "-" * len(head)]
    for entry in summary["models"]:
        line = f"{entry['label']:<32} {entry['frames']:>6} {entry['steps']:>6} {len(entry['runs']):>5}"
        for split in SPLITS:
            m = entry[split]
            std = f" ±{100 * m['f1_std']:.1f}" if m["f1_std"] is not None else ""
            cell = f"{100 * m['f1_mean']:.1f} [{100 * m['f1_ci95'][0]:.1f}, {100 * m['f1_ci95'][1]:.1f}]{std}"
            line += f" | {cell:>30}"
        lines.append(line)
    if summary["comparisons"]:
        lines += ["", "paired differences of F1 (same images; 95 % CI, clips resampled):"]
        for c in summary["comparisons"]:
            sure = "" if c["ci95"][0] <= 0 <= c["ci95"][1] else "  (interval excludes 0)"
            lines.append(
                f"  {c['a']:>13} - {c['b']:<13} {c['split']:<12} {100 * c['f1_diff']:+6.1f} "
                f"[{100 * c['ci95'][0]:+.1f}, {100 * c['ci95'][1]:+.1f}]{sure}"
            )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> dict:
    """Run the demo (see the module docstring); returns the summary written to ``summary.json``."""
    _require_pieces()
    import torch

    torch.set_num_threads(1 if args.quick else max(1, os.cpu_count() or 1))
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    root = _make_data(args.data, out, args.quick)
    skip_noalign = args.no_noalign or args.quick  # the quick run checks the machinery, not the ablation
    models = [m for m in MODELS if not (skip_noalign and m.name == "stam4_noalign")]
    seeds = list(range(args.seeds))
    summary: dict[str, Any] = {"data": str(root), "minutes_per_model": args.minutes_per_model, "seeds": seeds}
    summary["models"] = []
    curves, curve_labels = {}, {}
    steps, sec = (3, 0.0) if args.quick else (args.steps, 0.0)
    if steps is None:
        sec = _calibrate(models[0], root, out, args.quick)
        steps = max(50, int(args.minutes_per_model * 60 / sec))
        print(f"[demo] {models[0].name}: {sec:.2f} s/step -> {steps} steps for every model", flush=True)
    summary["steps"] = steps
    summary["calibrated_seconds_per_step"] = round(sec, 3) if sec else None
    rates: dict[str, dict[str, list[np.ndarray]]] = {}
    clips: dict[str, list[str]] = {}
    for model in models:
        entry: dict[str, Any] = {
            "name": model.name,
            "label": model.label,
            "config": f"configs/{model.config}",
            "steps": steps,
            "runs": [],
        }
        rates[model.name] = {split: [] for split in SPLITS}
        for seed in seeds:
            name = f"{model.name}-s{seed}"
            print(f"[demo] {name}: {model.label}, seed {seed}, {steps} steps", flush=True)
            start = time.perf_counter()
            run_dir = _train(model, root, out, steps, args.quick, seed)
            record: dict[str, Any] = {
                "seed": seed,
                "train_minutes": round((time.perf_counter() - start) / 60, 2),
                "run": str(run_dir),
                "last_ckpt": str(run_dir / "checkpoints" / "last.ckpt"),
            }
            config = (run_dir / "config.yaml").read_text()
            entry["frames"] = int(next(line.split(":")[1] for line in config.splitlines() if "num_frames:" in line))
            for split in SPLITS:
                pred_dir = _predict(name, run_dir, out, split, args.max_overlays)
                record[split], split_rates, clips[split] = _score(pred_dir, root / f"{split}.json")
                rates[model.name][split].append(split_rates)
            entry["runs"].append(record)
            curves[name], curve_labels[name] = _val_curve(run_dir), f"{model.label}, seed {seed}"
            _write_atomic(out / "summary.json", json.dumps(summary | {"partial": entry}, indent=2))
        _aggregate(entry, rates[model.name], clips)
        summary["models"].append(entry)
    summary["comparisons"] = _compare(summary, rates, clips)
    _plot(curves, curve_labels, out / "val_f1.png")
    summary["val_f1_plot"] = str(out / "val_f1.png")
    comparison = _comparison(out, [f"{m.name}-s0" for m in models], [m.label for m in models])
    summary["comparison"] = str(comparison) if comparison else None
    _write_atomic(out / "summary.json", json.dumps(summary, indent=2))
    print(_table(summary))
    print(
        f"[demo] wrote {out / 'summary.json'}, {out / 'val_f1.png'}, predictions, per-image results and overlays "
        f"under {out / 'predictions'}; final weights: {out}/<model>-s<seed>/run/checkpoints/last.ckpt"
    )
    return summary


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.minutes_per_model <= 0:
        print(f"stamlane demo: --minutes-per-model must be > 0, got {args.minutes_per_model}", file=sys.stderr)
        return 2
    if args.seeds < 1:
        print(f"stamlane demo: --seeds must be >= 1, got {args.seeds}", file=sys.stderr)
        return 2
    if args.steps is not None and args.steps < 1:
        print(f"stamlane demo: --steps must be >= 1, got {args.steps}", file=sys.stderr)
        return 2
    try:
        run(args)
    except DemoError as err:
        print(f"stamlane demo: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
