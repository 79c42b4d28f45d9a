"""The numbers an experiment reports, each made of per-image quantities, each under one name.

A metric's name is the one `stamlane_eval.integrations.lightning.LaneEvalCallback` logs (after ``val/`` or
``test/``), built by `stamlane_eval.names.metric_name`: ``tusimple_f1`` (the paper's TuSimple F1), ``culane_f1@0.5``
and ``culane_f1@0.3`` (the CULane-style IoU F1 of the paper's ApolloScape tables), ``temporal_rs@0.5`` ... (RVLD's
temporal stability). The same names key the summaries, the tables and the docs. Recall per paint-visibility class
(``recall_visible``, ``recall_revealed``, ``recall_hidden``; `stamlane.experiments.split_scores`), stamlane's own,
is reported where the data has visibility masks.

Two kinds of constant, two kinds of name: `stamlane_eval.names` spells the evaluators (``names.TUSIMPLE ==
"tusimple"``, strings that build logged names); this module holds the reported numbers, `Metric` objects named by
the number (`TUSIMPLE_F1`, `CULANE_F1`, `TEMPORAL_STABILITY`, `CLASS_RECALL`, all of them `REPORTED`).

Every metric is a statistic of the column means of per-image quantities (a row of ``per_image.jsonl``), so one
bootstrap serves all of them: clips resampled for an interval, the same clips for a paired difference.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from stamlane_eval import names
from stamlane_eval.culane import IOU_THRESHOLDS
from stamlane_eval.stats import f1_of_counts, f1_of_rates, rj_of_counts, rm_of_counts, rs_of_counts
from stamlane_eval.temporal import TEMPORAL_IOU_THRESHOLDS

from stamlane.synth.visibility import VISIBILITY_CLASSES

__all__ = ["CLASS_RECALL", "CULANE_F1", "REPORTED", "TEMPORAL_STABILITY", "TUSIMPLE_F1", "Metric", "metric"]


@dataclass(frozen=True)
class Metric:
    """One reported number.

    Attributes:
        key: its name everywhere (``tusimple_f1``, ``culane_f1@0.5``, ``recall_revealed``).
        label: its name in printed tables.
        columns: a ``per_image.jsonl`` row -> that image's quantities (k,), or None when the row lacks them.
        statistic: the column means (k,) over a set of images -> the number.
    """

    key: str
    label: str
    columns: Callable[[dict[str, Any]], list[float] | None]
    statistic: Callable[[np.ndarray], float]


def _culane_counts(threshold: float) -> Callable[[dict[str, Any]], list[float] | None]:
    def columns(row: dict[str, Any]) -> list[float] | None:
        counts = row.get("culane") or row.get("iou")  # "iou": summaries written before the one name
        return None if counts is None else counts[f"{threshold:g}"]

    return columns


def _class_counts(cls: str) -> Callable[[dict[str, Any]], list[float] | None]:
    i = VISIBILITY_CLASSES.index(cls)

    def columns(row: dict[str, Any]) -> list[float] | None:
        counts = row.get("classes")
        return None if counts is None else counts[2 * i : 2 * i + 2]

    return columns


def _recall(means: np.ndarray) -> float:
    """Recalled points over points (0 where a resample holds no point of the class)."""
    return float(means[0] / means[1]) if means[1] > 0 else 0.0


def _temporal_counts(threshold: float) -> Callable[[dict[str, Any]], list[float] | None]:
    def columns(row: dict[str, Any]) -> list[float] | None:
        counts = row.get("temporal")
        return None if counts is None else counts[f"{threshold:g}"]

    return columns


TUSIMPLE_F1 = Metric(
    names.metric_name(names.TUSIMPLE, "f1"),
    "TuSimple F1",
    lambda row: [row["fp"], row["fn"]] if "fp" in row else None,
    f1_of_rates,
)
CULANE_F1 = tuple(
    Metric(names.metric_name(names.CULANE, "f1", t), f"IoU F1 @{t:g}", _culane_counts(t), f1_of_counts)
    for t in sorted(IOU_THRESHOLDS, reverse=True)
)
CLASS_RECALL = tuple(
    Metric(f"recall_{c}", f"recall, {c} points", _class_counts(c), _recall) for c in VISIBILITY_CLASSES
)
TEMPORAL_STABILITY = tuple(
    Metric(
        names.metric_name(names.TEMPORAL, name, t),
        f"{name.capitalize()} @{t:g}",
        _temporal_counts(t),
        statistic,
    )
    for t in TEMPORAL_IOU_THRESHOLDS
    for name, statistic in (("rs", rs_of_counts), ("rj", rj_of_counts), ("rm", rm_of_counts))
)
"""RVLD's temporal stability (`stamlane_eval.temporal`): of the annotated lanes matched between consecutive frames,
the share predicted above the IoU threshold in both (Rs, stable), in one (Rj, jump), in neither (Rm, missing);
per-clip ``(Ns, Nj, Nm)`` counts (a row of ``per_clip.jsonl``)."""
REPORTED = (TUSIMPLE_F1, *CULANE_F1, *CLASS_RECALL, *TEMPORAL_STABILITY)
"""Everything an experiment scores: the paper's TuSimple F1, the IoU F1 at 0.5 and 0.3, recall per visibility class,
and the temporal stability of frame-after-frame predictions."""


def metric(key: str) -> Metric:
    """The metric named ``key`` (`REPORTED`)."""
    for m in REPORTED:
        if m.key == key:
            return m
    raise KeyError(f"no metric {key!r}; known: {' '.join(m.key for m in REPORTED)}")
