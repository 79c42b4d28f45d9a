"""One run trained, one run scored: the two steps that every experiment and every benchmark training a model composes.

`Runner.train` trains one run of a row from a recipe stage (`stamlane.experiments.recipes.Stage`) through
`stamlane.training.runs.fit` in this process, or reuses the run when its folder holds a finished record made with the same settings
(`stamlane.experiments.store.RunStore.finished`); a run killed midway goes on from its last checkpoint.

`Runner.score` predicts splits with a run's FINAL weights (`stamlane.training.runs.open_run`: the model built and its
weights loaded once for every split and probe), each split with its history probes (`stamlane.data.probes.Probe`),
and scores them (`stamlane.experiments.split_scores`). What decides whether a split's
predictions are current is kept in the run's record: the SHA-256 of its label file, the digest of its frame files
(`frame_files_digest`) and the scoring rules (`SCORING`). A split whose labels or frames changed is predicted again;
one scored under older rules is scored again from its saved predictions.

The data root is a TuSimple-layout set (``<split>.json`` and the clip folders they name). A synthetic set adds
paint-visibility masks (the recall per visibility class), the factors of its clips, the reveal splits and the
frame-after-frame labels (`TEMPORAL_SPLIT`); what a set lacks is not scored.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Mapping, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stamlane.experiments.recipes import CONFIG_DIR, Row, Stage
from stamlane.experiments.split_scores import (
    SCORING,
    clip_of,
    read_per_clip,
    read_per_image,
    score_split,
    score_temporal,
)
from stamlane.experiments.store import ExperimentError, RunStore
from stamlane.safety.guard import file_sha256
from stamlane.synth.layout import TEMPORAL_LABELS
from stamlane.training.run_record import RunRecord
from stamlane.training.runs import REAL, Probe, Run, RunError, RunSpec, fit, open_run, overrides_of, run_cli

__all__ = [
    "QUICK_OVERRIDES",
    "TEMPORAL_SPLIT",
    "Runner",
    "aligns",
    "check_fit_arguments",
    "frame_files_digest",
    "frames_of",
    "postprocess_of",
    "predicted_as",
]

QUICK_OVERRIDES: dict[str, Any] = {
    "data.clip.image_size": [64, 128],
    "model.encoder.width": 0.125,
    "model.channels_last": False,
    "data.loader.batch_size": 2,
    "data.loader.num_workers": 0,
}
"""A smoke run (``--quick``): a tiny network on small images; its numbers mean nothing."""
TEMPORAL_SPLIT = TEMPORAL_LABELS.removesuffix(".json")
"""The label file (stem) of a synthetic set whose every frame is a key frame: predicted frame after frame, each with
its own history, and scored with RVLD's temporal stability per clip (`stamlane.experiments.split_scores.score_temporal`)."""


def _say(line: str) -> None:
    print(f"[stamlane] {line}", flush=True)


@dataclass
class Runner:
    """Trains runs of rows and scores them on one data set, into one run store (see the module docstring).

    Attributes:
        store: where the runs and their predictions are kept.
        root: the data root.
        bf16: bfloat16 autocast in every run.
        extra: further options of every run (a mapping of dotted names, or ``stamlane fit`` flags as typed after
            ``--``), after the row's base config and before its others.
        quick: the smoke settings (`QUICK_OVERRIDES`), without progress bars.
        progress: progress bars while training.
        max_overlays: overlay pictures per run and split (of the real history only).
        say: where the one-line progress messages go.
    """

    store: RunStore
    root: Path
    bf16: bool = False
    extra: Mapping[str, Any] | Sequence[str] = ()
    quick: bool = False
    progress: bool = True
    max_overlays: int = 12
    say: Callable[[str], None] = field(default=_say)

    # ------------------------------------------------------------------ training
    def spec(self, row: Row, stage: Stage) -> RunSpec:
        """The run of ``row`` trained by ``stage``: its configs (``extra`` after the first, as part of the base: a
        row's own settings hold), the data, the precision, the progress bar, then the stage's options."""
        every = stage.val_every()
        return RunSpec(
            tuple(CONFIG_DIR / c for c in row.configs),
            {
                "data.root": self.root,
                "model.bf16": self.bf16,
                "trainer.enable_progress_bar": self.progress and not self.quick,
                "trainer.enable_model_summary": False,
                **(QUICK_OVERRIDES if self.quick else {}),
                **stage.overrides,
                "trainer.max_steps": stage.steps,
                "trainer.val_check_interval": every,
                **({"trainer.limit_val_batches": stage.val_batches} if stage.val_batches else {}),
                "trainer.log_every_n_steps": max(1, min(25, every)),
            },
            base=self.extra if isinstance(self.extra, Mapping) else overrides_of(self.extra),
        )

    def train(
        self,
        row: Row,
        seed: int,
        stage: Stage,
        settings: dict[str, Any],
        init: Path | None = None,
        label: str = "training",
    ) -> RunRecord:
        """The finished record of the run of ``row`` with ``seed``, training it first when there is none.

        Args:
            row: the model.
            seed: the training seed.
            stage: how it is trained.
            settings: what the run must share with the other runs of the store (recorded; a finished run made
                with other settings is refused).
            init: the weights it starts from (the final weights of a stage 1), or None: from scratch.
            label: the stage's name in the progress lines.

        Returns:
            the run's record (`stamlane.experiments.store`).
        """
        name = self.store.run_name(row.name, seed)
        record = self.store.finished(name, settings)
        if record is not None:
            check_run_config(record.run)
            _verify_checkpoint(record, self.store.folder(name))
            if record.recipe_args != row.recipe_args:
                raise ExperimentError(
                    f"{self.store.folder(name)} was trained with other recipe arguments; use another --out"
                )
            self.say(f"seed {seed}, {label}: {row.label}, done before, reused")
            return record
        self.say(f"seed {seed}, {label}: {row.label}, {stage.steps} steps")
        try:
            record = fit(self.spec(row, stage), seed, init, run_dir=self.store.run_dir(name))
        except RunError as err:
            raise ExperimentError(str(err)) from None
        record.settings, record.recipe_args = dict(settings), row.recipe_args
        self.store.mark(name, record)
        return record

    # ------------------------------------------------------------------ prediction and scoring
    def predict(self, name: str, run: Path, split: str, source: str = "real") -> Path:
        """Predict ``split`` with the final weights of ``run``, its history as the probe ``source`` asks, into the
        store's predictions of ``name``; returns the predictions folder (one pass: `score` opens a run once for all
        its splits and probes)."""
        with self._open(run) as opened:
            return self._predict(opened, name, split, Probe.of(source))

    def _open(self, run: Path) -> Run:
        try:
            return open_run(run)
        except RunError as err:
            raise ExperimentError(f"{err}; delete the run folder") from None

    def _predict(self, run: Run, name: str, split: str, probe: Probe) -> Path:
        out = self.store.pred_dir(name, split, probe.name)
        overlays = self.max_overlays if probe == REAL else 0
        try:
            return run.predict(split, probe, out, root=self.root, max_overlays=overlays)
        except RunError as err:  # a tampered run folder or checkpoint: one line
            raise ExperimentError(str(err)) from None

    def score(self, name: str, record: RunRecord, splits: Mapping[str, Sequence[str]]) -> bool:
        """Predict and score every split of ``splits`` with its probes that ``record`` holds no current scores of.
        The run is opened once (`stamlane.training.runs.open_run`): its model is built and its weights loaded once
        for every split and probe it predicts.

        Args:
            name: the run's name in the store (its predictions' folder).
            record: the run's record; its ``scores``, ``labels``, ``frame_files`` and ``scoring`` are brought up
                to date here (the caller writes it).
            splits: each label file (stem) with the history probes (`stamlane.data.probes.PROBES`) it is scored
                with besides the real history.

        Returns:
            whether any score changed.
        """
        labels, frame_files, scores = record.labels, record.frame_files, record.scores
        rescore = record.scoring != SCORING
        changed = False
        with ExitStack() as stack:
            opened: list[Run] = []
            for split, probes in splits.items():
                labels_sha256 = file_sha256(self.root / f"{split}.json")
                frames_digest = frame_files_digest(self.root, split)
                if labels.get(split) == labels_sha256:  # a record of before the frames counted: its predictions stand
                    frame_files.setdefault(split, frames_digest)
                stale = _stale(labels.get(split) == labels_sha256, frame_files.get(split) == frames_digest)
                if stale and split in scores:
                    self.say(f"{name}: the {split} {stale} changed, predicting them again")
                for source in ("real", *probes):
                    key = split if source == "real" else f"{split}@{source}"
                    current = not stale and key in scores
                    if current and not rescore:
                        continue
                    predicted = predicted_as(record, source)
                    if predicted != source:  # scored under its own name, predicted once
                        scores[key] = scores[f"{split}@{predicted}"]
                        changed = True
                        continue
                    pred_dir = self.store.pred_dir(name, split, source)
                    if not current or not (pred_dir / "predictions.json").is_file():
                        temporal = " frame after frame" if split == TEMPORAL_SPLIT else ""
                        self.say(f"{name}: predicting {key}{temporal}")
                        if not opened:  # once, at the first split or probe to predict
                            opened.append(stack.enter_context(self._open(record.run)))
                        self._predict(opened[0], name, split, Probe.of(source))
                    if split == TEMPORAL_SPLIT:
                        scores[key] = score_temporal(pred_dir, self.root, split)
                    else:
                        scores[key] = score_split(pred_dir, self.root, split, record.frames)
                    changed = True
                labels[split], frame_files[split] = labels_sha256, frames_digest
        if changed:
            record.scoring = SCORING
        return changed

    def scored(self, name: str, record: RunRecord, key: str) -> tuple[dict[str, np.ndarray], list[str]]:
        """The per-image quantities (per clip for `TEMPORAL_SPLIT`) of a score of ``record`` (``<split>`` or
        ``<split>@<probe>``), per metric key, and each row's clip."""
        split, _, source = key.partition("@")
        pred_dir = self.store.pred_dir(name, split, predicted_as(record, source or "real"))
        return read_per_clip(pred_dir) if split == TEMPORAL_SPLIT else read_per_image(pred_dir)


def _stale(same_labels: bool, same_frames: bool) -> str | None:
    """What changed since a split was predicted: ``"labels"``, ``"frames"``, or None."""
    if not same_labels:
        return "labels"
    return None if same_frames else "frames"


def predicted_as(record: RunRecord, source: str) -> str:
    """The probe whose predictions stand for ``source``: `stamlane.data.probes.Probe.unaligned_as` on a run that does
    not align (the same input: predicted once), else ``source``."""
    probe = Probe.of(source)
    return probe.name if probe.unaligned_as is None else probe.predicted_as(aligns(record.run)).name


def frame_files_digest(root: Path, split: str) -> str:
    """A digest of the frame files the predictions of a split read: for every clip folder its key frames lie in,
    each file's name, size and modification time.

    Frames written again (a generator that moves pixels and leaves the labels as they were) change it, so their
    predictions are made again. It reads no frame: hashing every frame's bytes would cost about what predicting
    them does. A set copied without its times (``cp`` without ``-p``) changes it too, and is predicted once more.
    """
    from stamlane_eval.io import read_tusimple

    digest = hashlib.sha256()
    for clip in sorted({clip_of(r["raw_file"]) for r in read_tusimple(root / f"{split}.json")}):
        folder = root / clip
        digest.update(f"{clip}\n".encode())
        if folder.is_dir():
            for entry in sorted(os.scandir(folder), key=lambda e: e.name):
                stat = entry.stat()
                digest.update(f"{entry.name}\0{stat.st_size}\0{stat.st_mtime_ns}\n".encode())
    return digest.hexdigest()


# ---------------------------------------------------------------------- a run folder, read as data
def run_config(run: Path) -> str:
    """The text of a run folder's ``config.yaml``, read only inside the folder (links resolved)."""
    from stamlane.safety.budget import MAX_RECORD_BYTES
    from stamlane.safety.guard import GuardError, read_inside

    try:
        return read_inside(run / "config.yaml", run, MAX_RECORD_BYTES, "run config")
    except GuardError as err:
        raise ExperimentError(f"{err}; delete the run folder") from None


def check_run_config(run: Path) -> None:
    """A run folder's ``config.yaml`` is data, not the user's code: checked against the closed registry
    (`stamlane.training.registry.check_run_config`); a tampered one is refused in one line."""
    from stamlane.safety.checkpoints import CheckpointError
    from stamlane.training.registry import check_run_config as check

    try:
        check(run_config(run), run / "config.yaml")
    except CheckpointError as err:
        raise ExperimentError(str(err)) from None


def frames_of(run: Path) -> int:
    """The clip length (T) of a finished run (`stamlane.training.runs.Run.frames`, its config read through the gate)."""
    with _opened(run) as opened:
        return opened.frames


def aligns(run: Path) -> bool:
    """Whether a finished run pre-aligns its history on the fly (`stamlane.training.runs.Run.aligns`)."""
    with _opened(run) as opened:
        return opened.aligns


def _opened(run: Path) -> Run:
    """A run folder opened through `open_run` (its config checked, nothing built), its refusal an `ExperimentError`."""
    try:
        return open_run(run)
    except RunError as err:
        raise ExperimentError(f"{err}; delete the run folder") from None


def postprocess_of(run: Path) -> dict[str, Any]:
    """A finished run's post-processing options (``model.postprocess`` of its checked config)."""
    with _opened(run) as opened:
        model = opened.config.get("model")
        return dict((model.get("postprocess") if isinstance(model, dict) else None) or {})


def _verify_checkpoint(record: RunRecord, folder: Path) -> None:
    """A finished run whose record holds no digest of its checkpoint (an older record, or one edited): the
    checkpoint must load whole before it is reused (a truncated file is refused, not reused as finished)."""
    from stamlane.safety.checkpoints import CheckpointError, read_checkpoint

    if not record.last_ckpt_sha256:
        try:
            state = read_checkpoint(record.last_ckpt)
        except CheckpointError as err:
            raise ExperimentError(f"{folder}: {err}; delete the folder to run it again") from None
        if not isinstance(state.get("state_dict"), dict) or not state["state_dict"]:
            raise ExperimentError(f"{folder}: its checkpoint holds no weights; delete the folder to run it again")


def check_fit_arguments(config: Path, extra: Sequence[str]) -> None:
    """Parse ``stamlane fit --config CONFIG EXTRA`` and build nothing: fit arguments that every run would refuse
    are said at once, in one line (ExperimentError), not after the data are made and a stage has started. A
    ``--config``, ``--ckpt_path`` or ``--source`` among them goes through the path gate ``stamlane fit`` uses
    (`stamlane.safety.paths.check_command_files`: a FIFO, a device, a config over 16 MiB, a name too long are refused
    unopened) before jsonargparse reads it."""
    from jsonargparse import ArgumentError

    from stamlane.safety.boundary import one_line
    from stamlane.safety.paths import PathError, check_command_files
    from stamlane.training.lightning_cli import StamLaneCLI

    try:
        check_command_files(extra)
    except PathError as err:
        raise ExperimentError(f"the stamlane fit arguments after --: {err}") from None

    class Parsed(Exception):
        """Raised once the arguments parsed: nothing is built."""

    class ParseOnly(StamLaneCLI):
        def before_instantiate_classes(self) -> None:
            raise Parsed

    try:
        run_cli(["fit", "--config", str(config), *extra], cli=ParseOnly, parser_kwargs={"exit_on_error": False})
    except Parsed:
        return
    except (ValueError, ArgumentError) as err:
        raise ExperimentError(f"the stamlane fit arguments after --: {one_line(err)}") from None
