"""The typed summary of an experiment (``summary.json``): runs, values with intervals, differences.

Every number of a table is here with its provenance: which models and seeds, which view of which split, which
metric (`stamlane.experiments.metrics`), its 95 % interval over the test clips and, with several seeds, over the
training seeds. ``Summary.write`` serialises the dataclasses to json; ``Summary.read`` reads them back.

A **view** is a set of scored key frames: a split (``test``, ``challenging``) or one factor of the challenging
split (``challenging:glare``). A **subject** is what produced predictions: a trained model (``stam4``), the same
weights with probed history (``stam4@key``: the key frame copied into every history slot; ``stam4@other_clip``:
another clip's history) or an oracle of the labels (``oracle:key``, ``oracle:history``).
"""

from __future__ import annotations

import json
import reprlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from stamlane.safety.guard import write_atomic

__all__ = [
    "DIFFERENCE_KINDS",
    "FORMAT",
    "Difference",
    "ModelEntry",
    "RunEntry",
    "Summary",
    "SummaryError",
    "Value",
]

FORMAT = 2
"""Format of ``summary.json``. Format 1 (no ``format`` key), the untyped summary ``stamlane demo`` wrote up to the
IoU F1 and the baselines, is no longer read: the summaries kept in docs/results/ were converted once."""
DIFFERENCE_KINDS = (
    "models",
    "history_key",
    "history_warped_key",
    "history_reversed",
    "history_other",
    "history_exact",
    "history_key_exact",
    "key_copied",
    "headroom",
    "alignment_oracle",
)
"""``models``: two trained models on the same images; ``history_<probe>``: a model with its real history minus the
same weights with the history probed (the key frame copied, warped out and back, the history reversed, another
clip's: its history use); ``history_exact``: the history aligned by the generator's exact homographies minus ORB's;
``history_key_exact``: exactly aligned history minus the key frame copied (history use with exact alignment);
``key_copied``: a multi-frame model with its key frame copied minus a single frame trained alike (what the
training did, history aside); ``headroom``: the history oracle minus the key-frame oracle (what history can
reveal); ``alignment_oracle``: the aligned minus the unaligned history oracle."""

Values = dict[str, dict[str, "Value"]]
"""metric key -> view -> value."""


class SummaryError(ValueError):
    """A summary that cannot be read: one line."""


@dataclass
class Value:
    """One metric of one subject on one view.

    Attributes:
        mean: mean over the seeds of the per-seed values.
        std: their standard deviation (None for one seed).
        ci95: 95 % interval of the value of the seed-averaged per-image quantities, clips resampled (None when
            the view holds a single clip).
        seeds: seeds averaged.
        images: key frames in the view.
    """

    mean: float
    std: float | None
    ci95: list[float] | None
    seeds: int
    images: int


@dataclass
class Difference:
    """``metric(a) - metric(b)`` on the same key frames of one view.

    Attributes:
        kind: one of `DIFFERENCE_KINDS`.
        a, b: subjects.
        view: the view.
        metric: the metric key.
        diff: the difference of the seed-averaged per-image quantities' values.
        ci95: its paired 95 % interval, clips resampled.
        seed_diffs: the per-seed differences (a and b of one seed).
        seed_ci95: the Student-t 95 % interval of their mean (None for one seed).
    """

    kind: str
    a: str
    b: str
    view: str
    metric: str
    diff: float
    ci95: list[float]
    seed_diffs: list[float] = field(default_factory=list)
    seed_ci95: list[float] | None = None

    @property
    def supported(self) -> bool:
        """Every interval (clips; seeds, where there are several) excludes 0: a difference the data supports."""
        intervals = [self.ci95, *([self.seed_ci95] if self.seed_ci95 else [])]
        return all(not low <= 0.0 <= high for low, high in intervals)


@dataclass
class RunEntry:
    """One trained run (a model and a seed): where its weights are and its scores per split (probes under
    ``<split>@<source>``)."""

    seed: int
    train_minutes: float
    run: str
    last_ckpt: str
    frames: int
    scores: dict[str, dict[str, Any]]


@dataclass
class ModelEntry:
    """A trained model: its runs, and the values of it and of its history probes."""

    name: str
    label: str
    paper_row: str | None
    configs: list[str]
    frames: int
    steps: int
    runs: list[RunEntry]
    values: Values
    probes: dict[str, Values] = field(default_factory=dict)


@dataclass
class Summary:
    """An experiment: data, recipe, models, oracles and differences (see the module docstring)."""

    data: str
    splits_sha256: dict[str, str]
    seeds: list[int]
    recipe: dict[str, Any]
    bf16: bool
    iou_width: int | None
    models: list[ModelEntry]
    oracles: dict[str, Values] = field(default_factory=dict)
    differences: list[Difference] = field(default_factory=list)
    minutes: float | None = None
    pictures: dict[str, str] = field(default_factory=dict)
    format: int = FORMAT

    def model(self, name: str) -> ModelEntry:
        for m in self.models:
            if m.name == name:
                return m
        raise KeyError(f"no model {name!r} in the summary; models: {' '.join(m.name for m in self.models)}")

    def value(self, subject: str, metric: str, view: str) -> Value | None:
        """The value of a subject (model, ``model@source`` probe or oracle), or None where it was not measured."""
        if subject in self.oracles:
            values = self.oracles[subject]
        else:
            name, _, source = subject.partition("@")
            try:
                model = self.model(name)
            except KeyError:
                return None
            values = model.probes.get(source, {}) if source else model.values
        return values.get(metric, {}).get(view)

    def difference(self, a: str, b: str, view: str, metric: str) -> Difference | None:
        """The difference a - b of one view and metric, read the other way round (negated) where it was measured
        as b - a; None where it was not measured."""
        for d in self.differences:
            if (d.a, d.b, d.view, d.metric) == (a, b, view, metric):
                return d
            if (d.b, d.a, d.view, d.metric) == (a, b, view, metric):
                return _negated(d)
        return None

    def views(self) -> list[str]:
        """Every view some value was measured on, splits first, in the order measured."""
        found: dict[str, None] = {}
        for m in self.models:
            for per_view in m.values.values():
                found |= dict.fromkeys(per_view)
        return sorted(found, key=lambda v: (":" in v, list(found).index(v)))

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=2)

    def write(self, path: Path) -> None:
        write_atomic(path, self.to_json())

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Summary:
        """A summary from its json form (any format this version reads).

        Raises:
            SummaryError: not a summary, or a format this version does not know.
        """
        if not isinstance(data, dict) or "models" not in data:
            raise SummaryError("not an experiment summary (no 'models')")
        fmt = data.get("format", 1)
        number = isinstance(fmt, int) and not isinstance(fmt, bool)
        if number and fmt == 1:
            raise SummaryError(
                "a summary of format 1 (the untyped summary of the first demos) is no longer read; run the "
                "experiment again to write it in this format"
            )
        if number and fmt > FORMAT:
            raise SummaryError(f"summary format {fmt} is newer than this stamlane reads ({FORMAT}); upgrade stamlane")
        if fmt != FORMAT:
            raise SummaryError(f"summary format {reprlib.repr(fmt)} is not one this stamlane reads ({FORMAT})")
        if not isinstance(data.get("models"), list):
            raise SummaryError("malformed summary: 'models' is not a list")
        try:
            models = [
                ModelEntry(
                    **{k: v for k, v in m.items() if k not in ("runs", "values", "probes")},
                    runs=[RunEntry(**r) for r in m["runs"]],
                    values=_values(m["values"]),
                    probes={s: _values(v) for s, v in m.get("probes", {}).items()},
                )
                for m in data["models"]
            ]
            rest = {k: v for k, v in data.items() if k not in ("models", "oracles", "differences")}
            summary = cls(
                **rest,
                models=models,
                oracles={name: _values(v) for name, v in data.get("oracles", {}).items()},
                differences=[Difference(**d) for d in data.get("differences", [])],
            )
        except (TypeError, KeyError, AttributeError) as err:
            raise SummaryError(f"malformed summary: {err}") from None
        _check_types(summary)
        return summary

    @classmethod
    def read(cls, path: Path) -> Summary:
        """Read ``summary.json``.

        Raises:
            SummaryError: unreadable, not json, or not a summary (the message names the file).
        """
        from stamlane.safety.budget import MAX_RECORD_BYTES
        from stamlane.safety.guard import GuardError, read_input

        try:  # a regular file within the budget: a FIFO or /dev/zero is refused unread
            data = json.loads(read_input(path, MAX_RECORD_BYTES, "summary"))
        except GuardError as err:
            raise SummaryError(str(err)) from None
        except (RecursionError, json.JSONDecodeError) as err:
            raise SummaryError(f"{path}: cannot read it as a summary ({type(err).__name__}: {err})") from None
        try:
            return cls.from_dict(data)
        except SummaryError as err:
            raise SummaryError(f"{path}: {err}") from None


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _interval(value: Any) -> bool:
    return isinstance(value, list) and len(value) == 2 and all(_number(v) for v in value)


def _check_types(summary: Summary) -> None:
    """Every field the tables read holds the type it is declared with (a mean of null, a string, an interval of
    one value is refused here in one line, not met as a TypeError in the middle of a table)."""

    def fail(where: str, value: Any) -> None:
        raise SummaryError(f"malformed summary: {where} is {reprlib.repr(value)}")

    def check_values(values: Any, where: str) -> None:
        if not isinstance(values, dict):
            fail(where, values)
        for metric, per_view in values.items():
            for view, v in per_view.items():
                at = f"{where} {metric} {view}"
                if not _number(v.mean):
                    fail(f"{at} mean", v.mean)
                if v.std is not None and not _number(v.std):
                    fail(f"{at} std", v.std)
                if v.ci95 is not None and not _interval(v.ci95):
                    fail(f"{at} ci95", v.ci95)
                for name in ("seeds", "images"):
                    if not isinstance(getattr(v, name), int) or isinstance(getattr(v, name), bool):
                        fail(f"{at} {name}", getattr(v, name))

    if not isinstance(summary.seeds, list) or not all(isinstance(s, int) for s in summary.seeds):
        fail("seeds", summary.seeds)
    if not isinstance(summary.recipe, dict):
        fail("recipe", summary.recipe)
    for m in summary.models:
        for name in ("name", "label"):
            if not isinstance(getattr(m, name), str):
                fail(f"a model's {name}", getattr(m, name))
        if m.paper_row is not None and not isinstance(m.paper_row, str):
            fail(f"model {m.name} paper_row", m.paper_row)
        if not isinstance(m.frames, int) or isinstance(m.frames, bool):
            fail(f"model {m.name} frames", m.frames)
        check_values(m.values, f"model {m.name}")
        if not isinstance(m.probes, dict):
            fail(f"model {m.name} probes", m.probes)
        for source, values in m.probes.items():
            check_values(values, f"model {m.name}@{source}")
    for name, values in summary.oracles.items():
        check_values(values, f"oracle {name}")
    for d in summary.differences:
        where = f"difference {d.a!r} - {d.b!r}"
        for name in ("kind", "a", "b", "view", "metric"):
            if not isinstance(getattr(d, name), str):
                fail(f"{where} {name}", getattr(d, name))
        if not _number(d.diff):
            fail(f"{where} diff", d.diff)
        if not _interval(d.ci95):
            fail(f"{where} ci95", d.ci95)
        if d.seed_ci95 is not None and not _interval(d.seed_ci95):
            fail(f"{where} seed_ci95", d.seed_ci95)
        if not isinstance(d.seed_diffs, list) or not all(_number(x) for x in d.seed_diffs):
            fail(f"{where} seed_diffs", d.seed_diffs)


def _values(data: dict[str, dict[str, dict[str, Any]]]) -> Values:
    return {metric: {view: Value(**v) for view, v in per_view.items()} for metric, per_view in data.items()}


def _negated(d: Difference) -> Difference:
    return Difference(
        d.kind,
        d.b,
        d.a,
        d.view,
        d.metric,
        -d.diff,
        [-d.ci95[1], -d.ci95[0]],
        [-x for x in d.seed_diffs],
        None if d.seed_ci95 is None else [-d.seed_ci95[1], -d.seed_ci95[0]],
    )
