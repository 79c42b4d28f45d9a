"""The experiment: rows x seeds trained with a recipe, scored with their history probed, and summarised.

``stamlane demo`` (three fixed rows and pictures) and ``stamlane ablate`` (the paper's tables) are this experiment
with other rows. It composes the two steps of `stamlane.experiments.runner`: for every seed, a recipe's optional
stage 1 (the single-frame network from scratch, whose final weights start every row) and then every row are
trained (`Runner.train`); each run's FINAL weights predict and score the splits (`Runner.score`), a multi-frame run
twice more or so with its history probed (the key frame copied into every history slot, and another clip's
history), which measures whether it reads its history at all. Where the set has paint-visibility masks, the oracles
of the labels (`stamlane.experiments.oracles`) give each view's headroom: what perfect use of the history could add.
The values and differences with their intervals (`stamlane.experiments.intervals`) make the summary.

The runs live in a `stamlane.experiments.store.RunStore`: a later call with the same ``out`` and settings reuses
them (more seeds, or a run killed midway), predicts again only a split whose labels or frames changed, scores again
one scored under older rules, and refuses other settings.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stamlane.data.probes import EXACT, KEY, OTHER_CLIP, REVERSED, WARPED_KEY, Probe
from stamlane.experiments.intervals import Scores, views
from stamlane.experiments.recipes import Recipe, Row
from stamlane.experiments.runner import TEMPORAL_SPLIT, Runner, aligns, postprocess_of
from stamlane.experiments.split_scores import image_size, read_per_image, read_visibility, score_split
from stamlane.experiments.store import ExperimentError, RunStore
from stamlane.experiments.summary import ModelEntry, RunEntry, Summary
from stamlane.predict.image_score import iou_width
from stamlane.safety.guard import file_sha256, make_folder, write_atomic
from stamlane.training.quiet import quiet_libraries
from stamlane.training.run_record import RunRecord

__all__ = [
    "ALL_PROBES",
    "REVEAL_PROBES",
    "REVEAL_SPLITS",
    "SPANS",
    "SPLIT_PROBES",
    "Experiment",
    "oracle_subject",
]

SPLIT_PROBES = (KEY.name,)
"""The history probes of every multi-frame run on the `Experiment.splits` (`stamlane.data.probes`, where each probe is
defined): the key frame copied into every history slot."""
ALL_PROBES = (KEY.name, OTHER_CLIP.name)
"""`SPLIT_PROBES` with ``other_clip`` (another clip's history) on the `Experiment.splits` too (``all_probes``): whether a
model leans on its history at all, on splits where the history shows little (the reveal splits always have it)."""
REVEAL_SPLITS = ("reveal", "reveal-traffic")
"""The splits where the history reveals lanes (`stamlane.synth.config.REVEAL`), scored where the set has them."""
REVEAL_PROBES = tuple(p.name for p in (KEY, WARPED_KEY, REVERSED, OTHER_CLIP, EXACT))
"""The probes of a multi-frame run on `REVEAL_SPLITS`: `SPLIT_PROBES`, the matched null, the history in reverse order,
another clip's history, and the real history aligned by the generator's exact homographies (runs that align on the fly
only). A run that does not align predicts its matched null once, as ``key`` (`stamlane.data.probes.Probe.unaligned_as`)."""
SPANS = ((2, 1), (4, 1), (8, 1), (2, 2), (4, 2), (8, 2))
"""The spans (frames, stride) whose oracle headroom is measured on every split with visibility masks, within the
reach of its masks (``dataset.json``'s ``visibility_reach``)."""


@dataclass
class Experiment:
    """Rows x seeds on one data set (see the module docstring).

    Attributes:
        rows: the models.
        recipe: how they are trained.
        seeds: training seeds.
        root: the data root (a TuSimple-layout set: ``test.json``, ``challenging.json``, ...; a synthetic set adds
            ``dataset.json``, visibility masks, the reveal splits and the frame-after-frame labels).
        out: the experiment's folder (`stamlane.experiments.store.RunStore`).
        bf16: bfloat16 autocast in every run.
        splits: the label files scored.
        probes: score multi-frame runs with their history probed too.
        reveal_probes: the probes of multi-frame runs on the reveal splits (`REVEAL_PROBES`, or some of them: the
            paper's tables need only ``key``, the history use).
        all_probes: `ALL_PROBES` instead of `SPLIT_PROBES` on ``splits`` (another clip's history too: a third prediction of
            every clean and challenging key frame).
        temporal: predict the frames of `stamlane.synth.layout.TEMPORAL_LABELS` one after the other (each
            with its own history) and score their temporal stability, where the set has that file.
        extra: further ``stamlane fit`` arguments of every run, after the row's base config and before its row
            config.
        quick: the smoke settings (`stamlane.experiments.runner.QUICK_OVERRIDES`), without progress bars.
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
    reveal_probes: tuple[str, ...] = REVEAL_PROBES
    all_probes: bool = False
    temporal: bool = True
    extra: tuple[str, ...] = ()
    quick: bool = False
    max_overlays: int = 12
    log: Callable[[str], None] = field(default=lambda line: print(f"[stamlane] {line}", flush=True))
    store: RunStore = field(init=False, repr=False)
    runner: Runner = field(init=False, repr=False)
    _start: float = field(default_factory=time.perf_counter, init=False, repr=False)

    def __post_init__(self) -> None:
        self.store = RunStore(self.out)
        self.runner = Runner(
            self.store,
            self.root,
            bf16=self.bf16,
            extra=self.extra,
            quick=self.quick,
            max_overlays=self.max_overlays,
            say=self._say,
        )

    def _say(self, line: str) -> None:
        """A progress line, with the minutes since the experiment began (where the time goes, on every machine)."""
        self.log(f"{(time.perf_counter() - self._start) / 60:5.1f} min  {line}")

    # ------------------------------------------------------------------ what is trained and scored
    def settings(self) -> dict[str, Any]:
        """What every run of ``out`` must share."""
        return {
            "data": str(self.root.resolve()),
            **self.recipe.settings(),
            "bf16": self.bf16,
            "extra": list(self.extra),
        }

    def pred_dir(self, name: str, split: str, source: str = "real") -> Path:
        """The predictions of run ``name`` of ``split`` (`stamlane.experiments.store.RunStore.pred_dir`)."""
        return self.store.pred_dir(name, split, source)

    def scored_splits(self) -> tuple[str, ...]:
        """``splits``, and the `REVEAL_SPLITS` the set has (a label file with key frames)."""
        files = [self.root / f"{s}.json" for s in REVEAL_SPLITS if s not in self.splits]
        extra = [f.stem for f in files if f.is_file() and f.stat().st_size > 0]
        return (*self.splits, *extra)

    def temporal_split(self) -> str | None:
        """The label file (stem) of frame-after-frame predictions, where the set has one and it is wanted."""
        return TEMPORAL_SPLIT if self.temporal and (self.root / f"{TEMPORAL_SPLIT}.json").is_file() else None

    def probes_of(self, split: str, record: RunRecord) -> tuple[str, ...]:
        """The history probes of a run on ``split``: none for a single frame; ``reveal_probes`` on the reveal splits,
        `SPLIT_PROBES` (`ALL_PROBES` with ``all_probes``) elsewhere. A run that does not align predicts neither ``exact``
        (there is no alignment to make exact) nor ``warped_key``: without alignment the key frame warped out comes
        back unwarped, the very input of ``key`` (`stamlane.data.clips.warped_key`), so its scores are ``key``'s
        (`stamlane.data.probes.Probe.unaligned_as`)."""
        if not self.probes or record.frames < 2:
            return ()
        if split not in REVEAL_SPLITS:
            return ALL_PROBES if self.all_probes else SPLIT_PROBES
        if aligns(record.run):
            return self.reveal_probes
        return tuple(p for p in self.reveal_probes if not Probe.of(p).exact)

    def scored(self, record: RunRecord) -> dict[str, tuple[str, ...]]:
        """Every split a run is scored on, with its probes: `scored_splits`, then the frame-after-frame split with
        the key frame copied into the history too (does the history itself make the lanes steadier?); another
        clip's history would be one clip's for every frame: not a probe of time."""
        found = {split: self.probes_of(split, record) for split in self.scored_splits()}
        frames = self.temporal_split()
        if frames is not None:
            found[frames] = ("key",) if self.probes and record.frames > 1 else ()
        return found

    # ------------------------------------------------------------------ the whole experiment
    def run(self, pairs: list[tuple[str, str]]) -> Summary:
        """Train, predict, score and summarise every row and seed.

        Args:
            pairs: the models compared, ``(a, b)`` names of rows (a - b on the same key frames).

        Returns:
            the summary, also written to ``<out>/summary.json``.
        """
        names = [r.name for r in self.rows]
        if len(set(names)) != len(names):
            raise ExperimentError(f"two rows share a name: {names}")
        make_folder(self.out, "--out")
        quiet_libraries()
        start = self._start = time.perf_counter()
        settings = self.settings()
        scores = Scores()
        records: dict[str, list[RunRecord]] = {r.name: [] for r in self.rows}
        pretraining = self.recipe.pretraining()
        for seed in self.seeds:
            init = base = None
            if pretraining is not None:
                assert self.recipe.pretrain is not None  # a recipe with a stage 1 names its model
                base = self.runner.train(self.recipe.pretrain, seed, pretraining, settings, label="stage 1")
                init = base.last_ckpt
            for row in self.rows:
                stage = "stage 2" if init else "training"
                record = self.runner.train(row, seed, self.recipe.training(row), settings, init, stage)
                if base is not None and record.pretrain_minutes is None:
                    record.pretrain_minutes = base.train_minutes
                name = self.store.run_name(row.name, seed)
                scored = self.scored(record)
                if self.runner.score(name, record, scored):
                    self.store.mark(name, record)
                for key in record.scores:  # what this experiment scores (a reused run may hold more)
                    split, _, source = key.partition("@")
                    if split not in scored or (source and source not in scored[split]):
                        continue
                    per_image, clips = self.runner.scored(name, record, key)
                    scores.add(row.name + (f"@{source}" if source else ""), split, seed, per_image, clips)
                records[row.name].append(record)
        self._say("scoring the oracles of the labels")
        summary = self._summary(scores, records, pairs)
        summary.minutes = round((time.perf_counter() - start) / 60, 2)
        summary.write(self.out / "summary.json")
        return summary

    def _summary(self, scores: Scores, records: dict[str, list[RunRecord]], pairs: list[tuple[str, str]]) -> Summary:
        """The summary of the scored runs: every model's values and probes, the oracles, the differences."""
        all_views = views(self.root, scores.clips)
        multi = [r.name for r in self.rows if records[r.name] and records[r.name][0].frames > 1]
        frames = sorted({records[n][0].frames for n in multi})
        oracles = self._oracles(scores, frames, postprocess_of(records[self.rows[0].name][0].run))
        differences = scores.differences("models", pairs, all_views)
        for name in multi:
            for probe in REVEAL_PROBES:  # real minus probe; exact alignment minus ORB's: exact - real
                pair = (f"{name}@exact", name) if probe == "exact" else (name, f"{name}@{probe}")
                differences += scores.differences(f"history_{probe.replace('other_clip', 'other')}", [pair], all_views)
            # the history use of the history aligned by the generator's exact homographies: what ORB's errors hide
            differences += scores.differences("history_key_exact", [(f"{name}@exact", f"{name}@key")], all_views)
            singles = [r.name for r in self.rows if r.name not in multi and records[r.name]]
            # the same weights without their history against a single frame trained alike: what the training did
            differences += scores.differences("key_copied", [(f"{name}@key", one) for one in singles], all_views)
        for subject in oracles:
            if subject.startswith("oracle:history-"):
                differences += scores.differences("headroom", [(subject, "oracle:key")], all_views)
            if subject.startswith("oracle:unaligned-"):
                aligned = subject.replace("unaligned", "history")
                differences += scores.differences("alignment_oracle", [(aligned, subject)], all_views)
        steps = self.recipe.steps + self.recipe.pretrain_steps
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
                    runs[0].frames,
                    steps,
                    [_run_entry(r) for r in runs],
                    scores.values(row.name, all_views),
                    {s: v for s, v in probes.items() if v},
                )
            )
        scored = (*self.scored_splits(), *filter(None, [self.temporal_split()]))
        recipe = self.recipe.settings()
        return Summary(
            data=str(self.root),
            splits_sha256={split: file_sha256(self.root / f"{split}.json") for split in scored},
            seeds=list(self.seeds),
            recipe={"name": recipe.pop("recipe"), **recipe},
            bf16=self.bf16,
            iou_width=iou_width(image_size(self.root, self.splits[0])),
            models=models,
            oracles={o: scores.values(o, all_views) for o in oracles},
            differences=differences,
        )

    # ------------------------------------------------------------------ oracles
    def _oracles(self, scores: Scores, frames: list[int], postprocess: dict[str, Any]) -> list[str]:
        """Score the oracles (`stamlane.experiments.oracles.oracle_predictions`) on every split with visibility
        masks: the key-frame oracle; the aligned and the unaligned history oracles of each clip length in
        ``frames``; the aligned history oracle of every span of `SPANS` within the masks' reach. Returns the oracle
        subjects (`oracle_subject`); none on a set without masks."""
        from stamlane_eval.io import read_tusimple

        from stamlane.experiments.oracles import oracle_predictions
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
            size = image_size(self.root, split)
            spans = [(t, 1) for t in frames] + [
                sp for sp in SPANS if (sp[0] - 1) * sp[1] <= reach.get(split, FIRST_KEY)
            ]
            for t, stride in dict.fromkeys(spans):
                unaligned = self.root if t in frames and stride == 1 else None
                found = oracle_predictions(gts, visibility, t, config, size, stride, unaligned)
                for kind, predictions in found.items():
                    subject = oracle_subject(kind, t, stride)
                    if subject in subjects and split in scores.quantities.get(subject, {}):
                        continue  # the key-frame oracle is the same for every span
                    pred_dir = self.store.oracle_dir(subject, split)
                    write_atomic(pred_dir / "predictions.json", "".join(json.dumps(r) + "\n" for r in predictions))
                    score_split(pred_dir, self.root, split, t)
                    per_image, clips = read_per_image(pred_dir)
                    scores.add(subject, split, 0, per_image, clips)
                    subjects.append(subject)
        return list(dict.fromkeys(subjects))


def oracle_subject(kind: str, frames: int, stride: int = 1) -> str:
    """The subject name of an oracle (`stamlane.experiments.oracles.ORACLES`) of a span: ``oracle:key``,
    ``oracle:history-4f``, ``oracle:unaligned-4f``, ``oracle:history-8f-x2`` (8 frames, every 2nd)."""
    if kind == "key":
        return "oracle:key"
    return f"oracle:{kind}-{frames}f" + (f"-x{stride}" if stride > 1 else "")


def _visibility_reach(root: Path) -> dict[str, int]:
    """History frames the visibility masks of each split look back over (``dataset.json``; 7 for sets of before
    format 6, `stamlane.synth.layout.FIRST_KEY`)."""
    info = root / "dataset.json"
    return json.loads(info.read_text()).get("visibility_reach", {}) if info.is_file() else {}


def _run_entry(record: RunRecord) -> RunEntry:
    return RunEntry(
        record.seed,
        round(record.train_minutes + (record.pretrain_minutes or 0.0), 2),
        str(record.run),
        str(record.last_ckpt),
        record.frames,
        record.scores,
    )
