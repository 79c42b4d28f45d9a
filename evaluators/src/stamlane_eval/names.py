"""The names of the numbers the metrics give, built and read in one place.

A metric's ``compute`` keys its numbers ``{quantity}`` or ``{quantity}@{threshold:g}`` (`metric_key`: ``f1``,
``f1@0.5``); the Lightning callback logs them as ``{stage}/{metric}_{key}`` (`metric_name`: ``val/tusimple_f1``,
``val/culane_f1@0.5``, ``test/video_miou``, ``val/temporal_rs@0.8``), and stamlane's experiments key their
summaries, tables and reports with the same names without the stage. `parse_metric_name` reads a name back;
names that `metric_name` would not write (another spelling of a threshold, an unknown metric or quantity) are
refused, so there is one vocabulary.

    >>> metric_name("culane", "f1", 0.5, stage="val")
    'val/culane_f1@0.5'
    >>> parse_metric_name("val/culane_f1@0.5")
    MetricName(metric='culane', quantity='f1', threshold=0.5, stage='val')
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "CULANE",
    "METRICS",
    "TEMPORAL",
    "THRESHOLDED",
    "TUSIMPLE",
    "UNTHRESHOLDED",
    "VIDEO",
    "MetricName",
    "metric_key",
    "metric_name",
    "parse_metric_key",
    "parse_metric_name",
]

TUSIMPLE = "tusimple"
"""TuSimple's lane.py (`stamlane_eval.tusimple`)."""
CULANE = "culane"
"""The CULane / ApolloScape area metric (`stamlane_eval.culane`)."""
VIDEO = "video"
"""MMA-Net's VIL-100 mIoU and F (`stamlane_eval.video`)."""
TEMPORAL = "temporal"
"""RVLD's temporal stability (`stamlane_eval.temporal`)."""
METRICS = (TUSIMPLE, CULANE, VIDEO, TEMPORAL)

UNTHRESHOLDED: dict[str, tuple[str, ...]] = {
    TUSIMPLE: ("accuracy", "fp", "fn", "f1", "late", "lane_precision", "lane_recall", "lane_f1"),
    CULANE: (),
    VIDEO: ("miou",),
    TEMPORAL: (),
}
"""Per metric, the quantities it gives once (``tusimple_f1``, ``video_miou``)."""
THRESHOLDED: dict[str, tuple[str, ...]] = {
    TUSIMPLE: (),
    CULANE: ("precision", "recall", "f1", "tp", "fp", "fn"),
    VIDEO: ("precision", "recall", "f1", "tp", "fp", "fn"),
    TEMPORAL: ("rs", "rj", "rm", "ns", "nj", "nm"),
}
"""Per metric, the quantities it gives at each IoU threshold (``culane_f1@0.5``, ``temporal_rs@0.8``)."""


@dataclass(frozen=True)
class MetricName:
    """A name taken apart.

    Attributes:
        metric: one of `METRICS` (``"culane"``).
        quantity: what is measured (``"f1"``; `UNTHRESHOLDED` / `THRESHOLDED` name each metric's).
        threshold: the IoU threshold of a thresholded quantity, else None.
        stage: the logging stage (``"val"``, ``"test"``), or None for the bare name.
    """

    metric: str
    quantity: str
    threshold: float | None = None
    stage: str | None = None

    def __post_init__(self) -> None:
        if self.metric not in METRICS:
            raise ValueError(f"unknown metric {self.metric!r}; known: {', '.join(METRICS)}")
        if self.quantity in THRESHOLDED[self.metric]:
            if self.threshold is None:
                raise ValueError(f"{self.metric} {self.quantity} is given per IoU threshold: name one")
        elif self.quantity in UNTHRESHOLDED[self.metric]:
            if self.threshold is not None:
                raise ValueError(f"{self.metric} {self.quantity} has no IoU threshold, got {self.threshold!r}")
        else:
            known = UNTHRESHOLDED[self.metric] + THRESHOLDED[self.metric]
            raise ValueError(f"{self.metric} gives no {self.quantity!r}; it gives {', '.join(known)}")
        if self.stage is not None and (not self.stage or "/" in self.stage):
            raise ValueError(f"a stage is a non-empty word without '/', got {self.stage!r}")

    @property
    def key(self) -> str:
        """The key of the number in its metric's ``compute()`` (``"f1@0.5"``)."""
        return metric_key(self.quantity, self.threshold)

    def __str__(self) -> str:
        bare = f"{self.metric}_{self.key}"
        return bare if self.stage is None else f"{self.stage}/{bare}"


def metric_key(quantity: str, threshold: float | None = None) -> str:
    """A number's key in a metric's ``compute()`` and in the paper tables' columns: ``"f1"``, ``"f1@0.5"``."""
    return quantity if threshold is None else f"{quantity}@{float(threshold):g}"


def parse_metric_key(key: str) -> tuple[str, float | None]:
    """``(quantity, threshold)`` of a `metric_key` (``"f1@0.5"`` -> ``("f1", 0.5)``; ``"fp"`` -> ``("fp", None)``).

    Raises:
        ValueError: a threshold that is not a number.
    """
    quantity, at, threshold = key.partition("@")
    if not at:
        return quantity, None
    try:
        return quantity, float(threshold)
    except ValueError:
        raise ValueError(f"{key!r}: the threshold after '@' must be a number") from None


def metric_name(metric: str, quantity: str, threshold: float | None = None, *, stage: str | None = None) -> str:
    """The name of a metric's number: ``metric_name("culane", "f1", 0.5)`` -> ``"culane_f1@0.5"``; with
    ``stage="val"``, ``"val/culane_f1@0.5"`` (what `LaneEvalCallback` logs).

    Raises:
        ValueError: an unknown metric or quantity, or a threshold missing or given where none belongs.
    """
    return str(MetricName(metric, quantity, None if threshold is None else float(threshold), stage))


def parse_metric_name(name: str) -> MetricName:
    """The parts of a name `metric_name` writes (``"val/culane_f1@0.5"``, ``"tusimple_f1"``).

    Raises:
        ValueError: a name `metric_name` would not write (unknown metric or quantity, ``@0.50`` for ``@0.5``).
    """
    stage, slash, bare = name.rpartition("/")
    metric, underscore, key = bare.partition("_")
    if not underscore:
        raise ValueError(f"{name!r} is not a metric name ({{metric}}_{{quantity}}[@threshold], e.g. tusimple_f1)")
    quantity, threshold = parse_metric_key(key)
    try:
        parsed = MetricName(metric, quantity, threshold, stage if slash else None)
    except ValueError as e:
        raise ValueError(f"{name!r}: {e}") from None
    if str(parsed) != name:
        raise ValueError(f"{name!r} is not written as the metrics write it: {str(parsed)!r}")
    return parsed
