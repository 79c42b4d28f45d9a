"""``stamlane demo``: README command 1 — synthetic clips, train, evaluate with stamlane-eval, pictures.

    stamlane demo [--out outputs/demo] [--seeds 1] [--pretrain-steps 1200] [--finetune-steps 300]
                  [--no-noalign] [--quick]

1. generates the synthetic set at ``data/synthetic-v<format>`` when missing (``stamlane.data``);
2. trains in two stages (docs: the CPU recipe). Stage 1: the single-frame network (``configs/demo_single.yaml``)
   from scratch for ``--pretrain-steps``. Stage 2: from those weights, each demo model for ``--finetune-steps``
   more: the 4-frame pre-aligned STAM model (``configs/demo.yaml``), the single-frame baseline itself and the
   4-frame model without alignment (``configs/demo_noalign.yaml``). Every model thus gets the SAME number of
   steps on the same data (the paper compares at equal iterations); the 4-frame steps, 3x dearer, are spent
   where the temporal part is learnt;
3. predicts the ``test`` (clean) and ``challenging`` (one factor per clip) splits with each model's FINAL weights (TuSimple
   json-lines, per-image results and overlay pictures under ``<out>/predictions/<model>-s<seed>/<split>``)
   and scores them with ``stamlane_eval.tusimple`` as ``stamlane-eval tusimple --no-time-limit`` would (the
   benchmark's 200 ms rule measures the machine, not the model: the images over it are counted as ``late``),
   and with the CULane-style IoU F1 at 0.5 and 0.3 of the paper's ApolloScape tables (`iou_width`);
4. writes ``<out>/val_f1.png`` (validation F1 over training), ``<out>/comparison.jpg`` (the same challenging
   key frames side by side, one column per model), ``<out>/summary.json`` (per model and seed: steps, minutes,
   checkpoints, accuracy / FP / FN / F1 and IoU F1 per split; per model, per split and per factor of the
   challenging split: F1 mean ± std over seeds and its 95 % bootstrap interval, in both metrics; paired
   differences between models, `_pairs`) and prints the tables.

A finished run (``done.json``) is reused; a split whose labels changed since it was scored is predicted and
scored again with the run's final weights, one scored under other rules (`SCORING`) is scored again from its
predictions.

``--quick`` is a seconds-long smoke run on a tiny generated set (used by the tests; 2 models, 3 + 2 steps);
its numbers mean nothing.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from stamlane_eval.cli_tools import OneLineParser, parse_or_status
from stamlane_eval.culane import CULANE_SIZE, IOU_THRESHOLDS, LANE_WIDTH
from stamlane_eval.stats import f1_of_counts, f1_of_rates

__all__ = ["MODELS", "SPLITS", "DemoModel", "main", "predict_split", "score_split"]

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs"


@dataclass(frozen=True)
class DemoModel:
    """One model of the demo: its name, config file (under ``configs/``) and a one-line description; a row of
    the paper's tables also has its row config (``configs/paper/rows/<id>.yaml``) applied after
    ``configs/paper/ablation.yaml``. ``paper`` is the row of ``configs/paper/tables.yaml`` the model IS (the
    demo's own models are three of them: asking for those rows reuses them instead of training them again)."""

    name: str
    config: str
    label: str
    row: str | None = None
    paper: str | None = None

    def configs(self) -> list[str]:
        """The config files of a ``stamlane fit`` of this model, in order (relative to ``configs/``)."""
        return (
            [self.config] if self.row is None else [self.config, "paper/ablation.yaml", f"paper/rows/{self.row}.yaml"]
        )

    @classmethod
    def paper_row(cls, row: str) -> DemoModel:
        """A row of the paper's tables (``configs/paper/tables.yaml``) on the demo's base and recipe."""
        if not (CONFIG_DIR / "paper" / "rows" / f"{row}.yaml").is_file():
            known = sorted(p.stem for p in (CONFIG_DIR / "paper" / "rows").glob("*.yaml"))
            raise DemoError(f"no paper row {row!r}; known rows: {' '.join(known)}")
        return cls(row, "demo.yaml", f"paper row {row}", row=row, paper=row)


PRETRAIN = DemoModel("pretrain", "demo_single.yaml", "1 frame, stage 1 (every model starts here)")
"""Stage 1: the single-frame network trained from scratch; its final weights start every model of stage 2."""
MODELS = (
    DemoModel("stam4", "demo.yaml", "4 frames, pre-aligned, STAM", paper="f4_mixed_cs_features"),
    DemoModel("single", "demo_single.yaml", "1 frame (baseline)", paper="f1_keyonly"),
    DemoModel(
        "stam4_noalign", "demo_noalign.yaml", "4 frames, no alignment, STAM", paper="f4_noalign_mixed_cs_features"
    ),
)
SPLITS = ("test", "challenging")
"""The splits the demo scores: the clean test split and the challenging one (val only picks checkpoints)."""


@dataclass(frozen=True)
class Metric:
    """A number the demo reports for every split, factor and pair of models, made of per-image quantities.

    Attributes:
        key: ``"tusimple"``, the paper's TuSimple F1 (kept where the summary always kept it: ``entry[split]`` and
            ``summary["comparisons"]``), or ``"iou@0.5"`` / ``"iou@0.3"``, the CULane-style lane F1 of the
            paper's ApolloScape tables (``entry[key][split]``, ``summary["iou_comparisons"]``).
        columns: the quantities of one row of ``per_image.jsonl`` (``(fp, fn)`` rates or ``(tp, fp, fn)`` lanes).
        statistic: their means -> F1.
    """

    key: str
    columns: Callable[[dict], list[float]]
    statistic: Callable[[np.ndarray], float]


def _iou_metric(threshold: float) -> Metric:
    return Metric(f"iou@{threshold:g}", lambda row: row["iou"][f"{threshold:g}"], f1_of_counts)


TUSIMPLE = Metric("tusimple", lambda row: [row["fp"], row["fn"]], f1_of_rates)
METRICS = (TUSIMPLE, *(_iou_metric(t) for t in sorted(IOU_THRESHOLDS, reverse=True)))
"""What the demo scores each split with: TuSimple F1, then the IoU F1 at 0.5 and at 0.3."""


def iou_width(size: tuple[int, int]) -> int:
    """The CULane metric's line thickness for images of ``size`` (H, W): the protocol's 30 px on CULane's
    1640-px-wide frames, scaled with the image width (12 px at 640), so that a lane covers the same fraction of
    the image as in the benchmark."""
    return max(1, round(LANE_WIDTH * size[1] / CULANE_SIZE[1]))


QUICK_OVERRIDES = [
    "--data.image_size=[64, 128]",
    "--model.encoder.width=0.125",
    "--model.channels_last=false",
    "--data.batch_size=2",
    "--data.num_workers=0",
]


class DemoError(Exception):
    """A known failure of the demo: printed as one line, exit status 2."""


def _parser() -> argparse.ArgumentParser:
    from stamlane.synth.generator import DEFAULT_SYNTHETIC_ROOT

    parser = OneLineParser(prog="stamlane demo", description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path("outputs/demo"), help="output folder")
    parser.add_argument(
        "--data", type=Path, default=None, help=f"synthetic set (default {DEFAULT_SYNTHETIC_ROOT}; made if missing)"
    )
    parser.add_argument("--pretrain-steps", type=int, default=1200, help="stage 1: single-frame steps from scratch")
    parser.add_argument("--finetune-steps", type=int, default=300, help="stage 2: steps of each model from stage 1")
    parser.add_argument("--seeds", type=int, default=1, help="training seeds per model (F1 as mean ± std)")
    parser.add_argument(
        "--bf16",
        choices=("auto", "true", "false"),
        default="auto",
        help="bfloat16 autocast: auto = where the CPU runs it natively (AMX, AVX512-BF16); false = float32, "
        "to compare with results trained on an AVX2-only CPU (default auto)",
    )
    parser.add_argument("--no-noalign", action="store_true", help="skip the 4-frame model without alignment")
    parser.add_argument(
        "--rows",
        nargs="+",
        default=[],
        metavar="ID",
        help="also train rows of the paper's tables (configs/paper/rows/<ID>.yaml) on the demo's recipe, each "
        "compared with the single frame",
    )
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
    from stamlane.data.datamodule import DEFAULT_SYNTHETIC_ROOT, ClipDataModule
    from stamlane.synth import FACTORS, SynthConfig, generate_dataset

    if quick:
        root = root or out / "quick_data"
        if not (root / "dataset.json").is_file():
            cfg = SynthConfig(width=256, height=144, num_frames=4)
            hard = 2 * len(FACTORS)  # two clips per factor: an interval per factor
            generate_dataset(root, train=4, val=2, test=2, challenging=hard, seed=0, config=cfg, progress=False)
        return root
    if root is None:
        ClipDataModule(root=None).prepare_data()  # generates it when missing (progress bar)
        return Path(DEFAULT_SYNTHETIC_ROOT)
    if root.exists() and not root.is_dir():
        raise DemoError(f"--data {root} is not a folder")
    if not (root / "train.json").is_file():  # the default set's settings, generated at the given place
        ClipDataModule(root=None).generate_synthetic(root)
    return root


def _cli(args: list[str], **kwargs: Any) -> Any:
    from stamlane.lightning_cli import StamLaneCLI

    argv, sys.argv = sys.argv, sys.argv[:1]  # LightningCLI warns when given args beside the demo's own argv
    try:
        return StamLaneCLI(args=args, **kwargs)
    finally:
        sys.argv = argv


def _common(model: DemoModel, root: Path, out: Path, quick: bool, bf16: bool) -> list[str]:
    return [
        *(arg for config in model.configs() for arg in ("--config", str(CONFIG_DIR / config))),
        f"--data.root={root}",
        f"--model.bf16={str(bf16).lower()}",
        "--trainer.enable_progress_bar=false" if quick else "--trainer.enable_progress_bar=true",
        *(QUICK_OVERRIDES if quick else []),
    ]


def _train(
    model: DemoModel, root: Path, out: Path, steps: int, quick: bool, seed: int, init: Path | None, bf16: bool
) -> Path:
    """Fit ``model`` for ``steps`` steps with ``seed`` (in bfloat16 autocast if ``bf16``), from the weights of
    checkpoint ``init`` when given; returns its run folder (config.yaml, metrics.csv, checkpoints: ``last.ckpt``
    holds the final weights)."""
    val_every = max(1, steps // (2 if init else 4))  # stage 2: twice (a 4-frame validation costs ~10 s)
    name = f"{model.name}-s{seed}"
    args = [
        "fit",
        *_common(model, root, out, quick, bf16),
        *([f"--model.init_weights={init}"] if init else []),
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


def predict_split(name: str, run: Path, out: Path, split: str, max_overlays: int, root: Path | None = None) -> Path:
    """Predict ``split`` with the FINAL weights (``last.ckpt``) of run ``name`` (model and seed); returns the
    predictions folder ``<out>/predictions/<name>/<split>``.

    Args:
        name: the run's name (``stam4-s0``).
        run: its folder (``config.yaml``, ``checkpoints/last.ckpt``).
        out: where ``predictions/`` goes.
        split: the label file ``<split>.json`` of the data root.
        max_overlays: overlay pictures to write.
        root: another data root than the run's (e.g. a set generated with another seed).
    """
    pred_dir = out / "predictions" / name / split
    args = [
        "predict",
        "--config",
        str(run / "config.yaml"),
        f"--ckpt_path={run / 'checkpoints' / 'last.ckpt'}",
        *([f"--data.root={root}"] if root is not None else []),
        f"--data.predict_labels=[{split}.json]",
        "--trainer.logger=false",
        "--trainer.callbacks=[]",
        "--trainer.enable_progress_bar=false",
        f"--predictions.output_dir={pred_dir}",
        f"--predictions.max_overlays={max_overlays}",
    ]
    _cli(args)
    return pred_dir


def score_split(pred_dir: Path, labels: Path) -> tuple[dict, dict[str, np.ndarray], list[str]]:
    """Score ``pred_dir/predictions.json`` against ``labels`` as ``stamlane-eval tusimple --no-time-limit`` does,
    and with the CULane-style IoU F1 as ``stamlane-eval culane predictions.json labels.json --size WxH --width
    <iou_width>`` does (the official C++ variant, IoU 0.3 and 0.5); write ``pred_dir/per_image.jsonl``. Returns the
    numbers, the per-image quantities of every metric of `METRICS` in LABEL order and each image's clip (the
    bootstrap's unit)."""
    from stamlane_eval import culane
    from stamlane_eval.io import read_tusimple, tusimple_points
    from stamlane_eval.tusimple import MAX_RUN_TIME_MS, evaluate

    preds, gts = read_tusimple(pred_dir / "predictions.json"), read_tusimple(labels)
    result = evaluate(preds, gts, time_limit=False)
    by_name = {p["raw_file"]: (p, r) for p, r in zip(preds, result.per_image)}
    size = _image_size(labels.parent)
    width = iou_width(size)
    iou = culane.evaluate(
        [tusimple_points(by_name[gt["raw_file"]][0]["lanes"], gt["h_samples"]) for gt in gts],
        [tusimple_points(gt["lanes"], gt["h_samples"]) for gt in gts],
        IOU_THRESHOLDS,
        width,
        size,
    )
    rows = []
    for gt, counts in zip(gts, iou.per_image):
        r = by_name[gt["raw_file"]][1]
        row = {"raw_file": gt["raw_file"], "clip": _clip_of(gt["raw_file"]), **asdict(r)}
        row["iou"] = {f"{t:g}": list(counts.counts[t]) for t in IOU_THRESHOLDS}
        rows.append(row)
    _write_atomic(pred_dir / "per_image.jsonl", "".join(json.dumps(row) + "\n" for row in rows))
    scores = {k: result.as_dict()[k] for k in ("accuracy", "fp", "fn", "f1", "images")}
    scores["late"] = sum(p["run_time"] > MAX_RUN_TIME_MS for p in preds)
    scores["iou"] = {f"{t:g}": c.as_dict() for t, c in iou.totals.items()}
    scores["iou_width"] = width
    return scores, _quantities(rows), [row["clip"] for row in rows]


def _image_size(root: Path) -> tuple[int, int]:
    """(H, W) of a synthetic set's frames, from its ``dataset.json``."""
    info = root / "dataset.json"
    if not info.is_file():
        raise DemoError(f"{root}: no dataset.json (the demo scores synthetic sets, which have one)")
    config = json.loads(info.read_text())["config"]
    return int(config["height"]), int(config["width"])


def _quantities(rows: list[dict]) -> dict[str, np.ndarray]:
    """Per metric of `METRICS`, its per-image quantities from the rows of ``per_image.jsonl``, (N, k)."""
    return {m.key: np.array([m.columns(row) for row in rows], dtype=np.float64) for m in METRICS}


DONE = "done.json"
"""Written in a run's folder when it is trained and scored: a later ``stamlane demo`` with the same ``--out`` and
settings reuses it (more seeds, or a run that was killed midway continues where it stopped)."""
SCORING = "no-time-limit+iou"
"""How `score_split` scores (kept in ``done.json``): a run scored otherwise is scored again from its predictions
(``no-time-limit``: TuSimple F1 only, before the IoU F1 was added)."""


def _score_run(record: dict, name: str, out: Path, root: Path, max_overlays: int) -> None:
    """Predict and score every split of `SPLITS` that ``record`` has no scores of for the current label file
    (its SHA-256 is kept in ``record["labels"]``), then write the record as the run's ``done.json``. A split
    regenerated by a newer generator is thus predicted again with the same final weights; a split scored under
    other rules than `SCORING` is scored again from its predictions; the rest is reused."""
    labels = record.setdefault("labels", {})
    rescore = record.get("scoring") != SCORING
    changed = False
    for split in SPLITS:
        digest = hashlib.sha256((root / f"{split}.json").read_bytes()).hexdigest()
        predicted = labels.get(split) == digest and split in record
        if predicted and not rescore:
            continue
        if predicted:
            pred_dir = out / "predictions" / name / split
        else:
            if split in record:
                print(f"[demo] {name}: the {split} labels changed, scoring them again", flush=True)
            pred_dir = predict_split(name, Path(record["run"]), out, split, max_overlays, root=root)  # today's data
        record[split], _, _ = score_split(pred_dir, root / f"{split}.json")
        labels[split] = digest
        changed = True
    record["scoring"] = SCORING
    if changed or not (out / name / DONE).is_file():
        _write_atomic(out / name / DONE, json.dumps(record, indent=2))


def _finished(folder: Path, settings: dict) -> dict | None:
    """The record of a finished run in ``folder`` made with ``settings``, or None when it has not finished."""
    path = folder / DONE
    if not path.is_file():
        return None
    record = json.loads(path.read_text())
    if {k: record.get(k) for k in settings} != settings:
        raise DemoError(
            f"{folder} was made with other settings ({ {k: record.get(k) for k in settings} }); use another --out"
        )
    return record


def _read_quantities(pred_dir: Path) -> tuple[dict[str, np.ndarray], list[str]]:
    """Per metric, the per-image quantities, and the clips, of a scored split (its ``per_image.jsonl``, in label
    order)."""
    rows = [json.loads(line) for line in (pred_dir / "per_image.jsonl").read_text().splitlines()]
    return _quantities(rows), [r["clip"] for r in rows]


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


def _plot(curves: dict[str, list[tuple[int, float]]], labels: dict[str, str], path: Path, stage2: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for name, points in curves.items():
        if points:
            steps, f1 = zip(*points)
            ax.plot(steps, f1, marker="o", label=labels[name])
    ax.axvline(stage2, color="grey", linestyle=":", linewidth=1)
    ax.set_xlabel("training step (stage 2 right of the dotted line)")
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


View = tuple[str, str, np.ndarray]
"""A set of scored key frames: ``(name, split, row indices into the split's per-image results)``; the names are
the splits (`SPLITS`) and ``challenging:<factor>`` for each factor of the challenging split."""


def _views(root: Path, clips: dict[str, list[str]]) -> list[View]:
    """Every split whole, then each factor of the challenging split (from ``dataset.json``'s ``clip_factors``;
    none for a set without them)."""
    views = [(split, split, np.arange(len(clips[split]))) for split in SPLITS]
    info = root / "dataset.json"
    clip_factors = json.loads(info.read_text()).get("clip_factors", {}) if info.is_file() else {}
    of_row = [clip_factors.get(clip.rsplit("/", 1)[-1]) for clip in clips.get("challenging", [])]
    for factor in dict.fromkeys(f for f in of_row if f is not None):
        rows = np.array([i for i, f in enumerate(of_row) if f == factor])
        views.append((f"challenging:{factor}", "challenging", rows))
    return views


def _aggregate(
    metric: Metric, quantities: dict[str, list[np.ndarray]], clips: dict[str, list[str]], views: list[View]
) -> dict:
    """Per view, the ``metric``'s F1: mean and std over the seeds, and the 95 % interval (clips resampled) of the
    F1 of the seed-averaged per-image quantities. Splits go to ``[split]``, factors to ``["factors"][factor]``."""
    from stamlane_eval.stats import bootstrap

    found: dict[str, Any] = {}
    for name, split, rows in views:
        per_seed = [q[rows] for q in quantities[split]]
        f1 = np.array([metric.statistic(q.mean(axis=0)) for q in per_seed])
        groups = [clips[split][i] for i in rows]
        ci = None
        if len(set(groups)) >= 2:  # else no interval (a tiny set)
            est = bootstrap(np.mean(per_seed, axis=0), metric.statistic, groups=groups)
            ci = [est.low, est.high]
        view = {
            "f1_mean": float(f1.mean()),
            "f1_std": float(f1.std(ddof=1)) if len(f1) > 1 else None,
            "f1_ci95": ci,
            "seeds": len(f1),
            "images": len(rows),
        }
        if ":" in name:
            found.setdefault("factors", {})[name.split(":", 1)[1]] = view
        else:
            found[name] = view
    return found


PAIRS = (("stam4", "single"), ("stam4_noalign", "single"), ("stam4", "stam4_noalign"))
"""The demo's comparisons, A against B: what the history frames bring, with and without alignment."""


def _pairs(models: dict[str, str | None]) -> list[tuple[str, str]]:
    """The pairs (A, B) the demo compares, of ``models`` (name -> the paper row it is): every pair of `PAIRS`,
    each paper row asked for (``--rows``) against the single frame and against the pre-aligned STAM model (the
    paper's choice, against which Tables 2-4 set every other row), and every model of a table with a
    ``baseline`` (``configs/paper/tables.yaml``: Tables 2 and 8) against that baseline."""
    from stamlane.experiments.tables import load_tables

    own = {m.name for m in MODELS}
    pairs = [*PAIRS, *((name, other) for name in models if name not in own for other in ("single", "stam4"))]
    by_row = {row: name for name, row in models.items() if row}
    for table in load_tables(CONFIG_DIR / "paper" / "tables.yaml").tables.values():
        base = by_row.get(table.baseline)
        pairs += [(by_row[r.id], base) for r in table.rows if base and r.id in by_row and by_row[r.id] != base]
    return [(a, b) for a, b in dict.fromkeys(pairs) if a in models and b in models]


def _compare(
    metric: Metric, pairs: list[tuple[str, str]], quantities: dict[str, dict], clips: dict, views: list[View]
) -> list[dict]:
    """For each pair (A, B) (`_pairs`), per view: the ``metric``'s F1(A) - F1(B) of the seed-averaged per-image
    quantities on the same images with its paired bootstrap interval (clips resampled: ``ci95``), and the
    per-seed differences (A and B of one seed share stage 1) with their Student-t interval (``seed_diffs``,
    ``seed_ci95``: what training randomness does to the difference; None for one seed). IoU comparisons name
    their ``metric``."""
    from stamlane_eval.stats import paired_bootstrap, seed_interval

    f1 = metric.statistic
    found = []
    for a, b in pairs:
        for name, split, rows in views:
            groups = [clips[split][i] for i in rows]
            if len(set(groups)) < 2:  # no interval from a single clip
                continue
            per_seed_a = [q[rows] for q in quantities[a][split]]
            per_seed_b = [q[rows] for q in quantities[b][split]]
            est = paired_bootstrap(np.mean(per_seed_a, axis=0), np.mean(per_seed_b, axis=0), f1, groups=groups)
            diffs = [f1(qa.mean(axis=0)) - f1(qb.mean(axis=0)) for qa, qb in zip(per_seed_a, per_seed_b)]
            seeds = seed_interval(diffs) if len(diffs) > 1 else None
            found.append(
                {
                    "a": a,
                    "b": b,
                    "split": name,
                    **({} if metric is TUSIMPLE else {"metric": metric.key}),
                    "f1_diff": est.value,
                    "ci95": [est.low, est.high],
                    "seed_diffs": diffs,
                    "seed_ci95": [seeds.low, seeds.high] if seeds else None,
                }
            )
    return found


def _cell(value: float, ci: list[float] | None, signed: bool = False) -> str:
    """``value [low, high]`` in percent; ``*`` when a signed difference's interval excludes 0."""
    text = f"{100 * value:+.1f}" if signed else f"{100 * value:.1f}"
    return text if ci is None else f"{text} {_interval(ci, signed)}"


def _interval(ci: list[float], signed: bool = True) -> str:
    """``[low, high]`` in percent; signed: with signs, and ``*`` when it excludes 0."""
    if not signed:
        return f"[{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]"
    return f"[{100 * ci[0]:+.1f}, {100 * ci[1]:+.1f}]" + ("" if ci[0] <= 0 <= ci[1] else "*")


def _table(summary: dict) -> str:
    """The printed results: F1 (%) per model and split as mean [95 % CI] (± seed std), the differences, then
    F1 and the differences per factor of the challenging split."""
    head = f"{'model':<32} {'frames':>6} {'steps':>6} {'seeds':>5}"
    for split in SPLITS:
        head += f" | {split + ' F1 % [95% CI]':>30}"
    lines = [head, "-" * len(head)]
    for entry in summary["models"]:
        line = f"{entry['label']:<32} {entry['frames']:>6} {entry['steps']:>6} {len(entry['runs']):>5}"
        for split in SPLITS:
            m = entry[split]
            std = f" ±{100 * m['f1_std']:.1f}" if m["f1_std"] is not None else ""
            line += f" | {_cell(m['f1_mean'], m['f1_ci95']) + std:>30}"
        lines.append(line)
    splits = [c for c in summary["comparisons"] if ":" not in c["split"]]
    if splits:
        lines += [
            "",
            "paired differences of F1 (same images; 95 % CI with clips resampled, and over the training seeds;",
            "* = the interval excludes 0):",
        ]
        lines += [_difference_line(c) for c in splits]
    lines += _iou_table(summary)
    factors = list(summary["models"][0].get("factors", {})) if summary["models"] else []
    if factors:
        names = [m["name"] for m in summary["models"]]
        pairs = [(c["a"], c["b"]) for c in splits if c["split"] == SPLITS[0]]
        head = f"{'factor':<19}" + "".join(f" | {n:>19}" for n in names)
        head += "".join(f" | {a + ' - ' + b:>28}" for a, b in pairs)
        lines += ["", "challenging split per factor: F1 % [95% CI] and paired differences", head, "-" * len(head)]
        diffs = {(c["a"], c["b"], c["split"]): c for c in summary["comparisons"]}
        for factor in factors:
            line = f"{factor:<19}"
            for m in summary["models"]:
                f = m["factors"][factor]
                line += f" | {_cell(f['f1_mean'], f['f1_ci95']):>19}"
            for a, b in pairs:
                c = diffs.get((a, b, f"challenging:{factor}"))
                line += f" | {_cell(c['f1_diff'], c['ci95'], True) if c else 'n/a (one clip)':>28}"
            lines.append(line)
    return "\n".join(lines)


def _iou_table(summary: dict) -> list[str]:
    """The IoU F1 (%) per model at each threshold and split, mean [95 % CI], and its paired differences."""
    keys = [m.key for m in METRICS if m is not TUSIMPLE]
    head = f"{'IoU F1 % (CULane-style, ' + str(summary['iou_width']) + ' px lines)':<45}"
    head += "".join(f" | {split + ' @' + key.split('@')[1]:>22}" for key in keys for split in SPLITS)
    lines = ["", head, "-" * len(head)]
    for entry in summary["models"]:
        cells = [_cell(entry[key][split]["f1_mean"], entry[key][split]["f1_ci95"]) for key in keys for split in SPLITS]
        lines.append(f"{entry['label']:<45}" + "".join(f" | {cell:>22}" for cell in cells))
    return lines + [_difference_line(c) for c in summary["iou_comparisons"] if ":" not in c["split"]]


def _difference_line(c: dict) -> str:
    """One printed paired difference: A - B, its metric (IoU ones), split, ``+d [clips]`` and ``seeds [...]``."""
    metric = f"{c['metric']:<8} " if "metric" in c else ""
    seeds = f"   seeds {_interval(c['seed_ci95'])}" if c.get("seed_ci95") else ""
    return f"  {c['a']:>13} - {c['b']:<13} {metric}{c['split']:<12} {_cell(c['f1_diff'], c['ci95'], True)}{seeds}"


def run(args: argparse.Namespace) -> dict:
    """Run the demo (see the module docstring); returns the summary written to ``summary.json``."""
    _require_pieces()
    import torch

    from stamlane.hardware import resolve_bf16

    torch.set_num_threads(1 if args.quick else max(1, os.cpu_count() or 1))
    skip_noalign = args.no_noalign or args.quick  # the quick run checks the machinery, not the ablation
    models = [m for m in MODELS if not (skip_noalign and m.name == "stam4_noalign")]
    have = {m.name for m in models} | {m.paper for m in models}
    models += [DemoModel.paper_row(row) for row in dict.fromkeys(args.rows) if row not in have]
    out = args.out
    if out.exists() and not out.is_dir():
        raise DemoError(f"--out {out} is a file, not a folder")
    out.mkdir(parents=True, exist_ok=True)
    root = _make_data(args.data, out, args.quick)
    pre_steps, ft_steps = (3, 2) if args.quick else (args.pretrain_steps, args.finetune_steps)
    quick_fp32 = args.quick and args.bf16 == "auto"  # the smoke run in float32 unless asked otherwise
    bf16 = False if quick_fp32 else resolve_bf16({"true": True, "false": False}.get(args.bf16, args.bf16))
    seeds = list(range(args.seeds))
    summary: dict[str, Any] = {
        "data": str(root),
        "seeds": seeds,
        "pretrain_steps": pre_steps,
        "finetune_steps": ft_steps,
        "steps": pre_steps + ft_steps,
        "bf16": bf16,
        "models": [],
    }
    curves: dict[str, list[tuple[int, float]]] = {}
    curve_labels: dict[str, str] = {}
    # per metric, model and split: the per-image quantities of every seed
    quantities = {metric.key: {m.name: {split: [] for split in SPLITS} for m in models} for metric in METRICS}
    clips: dict[str, list[str]] = {}
    entries = {
        m.name: {
            "name": m.name,
            "label": m.label,
            "paper_row": m.paper,
            "configs": [f"configs/{c}" for c in m.configs()],
            "runs": [],
        }
        for m in models
    }
    start_all = time.perf_counter()
    settings = {"data": str(root.resolve()), "pretrain_steps": pre_steps, "finetune_steps": ft_steps, "bf16": bf16}
    for seed in seeds:
        base_dir = out / f"pretrain-s{seed}"
        done = _finished(base_dir, settings)
        if done is None:
            print(f"[demo] seed {seed}, stage 1: {PRETRAIN.label}, {pre_steps} steps", flush=True)
            start = time.perf_counter()
            _train(PRETRAIN, root, out, pre_steps, args.quick, seed, init=None, bf16=bf16)
            done = settings | {"train_minutes": round((time.perf_counter() - start) / 60, 2)}
            _write_atomic(base_dir / DONE, json.dumps(done, indent=2))
        else:
            print(f"[demo] seed {seed}, stage 1: done before, reused ({base_dir})", flush=True)
        base = base_dir / "run"
        init = base / "checkpoints" / "last.ckpt"
        curves[f"pretrain-s{seed}"] = _val_curve(base)
        curve_labels[f"pretrain-s{seed}"] = f"stage 1 (1 frame), seed {seed}"
        for model in models:
            name = f"{model.name}-s{seed}"
            record = _finished(out / name, settings)
            if record is None:
                print(f"[demo] seed {seed}, stage 2: {model.label}, {ft_steps} steps", flush=True)
                start = time.perf_counter()
                run_dir = _train(model, root, out, ft_steps, args.quick, seed, init=init, bf16=bf16)
                record = settings | {
                    "seed": seed,
                    "train_minutes": round(done["train_minutes"] + (time.perf_counter() - start) / 60, 2),
                    "run": str(run_dir),
                    "last_ckpt": str(run_dir / "checkpoints" / "last.ckpt"),
                }
                config = (run_dir / "config.yaml").read_text()
                record["frames"] = int(next(ln.split(":")[1] for ln in config.splitlines() if "num_frames:" in ln))
                _score_run(record, name, out, root, args.max_overlays)
            else:
                print(f"[demo] seed {seed}, stage 2: {model.label}: done before, reused", flush=True)
                _score_run(record, name, out, root, args.max_overlays)  # splits whose labels changed
            for split in SPLITS:
                per_image, clips[split] = _read_quantities(out / "predictions" / name / split)
                for key, values in per_image.items():
                    quantities[key][model.name][split].append(values)
            entries[model.name]["frames"] = record["frames"]
            entries[model.name]["runs"].append({k: v for k, v in record.items() if k not in settings})
            curves[name] = [(pre_steps + step, f1) for step, f1 in _val_curve(Path(record["run"]))]
            curve_labels[name] = f"{model.label}, seed {seed}"
            _write_atomic(out / "summary.json", json.dumps(summary | {"partial": entries}, indent=2))
    views = _views(root, clips)
    for model in models:
        entry = entries[model.name]
        entry["steps"] = pre_steps + ft_steps
        for metric in METRICS:
            found = _aggregate(metric, quantities[metric.key][model.name], clips, views)
            if metric is TUSIMPLE:  # where the summary always kept it
                entry.update(found)
            else:
                entry[metric.key] = found
        summary["models"].append(entry)
    pairs = _pairs({m.name: m.paper for m in models})
    compared = {metric.key: _compare(metric, pairs, quantities[metric.key], clips, views) for metric in METRICS}
    summary["comparisons"] = compared.pop(TUSIMPLE.key)
    summary["iou_comparisons"] = [c for found in compared.values() for c in found]
    summary["iou_width"] = iou_width(_image_size(root))
    summary["minutes"] = round((time.perf_counter() - start_all) / 60, 2)
    _plot(curves, curve_labels, out / "val_f1.png", pre_steps)
    summary["val_f1_plot"] = str(out / "val_f1.png")
    comparison = _comparison(out, [f"{m.name}-s0" for m in models], [m.label for m in models])
    summary["comparison"] = str(comparison) if comparison else None
    _write_atomic(out / "summary.json", json.dumps(summary, indent=2))
    print(_table(summary))
    print(
        f"[demo] wrote {out / 'summary.json'}, {out / 'val_f1.png'}, predictions, per-image results and overlays "
        f"under {out / 'predictions'}; final weights of each model: {out}/<model>-s<seed>/run/checkpoints/last.ckpt"
    )
    return summary


def main(argv: list[str] | None = None) -> int:
    args = parse_or_status(_parser(), argv)
    if isinstance(args, int):
        return args
    for option in ("seeds", "pretrain_steps", "finetune_steps"):
        if getattr(args, option) < 1:
            flag = "--" + option.replace("_", "-")
            print(f"stamlane demo: {flag} must be >= 1, got {getattr(args, option)}", file=sys.stderr)
            return 2
    try:
        run(args)
    except DemoError as err:
        print(f"stamlane demo: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
