"""The experiment engine: train rows x seeds with a named recipe, predict, score, probe the history, summarise.

``stamlane demo`` (three fixed rows and pictures) and ``stamlane ablate`` (the paper's tables) are this engine
with other rows. For every seed, a recipe's optional stage 1 (the single-frame network from scratch, whose final
weights start every row) and then every row are trained through ``stamlane fit`` in this process; each run's
FINAL weights predict the scored splits (``stamlane predict``), which are scored (`stamlane.experiments.scoring`);
a multi-frame run is scored twice more with its history probed (``data.history_source``: the key frame copied
into every history slot, and another clip's history), which measures whether it reads its history at all.
Where the set has paint-visibility masks, two oracles fitted to the labels (`stamlane.experiments.history`) give
each view's headroom: what perfect use of the history could add.

Runs finish with ``done.json`` (`stamlane.experiments.store`): a later call with the same ``out`` and settings
reuses them (more seeds, or a run killed midway), predicts and scores again only a split whose labels changed or
that was scored under older rules, and refuses other settings.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from stamlane.configs import configs_dir
from stamlane.experiments.scoring import (
    SCORING,
    image_size,
    iou_width,
    read_per_clip,
    read_per_image,
    score_split,
    score_temporal,
)
from stamlane.experiments.stats import Scores, views
from stamlane.experiments.store import StoreError, finished, mark_finished, write_atomic
from stamlane.experiments.summary import ModelEntry, RunEntry, Summary
from stamlane.training.quiet import quiet_libraries

__all__ = [
    "ALL_PROBES",
    "CONFIG_DIR",
    "PROBES",
    "QUICK_OVERRIDES",
    "RECIPES",
    "REVEAL_PROBES",
    "REVEAL_SPLITS",
    "SAME_AS_KEY",
    "SPANS",
    "Experiment",
    "ExperimentError",
    "Recipe",
    "Row",
    "oracle_subject",
]

CONFIG_DIR = configs_dir()
PROBES = ("key",)
"""History probes of every multi-frame run on the `Experiment.splits` (`stamlane.data.clips.HISTORY_SOURCES` other
than ``real``): the key frame copied into every history slot."""
ALL_PROBES = ("key", "other_clip")
"""`PROBES` with ``other_clip`` (another clip's history) on the `Experiment.splits` too (``all_probes``): whether a
model leans on its history at all, on splits where the history shows little (the reveal splits always have it)."""
REVEAL_SPLITS = ("reveal", "reveal-traffic")
"""The splits where the history reveals lanes (`stamlane.synth.generator.REVEAL`), scored where the set has them."""
REVEAL_PROBES = ("key", "warped_key", "reversed", "other_clip", "exact")
"""The probes of a multi-frame run on `REVEAL_SPLITS`: `PROBES`, the matched null (the key frame warped out and back
through each history frame's homography), the history in reverse order, and ``exact``: the real history aligned
by the generator's exact homographies instead of ORB (runs that align on the fly only)."""
SAME_AS_KEY = ("warped_key",)
"""Probes whose input equals ``key``'s for a run that does not align: scored as ``key`` without predicting."""
SPANS = ((2, 1), (4, 1), (8, 1), (2, 2), (4, 2), (8, 2))
"""The spans (frames, stride) whose oracle headroom is measured on every split with visibility masks, within the
reach of its masks (``dataset.json``'s ``visibility_reach``)."""
QUICK_OVERRIDES = (
    "--data.clip.image_size=[64, 128]",
    "--model.encoder.width=0.125",
    "--model.channels_last=false",
    "--data.loader.batch_size=2",
    "--data.loader.num_workers=0",
)
"""A seconds-long smoke run (``--quick``): a tiny network on small images; its numbers mean nothing."""


class ExperimentError(Exception):
    """A known failure of an experiment (bad rows, a used ``--out``, a broken run folder): one line, exit 2."""


@dataclass(frozen=True)
class Row:
    """A model of an experiment: a name (its folders), a label (its tables), its ``stamlane fit`` configs
    (relative to ``configs/``, in order), the paper row it is (``configs/paper/tables.yaml``), if any, and whether
    the recipe's ``row_args`` (the key-frame corruption of the CPU recipe) apply to it."""

    name: str
    label: str
    configs: tuple[str, ...]
    paper: str | None = None
    recipe_args: bool = True

    @classmethod
    def paper_row(cls, row: str, base: str = "demo.yaml") -> Row:
        """A row of the paper's tables on ``base`` (``base``, ``paper/ablation.yaml``, ``paper/rows/<row>.yaml``)."""
        if not (CONFIG_DIR / "paper" / "rows" / f"{row}.yaml").is_file():
            known = sorted(p.stem for p in (CONFIG_DIR / "paper" / "rows").glob("*.yaml"))
            raise ExperimentError(f"no paper row {row!r}; known rows: {' '.join(known)}")
        return cls(row, f"paper row {row}", (base, "paper/ablation.yaml", f"paper/rows/{row}.yaml"), paper=row)


@dataclass(frozen=True)
class Recipe:
    """How every row is trained.

    Attributes:
        name: ``"cpu"`` (two stages) or ``"paper"`` (one stage).
        steps: steps of each row (stage 2 of the two-stage recipe).
        pretrain_steps: steps of stage 1, the single-frame network from scratch whose final weights start every
            row (0: one stage, every row from scratch).
        pretrain: the stage-1 model.
        row_args: ``stamlane fit`` arguments of every row's training (not of stage 1), after its configs.
        val_checks: validations per run (for the curves; stage 2 validates half as often as stage 1).
        val_batches: validation batches each validation scores (None: the whole split). The validations only draw
            the curves (every score is of the final weights, on the test splits); how many batches they read
            leaves the final weights bit for bit the same (tests/experiments/test_engine_speed.py).
    """

    name: str
    steps: int
    pretrain_steps: int = 0
    pretrain: Row | None = None
    row_args: tuple[str, ...] = ()
    val_checks: int = 4
    val_batches: int | None = None

    def settings(self) -> dict[str, Any]:
        return {
            "recipe": self.name,
            "pretrain_steps": self.pretrain_steps,
            "steps": self.steps,
            "row_args": list(self.row_args),
        }


PRETRAIN = Row("pretrain", "1 frame, stage 1 (every model starts here)", ("demo_single.yaml",))
KEY_CORRUPTION = ("--data.augment.key_corruption=0.5", "--data.augment.key_corruption_kinds=[blank, glare]")
"""Stage 2 of the CPU recipe: half the training clips have their key frame's near road blanked or the frame
overexposed, history intact (`stamlane.data.corruption`): the reason to read the history (docs/training.md)."""
RECIPES = {
    "cpu": Recipe("cpu", steps=300, pretrain_steps=1200, pretrain=PRETRAIN, row_args=KEY_CORRUPTION, val_batches=25),
    "paper": Recipe("paper", steps=1500),
}
"""The named recipes (docs/training.md): ``cpu``, the demo's two stages (1,200 single-frame steps from scratch,
then each row for 300 steps from those weights with the key frame corrupted in half the clips: every model gets
1,500 steps on the same data; the validations of the curves on 25 batches, 100 clips); ``paper``, every row from
scratch for 1,500 steps (the paper's protocol at a CPU budget). Steps can be changed per call."""


def _cli(args: list[str], **kwargs: Any) -> Any:
    from stamlane.training.lightning_cli import StamLaneCLI

    argv, sys.argv = sys.argv, sys.argv[:1]  # LightningCLI warns when given args beside the command's own argv
    try:
        return StamLaneCLI(args=args, report=False, **kwargs)
    finally:
        sys.argv = argv


def _run_config(run: Path) -> str:
    """The text of a run folder's ``config.yaml``, read only inside the folder (links resolved)."""
    from stamlane.safety.budget import MAX_RECORD_BYTES
    from stamlane.safety.guard import GuardError, read_inside

    path = run / "config.yaml"
    try:
        return read_inside(path, run, MAX_RECORD_BYTES, "run config")
    except GuardError as err:
        raise ExperimentError(f"{err}; delete the run folder") from None


def _check_run_config(run: Path) -> None:
    """A run folder's ``config.yaml`` is data, not the user's code: checked against the closed registry
    (`stamlane.training.registry.check_run_config`); a tampered one is refused in one line."""
    from stamlane.safety.checkpoints import CheckpointError
    from stamlane.training.registry import check_run_config

    try:
        check_run_config(_run_config(run), run / "config.yaml")
    except CheckpointError as err:
        raise ExperimentError(str(err)) from None


def _run_data(run: Path, section: str) -> dict[str, Any]:
    """A section of a run folder's config (``data``, ``model``) as a mapping."""
    path = run / "config.yaml"
    try:
        config = yaml.safe_load(_run_config(run))
    except yaml.YAMLError as err:
        raise ExperimentError(f"{path}: not YAML ({_one_line(err)}); delete the run folder") from None
    value = config.get(section) if isinstance(config, dict) else None
    if not isinstance(value, dict):
        raise ExperimentError(f"{path}: its {section!r} section is not a mapping; delete the run folder")
    return value


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split())


def _frames_of(run: Path) -> int:
    from stamlane.training.compat import clip_options  # a run of before the data options were grouped too

    try:
        return clip_options(_run_data(run, "data")).num_frames
    except ValueError as err:
        raise ExperimentError(f"{run / 'config.yaml'}: {err}") from None


def _verify_checkpoint(record: dict[str, Any], folder: Path) -> None:
    """A finished run whose record holds no digest of its checkpoint (an older record, or one edited): the
    checkpoint must load whole before it is reused (a truncated file is refused, not reused as finished)."""
    from stamlane.safety.checkpoints import CheckpointError, read_checkpoint

    if record.get("last_ckpt") and not record.get("last_ckpt_sha256"):
        try:
            state = read_checkpoint(record["last_ckpt"])
        except CheckpointError as err:
            raise ExperimentError(f"{folder}: {err}; delete the folder to run it again") from None
        if not isinstance(state.get("state_dict"), dict) or not state["state_dict"]:
            raise ExperimentError(f"{folder}: its checkpoint holds no weights; delete the folder to run it again")


def _grouped_args(record: dict[str, Any]) -> dict[str, Any]:
    """A run record with the ``stamlane fit`` arguments it was made with (``row_args``, ``extra``) in today's
    names: a run recorded with ``--data.key_corruption`` before the data options were grouped is the same run as
    one with ``--data.augment.key_corruption``."""
    from stamlane.training.compat import upgrade_flags as group_flags

    return record | {k: group_flags(record[k]) for k in ("row_args", "extra") if isinstance(record.get(k), list)}


def _postprocess_of(run: Path) -> dict[str, Any]:
    return dict(_run_data(run, "model").get("postprocess") or {})


@dataclass
class Experiment:
    """Rows x seeds on one synthetic set (see the module docstring).

    Attributes:
        rows: the models.
        recipe: how they are trained.
        seeds: training seeds.
        root: the data root (a synthetic set: ``dataset.json``, ``test.json``, ``challenging.json``).
        out: the experiment's folder.
        bf16: bfloat16 autocast in every run.
        splits: the label files scored.
        probes: score multi-frame runs with their history probed too.
        all_probes: `ALL_PROBES` instead of `PROBES` on ``splits`` (another clip's history too: a third prediction of
            every clean and challenging key frame).
        temporal: predict the frames of `stamlane.synth.generator.TEMPORAL_LABELS` one after the other (each
            with its own history) and score their temporal stability, where the set has that file.
        extra: further ``stamlane fit`` arguments of every run, after the row's base config and before its row
            config.
        quick: the smoke settings (`QUICK_OVERRIDES`), without progress bars.
        max_overlays: overlay pictures per run and split.
        log: where the one-line progress messages go.
    """

    rows: list[Row]
    recipe: Recipe
    seeds: list[int]
    root: Path
    out: Path
    bf16: bool = False
    splits: tuple[str, ...] = ("test", "challenging")
    probes: bool = True
    all_probes: bool = False
    temporal: bool = True
    extra: tuple[str, ...] = ()
    quick: bool = False
    max_overlays: int = 12
    log: Callable[[str], None] = field(default=lambda line: print(f"[stamlane] {line}", flush=True))
    _start: float = field(default_factory=time.perf_counter, init=False, repr=False)

    def _say(self, line: str) -> None:
        """A progress line, with the minutes since the experiment began (where the time goes, on every machine)."""
        self.log(f"{(time.perf_counter() - self._start) / 60:5.1f} min  {line}")

    # ------------------------------------------------------------------ settings and folders
    def settings(self) -> dict[str, Any]:
        """What every run of ``out`` must share."""
        return {
            "data": str(self.root.resolve()),
            **self.recipe.settings(),
            "bf16": self.bf16,
            "extra": list(self.extra),
        }

    def run_name(self, row: Row, seed: int) -> str:
        return f"{row.name}-s{seed}"

    def pred_dir(self, name: str, split: str, source: str = "real") -> Path:
        return self.out / "predictions" / name / (split if source == "real" else f"{split}@{source}")

    def scored_splits(self) -> tuple[str, ...]:
        """``splits``, and the `REVEAL_SPLITS` the set has (a label file with key frames)."""
        files = [self.root / f"{s}.json" for s in REVEAL_SPLITS if s not in self.splits]
        extra = [f.stem for f in files if f.is_file() and f.stat().st_size > 0]
        return (*self.splits, *extra)

    def probes_of(self, split: str, record: dict[str, Any]) -> tuple[str, ...]:
        """The history probes of a run on ``split``: none for a single frame; `REVEAL_PROBES` on the reveal splits,
        `PROBES` (`ALL_PROBES` with ``all_probes``) elsewhere. A run that does not align predicts neither ``exact``
        (there is no alignment to make exact) nor ``warped_key``: without alignment the key frame warped out comes
        back unwarped, the very input of ``key`` (`stamlane.data.clips.warped_key`), so its scores are ``key``'s
        (`SAME_AS_KEY`)."""
        if not self.probes or record["frames"] < 2:
            return ()
        if split not in REVEAL_SPLITS:
            return ALL_PROBES if self.all_probes else PROBES
        if _aligns(record):
            return REVEAL_PROBES
        return tuple(p for p in REVEAL_PROBES if p != "exact")

    def predicted_as(self, record: dict[str, Any], source: str) -> str:
        """The history source whose predictions stand for ``source``: ``key`` for `SAME_AS_KEY` on a run that does
        not align (the same input: predicted once), else ``source``."""
        return "key" if source in SAME_AS_KEY and not _aligns(record) else source

    # ------------------------------------------------------------------ training and prediction
    def _common(self, row: Row) -> list[str]:
        configs = [str(CONFIG_DIR / c) for c in row.configs]
        args = ["--config", configs[0], *self.extra]  # extra acts as part of the base: a row's own settings hold
        for config in configs[1:]:
            args += ["--config", config]
        return [
            *args,
            f"--data.root={self.root}",
            f"--model.bf16={str(self.bf16).lower()}",
            f"--trainer.enable_progress_bar={str(not self.quick).lower()}",
            "--trainer.enable_model_summary=false",
            *(QUICK_OVERRIDES if self.quick else ()),
        ]

    def _fit(self, row: Row, steps: int, seed: int, init: Path | None) -> Path:
        """Train ``row`` for ``steps`` steps with ``seed`` from the weights of ``init`` (or from scratch); returns the
        run folder (``config.yaml``, ``metrics.csv``, ``checkpoints/last.ckpt``: the final weights)."""
        checks = self.recipe.val_checks // (2 if init else 1)
        val_every = max(1, steps // max(checks, 1))
        name = self.run_name(row, seed)
        last = self.out / name / "run" / "checkpoints" / "last.ckpt"  # a run killed midway goes on from there
        row_args = self.recipe.row_args if row is not self.recipe.pretrain and row.recipe_args else ()
        from stamlane.safety.checkpoints import CheckpointError

        try:
            cli = _cli(
                [
                    "fit",
                    *([f"--ckpt_path={last}"] if last.is_file() else []),
                    *self._common(row),
                    *row_args,
                    *([f"--model.init_weights={init}"] if init else []),
                    f"--seed_everything={seed}",
                    f"--trainer.max_steps={steps}",
                    f"--trainer.val_check_interval={val_every}",
                    *([f"--trainer.limit_val_batches={self.recipe.val_batches}"] if self.recipe.val_batches else []),
                    f"--trainer.log_every_n_steps={max(1, min(25, val_every))}",
                    f"--trainer.default_root_dir={self.out / name}",
                    f"--trainer.logger.save_dir={self.out}",
                    f"--trainer.logger.name={name}",
                    "--trainer.logger.version=run",
                ]
            )
        except CheckpointError as err:  # a tampered checkpoint to resume from or to start from: one line
            raise ExperimentError(f"{self.out / name}: {err}") from None
        return Path(cli.trainer.logger.log_dir)

    def predict(self, name: str, run: Path, split: str, source: str = "real") -> Path:
        """Predict ``split`` with the final weights of ``run``, its history as ``source`` asks; returns the
        predictions folder."""
        from jsonargparse import ArgumentError

        from stamlane.safety.boundary import one_line
        from stamlane.training.registry import safe_config_file

        pred_dir = self.pred_dir(name, split, source)
        try:  # the run's config is data: a checked copy is what LightningCLI reads
            with safe_config_file(_run_config(run), run / "config.yaml") as config:
                _cli(
                    [
                        "predict",
                        "--config",
                        str(config),
                        f"--ckpt_path={run / 'checkpoints' / 'last.ckpt'}",
                        f"--data.root={self.root}",
                        f"--data.predict_labels=[{split}.json]",
                        f"--data.history_source={'real' if source == 'exact' else source}",
                        *(["--data.clip.align=true"] if source == "exact" else []),
                        "--trainer.logger=false",
                        "--trainer.callbacks=[]",
                        "--trainer.enable_progress_bar=false",
                        "--predictions.verbose=false",
                        f"--predictions.output_dir={pred_dir}",
                        f"--predictions.max_overlays={self.max_overlays if source == 'real' else 0}",
                    ],
                    parser_kwargs={"exit_on_error": False},
                )
        except (ValueError, ArgumentError) as err:  # a tampered run folder or checkpoint: one line
            raise ExperimentError(f"{run}: {one_line(err)}") from None
        return pred_dir

    def _trained(self, row: Row, seed: int, steps: int, init: Path | None, label: str) -> dict[str, Any]:
        """The finished record of a run, training it first when there is none."""
        name = self.run_name(row, seed)
        try:
            record = finished(self.out / name, self.settings(), self.out, upgrade=_grouped_args)
        except StoreError as err:
            raise ExperimentError(str(err)) from None
        if record is not None:
            _check_run_config(Path(record["run"]))
            _verify_checkpoint(record, self.out / name)
            if record.get("recipe_args", True) != row.recipe_args:
                raise ExperimentError(f"{self.out / name} was trained with other recipe arguments; use another --out")
            self._say(f"seed {seed}, {label}: {row.label}, done before, reused")
            return record
        self._say(f"seed {seed}, {label}: {row.label}, {steps} steps")
        start = time.perf_counter()
        run = self._fit(row, steps, seed, init)
        record = self.settings() | {
            "seed": seed,
            "train_minutes": round((time.perf_counter() - start) / 60, 2),
            "run": str(run),
            "last_ckpt": str(run / "checkpoints" / "last.ckpt"),
            "frames": _frames_of(run),
            "hardware": _hardware(),
            "recipe_args": row.recipe_args,
        }
        mark_finished(self.out / name, record)
        return record

    def _score(self, name: str, record: dict[str, Any]) -> None:
        """Predict and score every split (and its probes) that ``record`` has no current scores of; record them."""
        labels = record.setdefault("labels", {})
        scores = record.setdefault("scores", {})
        rescore = record.get("scoring") != SCORING
        changed = False
        for split in self.scored_splits():
            digest = _sha256(self.root / f"{split}.json")
            for source in ("real", *self.probes_of(split, record)):
                key = split if source == "real" else f"{split}@{source}"
                current = labels.get(split) == digest and key in scores
                if current and not rescore:
                    continue
                pred_dir = self.pred_dir(name, split, self.predicted_as(record, source))
                if self.predicted_as(record, source) != source:  # scored under its own name, predicted once
                    scores[key] = scores[f"{split}@key"]
                    changed = True
                    continue
                if not current or not (pred_dir / "predictions.json").is_file():
                    if key in scores:
                        self._say(f"{name}: the {split} labels changed, predicting them again")
                    self._say(f"{name}: predicting {key}")
                    self.predict(name, Path(record["run"]), split, source)
                scores[key] = score_split(pred_dir, self.root, split, record["frames"])
                changed = True
            labels[split] = digest
        frames = self.temporal_split()
        if frames is not None:  # the key-copied probe too: does the history itself make the lanes steadier?
            digest = _sha256(self.root / f"{frames}.json")
            for source in (
                ("real", "key") if self.probes and record["frames"] > 1 else ("real",)
            ):  # another clip's history is one clip's for every frame: not a probe of time
                key = frames if source == "real" else f"{frames}@{source}"
                if labels.get(frames) == digest and key in scores:
                    continue
                pred_dir = self.pred_dir(name, frames, source)
                if labels.get(frames) != digest or not (pred_dir / "predictions.json").is_file():
                    self._say(f"{name}: predicting {key} frame after frame")
                    self.predict(name, Path(record["run"]), frames, source)
                scores[key] = score_temporal(pred_dir, self.root, frames)
                changed = True
            labels[frames] = digest
        if changed:
            record["scoring"] = SCORING
            mark_finished(self.out / name, record)

    def temporal_split(self) -> str | None:
        """The label file (stem) of frame-after-frame predictions, where the set has one and it is wanted."""
        from stamlane.synth.layout import TEMPORAL_LABELS

        stem = TEMPORAL_LABELS.removesuffix(".json")
        return stem if self.temporal and (self.root / TEMPORAL_LABELS).is_file() else None

    # ------------------------------------------------------------------ oracles
    def _oracles(self, scores: Scores, frames: list[int], postprocess: dict[str, Any]) -> list[str]:
        """Score the oracles (`stamlane.experiments.history.oracle_predictions`) on every split with visibility
        masks: the key-frame oracle; the aligned and the unaligned history oracles of each clip length in
        ``frames``; the aligned history oracle of every span of `SPANS` within the masks' reach. Returns the oracle
        subjects (`oracle_subject`)."""
        from stamlane_eval.io import read_tusimple

        from stamlane.experiments.history import oracle_predictions, read_visibility
        from stamlane.predict.postprocess import PostprocessConfig
        from stamlane.synth.layout import FIRST_KEY

        config = PostprocessConfig(**postprocess)
        reach = _visibility_reach(self.root)
        subjects: list[str] = []
        for split in self.scored_splits():
            visibility = read_visibility(self.root, split)
            if visibility is None:
                continue
            gts = read_tusimple(self.root / f"{split}.json")
            spans = [(t, 1) for t in frames] + [
                sp for sp in SPANS if (sp[0] - 1) * sp[1] <= reach.get(split, FIRST_KEY)
            ]
            for t, stride in dict.fromkeys(spans):
                unaligned = self.root if t in frames and stride == 1 else None
                found = oracle_predictions(gts, visibility, t, config, image_size(self.root), stride, unaligned)
                for kind, records in found.items():
                    subject = oracle_subject(kind, t, stride)
                    if subject in subjects and split in scores.quantities.get(subject, {}):
                        continue  # the key-frame oracle is the same for every span
                    pred_dir = self.out / "predictions" / subject.replace(":", "-") / split
                    write_atomic(pred_dir / "predictions.json", "".join(json.dumps(r) + "\n" for r in records))
                    score_split(pred_dir, self.root, split, t)
                    per_image, clips = read_per_image(pred_dir)
                    scores.add(subject, split, 0, per_image, clips)
                    subjects.append(subject)
        return list(dict.fromkeys(subjects))

    # ------------------------------------------------------------------ the whole experiment
    def run(self, pairs: list[tuple[str, str]]) -> Summary:
        """Train, predict, score and summarise every row and seed.

        Args:
            pairs: the models compared, ``(a, b)`` names of rows (a - b on the same key frames).

        Returns:
            the summary, also written to ``<out>/summary.json``.
        """
        if self.out.exists() and not self.out.is_dir():
            raise ExperimentError(f"--out {self.out} is a file, not a folder")
        names = [r.name for r in self.rows]
        if len(set(names)) != len(names):
            raise ExperimentError(f"two rows share a name: {names}")
        self.out.mkdir(parents=True, exist_ok=True)
        quiet_libraries()
        start = self._start = time.perf_counter()
        scores = Scores()
        records: dict[str, list[dict[str, Any]]] = {r.name: [] for r in self.rows}
        steps = self.recipe.steps + self.recipe.pretrain_steps
        for seed in self.seeds:
            init = None
            if self.recipe.pretrain is not None:
                base = self._trained(self.recipe.pretrain, seed, self.recipe.pretrain_steps, None, "stage 1")
                init = Path(base["last_ckpt"])
            for row in self.rows:
                stage = "stage 2" if init else "training"
                record = self._trained(row, seed, self.recipe.steps, init, stage)
                if init is not None:
                    record.setdefault("pretrain_minutes", base["train_minutes"])
                name = self.run_name(row, seed)
                self._score(name, record)
                for key in record["scores"]:
                    split, _, source = key.partition("@")
                    pred_dir = self.pred_dir(name, split, self.predicted_as(record, source or "real"))
                    read = read_per_clip if split == self.temporal_split() else read_per_image
                    per_image, clips = read(pred_dir)
                    scores.add(row.name + (f"@{source}" if source else ""), split, seed, per_image, clips)
                records[row.name].append(record)
        self._say("scoring the oracles of the labels")
        all_views = views(self.root, scores.clips)
        multi = [r.name for r in self.rows if records[r.name] and records[r.name][0]["frames"] > 1]
        frames = sorted({records[n][0]["frames"] for n in multi})
        oracles = self._oracles(scores, frames, _postprocess_of(Path(records[self.rows[0].name][0]["run"])))
        differences = scores.differences("models", pairs, all_views)
        for name in multi:
            for probe in REVEAL_PROBES:  # real minus probe; exact alignment minus ORB's: exact - real
                pair = (f"{name}@exact", name) if probe == "exact" else (name, f"{name}@{probe}")
                differences += scores.differences(f"history_{probe.replace('other_clip', 'other')}", [pair], all_views)
            singles = [r.name for r in self.rows if r.name not in multi and records[r.name]]
            # the same weights without their history against a single frame trained alike: what the training did
            differences += scores.differences("key_copied", [(f"{name}@key", one) for one in singles], all_views)
        for subject in oracles:
            if subject.startswith("oracle:history-"):
                differences += scores.differences("headroom", [(subject, "oracle:key")], all_views)
            if subject.startswith("oracle:unaligned-"):
                aligned = subject.replace("unaligned", "history")
                differences += scores.differences("alignment_oracle", [(aligned, subject)], all_views)
        models = []
        for row in self.rows:
            runs = records[row.name]
            probes = {s: scores.values(f"{row.name}@{s}", all_views) for s in REVEAL_PROBES if row.name in multi}
            models.append(
                ModelEntry(
                    row.name,
                    row.label,
                    row.paper,
                    [f"configs/{c}" for c in row.configs],
                    runs[0]["frames"],
                    steps,
                    [_run_entry(r) for r in runs],
                    scores.values(row.name, all_views),
                    {s: v for s, v in probes.items() if v},
                )
            )
        summary = Summary(
            data=str(self.root),
            splits_sha256={
                split: _sha256(self.root / f"{split}.json")
                for split in (*self.scored_splits(), *filter(None, [self.temporal_split()]))
            },
            seeds=list(self.seeds),
            recipe={
                "name": self.recipe.name,
                "pretrain_steps": self.recipe.pretrain_steps,
                "steps": self.recipe.steps,
                "row_args": list(self.recipe.row_args),
            },
            bf16=self.bf16,
            iou_width=iou_width(image_size(self.root)),
            models=models,
            oracles={o: scores.values(o, all_views) for o in oracles},
            differences=differences,
            minutes=round((time.perf_counter() - start) / 60, 2),
        )
        summary.write(self.out / "summary.json")
        return summary


def oracle_subject(kind: str, frames: int, stride: int = 1) -> str:
    """The subject name of an oracle (`stamlane.experiments.history.ORACLES`) of a span: ``oracle:key``,
    ``oracle:history-4f``, ``oracle:unaligned-4f``, ``oracle:history-8f-x2`` (8 frames, every 2nd)."""
    if kind == "key":
        return "oracle:key"
    return f"oracle:{kind}-{frames}f" + (f"-x{stride}" if stride > 1 else "")


def _visibility_reach(root: Path) -> dict[str, int]:
    """History frames the visibility masks of each split look back over (``dataset.json``; 7 for sets of before
    format 6, `stamlane.synth.generator.FIRST_KEY`)."""
    info = root / "dataset.json"
    return json.loads(info.read_text()).get("visibility_reach", {}) if info.is_file() else {}


def _aligns(record: dict[str, Any]) -> bool:
    """Whether a run pre-aligns its history on the fly (``data.clip.align: fly``, the default)."""
    return _clip_option(Path(record["run"]), "align", "fly") == "fly"


def _clip_option(run: Path, name: str, default: Any) -> Any:
    """A ``data.clip`` option of a run's config (``default`` where it is not set)."""
    return (_run_data(run, "data").get("clip") or {}).get(name, default)


def _hardware() -> str:
    """The CPU (or GPU), threads and torch version a run trained on."""
    import platform

    import torch

    if torch.cuda.is_available():
        return f"cuda: {torch.cuda.get_device_name(0)}, torch {torch.__version__}"
    name = platform.processor() or platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        name = next(
            (ln.split(":", 1)[1].strip() for ln in cpuinfo.read_text().splitlines() if ln.startswith("model name")),
            name,
        )
    return f"cpu: {name}, {torch.get_num_threads()} threads, torch {torch.__version__}"


def _run_entry(record: dict[str, Any]) -> RunEntry:
    return RunEntry(
        record["seed"],
        round(record["train_minutes"] + record.get("pretrain_minutes", 0.0), 2),
        record["run"],
        record["last_ckpt"],
        record["frames"],
        record["scores"],
    )


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()
