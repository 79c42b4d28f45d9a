"""Values and differences of a set of runs: one statistics module for every experiment.

The per-image quantities of every subject (model, history probe, oracle), split and seed are held in a
`Scores`; a view is a subset of one split's key frames (`views`). A value is the metric's statistic of the
seed-averaged per-image quantities with its clip-bootstrap interval, beside the per-seed mean and standard
deviation; a difference between two subjects on the same key frames has a paired clip-bootstrap interval and,
with several seeds, the Student-t interval of the per-seed differences (`stamlane_eval.stats`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from stamlane_eval.stats import bootstrap, paired_bootstrap, seed_interval

from stamlane.experiments.metrics import REPORTED, Metric
from stamlane.experiments.summary import Difference, Value, Values

__all__ = ["MIN_CLASS_POINTS", "Scores", "View", "views"]

MIN_CLASS_POINTS = 20
"""A recall per visibility class is reported on a view only where the class has at least this many points."""


@dataclass(frozen=True)
class View:
    """Key frames scored together: a ``name`` (``test``, ``challenging:glare``), the ``split`` they come from and
    their row indices in that split's per-image results."""

    name: str
    split: str
    rows: np.ndarray


def views(root: Path, clips: dict[str, list[str]]) -> list[View]:
    """Every split whole, then each factor of each split (``dataset.json``'s ``clip_factors``: the challenging
    split's, and the factor clips of a format-5 val split; none for a set without them).

    Args:
        root: the data root.
        clips: per split, each key frame's clip in label order.
    """
    found = [View(split, split, np.arange(len(c))) for split, c in clips.items()]
    info = root / "dataset.json"
    clip_factors = json.loads(info.read_text()).get("clip_factors", {}) if info.is_file() else {}
    for split, split_clips in clips.items():
        of_row = [clip_factors.get(clip.rsplit("/", 1)[-1]) for clip in split_clips]
        for factor in dict.fromkeys(f for f in of_row if f is not None):
            rows = np.array([i for i, f in enumerate(of_row) if f == factor])
            found.append(View(f"{split}:{factor}", split, rows))
    return found


@dataclass
class Scores:
    """Per-image quantities: subject -> split -> seed -> metric key -> (N, k); each split's clips."""

    quantities: dict[str, dict[str, dict[int, dict[str, np.ndarray]]]] = field(default_factory=dict)
    clips: dict[str, list[str]] = field(default_factory=dict)

    def add(self, subject: str, split: str, seed: int, per_image: dict[str, np.ndarray], clips: list[str]) -> None:
        """Record one subject's scored split for one seed (its clips must be the split's, in the same order)."""
        known = self.clips.setdefault(split, clips)
        if known != clips:
            raise ValueError(f"{subject} seed {seed}: the {split} split holds other key frames than before")
        self.quantities.setdefault(subject, {}).setdefault(split, {})[seed] = per_image

    def _per_seed(self, subject: str, view: View, metric: Metric) -> dict[int, np.ndarray] | None:
        seeds = self.quantities.get(subject, {}).get(view.split, {})
        found = {seed: q[metric.key][view.rows] for seed, q in seeds.items() if metric.key in q}
        if not found or len(found) != len(seeds):
            return None
        if metric.key.startswith("recall_") and next(iter(found.values()))[:, 1].sum() < MIN_CLASS_POINTS:
            return None
        return found

    def value(self, subject: str, view: View, metric: Metric) -> Value | None:
        """The metric of a subject on a view (None where it was not scored or a class has too few points)."""
        per_seed = self._per_seed(subject, view, metric)
        if per_seed is None:
            return None
        values = np.array([metric.statistic(q.mean(axis=0)) for q in per_seed.values()])
        groups = [self.clips[view.split][i] for i in view.rows]
        ci = None
        if len(set(groups)) >= 2:
            est = bootstrap(np.mean(list(per_seed.values()), axis=0), metric.statistic, groups=groups)
            ci = [est.low, est.high]
        std = float(values.std(ddof=1)) if len(values) > 1 else None
        return Value(float(values.mean()), std, ci, len(values), len(view.rows))

    def values(self, subject: str, all_views: list[View], metrics: tuple[Metric, ...] = REPORTED) -> Values:
        """Every metric of a subject on every view where it was measured."""
        found: Values = {}
        for metric in metrics:
            for view in all_views:
                value = self.value(subject, view, metric)
                if value is not None:
                    found.setdefault(metric.key, {})[view.name] = value
        return found

    def difference(self, kind: str, a: str, b: str, view: View, metric: Metric) -> Difference | None:
        """``metric(a) - metric(b)`` on a view (see `Difference`); None where either was not measured or the view
        holds a single clip. Per-seed differences pair the seeds both have (a subject with one "seed", an oracle,
        is paired with every seed of the other)."""
        qa, qb = self._per_seed(a, view, metric), self._per_seed(b, view, metric)
        groups = [self.clips[view.split][i] for i in view.rows]
        if qa is None or qb is None or len(set(groups)) < 2:
            return None
        f = metric.statistic
        est = paired_bootstrap(np.mean(list(qa.values()), axis=0), np.mean(list(qb.values()), axis=0), f, groups=groups)
        if len(qa) == 1 or len(qb) == 1:
            diffs = []
        else:
            diffs = [f(qa[s].mean(axis=0)) - f(qb[s].mean(axis=0)) for s in sorted(set(qa) & set(qb))]
        seeds = seed_interval(diffs) if len(diffs) > 1 else None
        return Difference(
            kind,
            a,
            b,
            view.name,
            metric.key,
            est.value,
            [est.low, est.high],
            diffs,
            [seeds.low, seeds.high] if seeds else None,
        )

    def differences(
        self, kind: str, pairs: list[tuple[str, str]], all_views: list[View], metrics: tuple[Metric, ...] = REPORTED
    ) -> list[Difference]:
        """`difference` of every pair on every view and metric where both were measured."""
        found = []
        for a, b in pairs:
            for metric in metrics:
                for view in all_views:
                    d = self.difference(kind, a, b, view, metric)
                    if d is not None:
                        found.append(d)
        return found
