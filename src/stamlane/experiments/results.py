"""Per-run result files and their summary over seeds (mean ± sample std).

A finished run (one row, one seed) leaves ``<out>/runs/<row id>/seed<k>/result.json``; its presence is
what makes ``stamlane ablate`` skip the run next time. The file holds the test metrics of every split
(``"test"``, ``"challenging"``) under the names `LaneEvalCallback` logs, without the ``test/`` prefix.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["RowSummary", "load_result", "result_path", "run_dir", "save_result", "summarize"]


def run_dir(out: str | Path, row_id: str, seed: int) -> Path:
    """Folder of one run: ``<out>/runs/<row id>/seed<seed>``."""
    return Path(out) / "runs" / row_id / f"seed{seed}"


def result_path(out: str | Path, row_id: str, seed: int) -> Path:
    """``result.json`` of one run (exists only when the run finished)."""
    return run_dir(out, row_id, seed) / "result.json"


def save_result(path: str | Path, result: dict[str, Any]) -> None:
    """Write ``result`` as json atomically (a killed process never leaves a half-written result)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(result, indent=2, sort_keys=True))
    os.replace(tmp, path)


def load_result(path: str | Path) -> dict[str, Any] | None:
    """The result of a finished run, or None when it has not finished (no file)."""
    path = Path(path)
    if not path.is_file():
        return None
    return json.loads(path.read_text())


@dataclass
class RowSummary:
    """Metrics of one row over its finished seeds.

    Attributes:
        row_id: the row's id.
        seeds: the seeds with a result, sorted.
        mean: ``{split: {metric: mean}}``.
        std: ``{split: {metric: sample std (ddof 1)}}``; NaN with a single seed.
    """

    row_id: str
    seeds: list[int]
    mean: dict[str, dict[str, float]] = field(default_factory=dict)
    std: dict[str, dict[str, float]] = field(default_factory=dict)

    def get(self, split: str, metric: str) -> tuple[float, float] | None:
        """``(mean, std)`` of a metric on a split, or None when no run logged it."""
        if metric not in self.mean.get(split, {}):
            return None
        return self.mean[split][metric], self.std[split][metric]


def _mean_std(values: list[float]) -> tuple[float, float]:
    n = len(values)
    mean = sum(values) / n
    if n < 2:
        return mean, math.nan
    return mean, math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1))


def _with_delta(metrics: dict[str, dict[str, float] | None]) -> dict[str, dict[str, float] | None]:
    test, hard = metrics.get("test") or {}, metrics.get("challenging") or {}
    common = [k for k in test if k in hard and test[k] is not None and hard[k] is not None]
    if not common:
        return dict(metrics)
    return {**metrics, "delta": {k: float(hard[k]) - float(test[k]) for k in common}}


def summarize(row_id: str, results: dict[int, dict[str, Any]]) -> RowSummary:
    """Mean and sample standard deviation over seeds of every metric of every split.

    Args:
        row_id: the row's id.
        results: ``{seed: result dict}`` of the finished runs (see `save_result`).

    Returns:
        the summary; a metric missing from some seeds is averaged over the seeds that have it. When a run
        has both ``"test"`` and ``"challenging"`` metrics, the split ``"delta"`` holds their paired
        difference (challenging - test) per seed, summarised like the others.
    """
    results = {seed: {"metrics": _with_delta(r.get("metrics", {}))} for seed, r in results.items()}
    summary = RowSummary(row_id, sorted(results))
    splits = sorted({s for r in results.values() for s in r.get("metrics", {})})
    for split in splits:
        names = sorted({m for r in results.values() for m in (r["metrics"].get(split) or {})})
        for name in names:
            values = [
                float(r["metrics"][split][name])
                for r in results.values()
                if (r["metrics"].get(split) or {}).get(name) is not None
            ]
            mean, std = _mean_std(values)
            summary.mean.setdefault(split, {})[name] = mean
            summary.std.setdefault(split, {})[name] = std
    return summary
