"""Tables of an ablation: CSV, markdown (ours beside the paper's), the Table 6-like robustness split, and a
bar plot with error bars.

Accuracy and F1 are printed in percent like the paper; FP and FN as fractions. Cells are
``mean ± std`` over seeds (sample std); a single seed prints the mean alone.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

from stamlane.experiments.results import RowSummary
from stamlane.experiments.tables import PaperRow, PaperTable

__all__ = ["COLUMNS", "plot_table", "robustness_markdown", "table_markdown", "write_csv"]

SPLITS = ("test", "challenging", "delta")
"""Splits of a summary: the test split, the challenging split, and their paired difference per seed."""

# (metric name as logged, header, percent?) per metric kind
COLUMNS: dict[str, tuple[tuple[str, str, bool], ...]] = {
    "tusimple": (
        ("tusimple_f1", "F1 (%)", True),
        ("tusimple_accuracy", "Acc (%)", True),
        ("tusimple_fp", "FP", False),
        ("tusimple_fn", "FN", False),
        ("culane_f1@0.5", "IoU F1@0.5 (%)", True),
    ),
    "iou": (
        ("culane_precision@0.5", "P@0.5", False),
        ("culane_recall@0.5", "R@0.5", False),
        ("culane_f1@0.5", "F1@0.5", False),
        ("culane_precision@0.3", "P@0.3", False),
        ("culane_recall@0.3", "R@0.3", False),
        ("culane_f1@0.3", "F1@0.3", False),
    ),
}


def _fmt(value: float | None, percent: bool) -> str:
    if value is None or math.isnan(value):
        return "–"
    return f"{value * 100:.2f}" if percent else f"{value:.4f}"


def _cell(stat: tuple[float, float] | None, percent: bool) -> str:
    if stat is None:
        return "–"
    mean, std = stat
    if math.isnan(std):
        return _fmt(mean, percent)
    return f"{_fmt(mean, percent)} ± {_fmt(std, percent)}"


def _md_table(header: list[str], lines: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(cells) + " |" for cells in lines]
    return "\n".join(out) + "\n"


def table_markdown(table: PaperTable, rows: Sequence[PaperRow], summaries: dict[str, RowSummary]) -> str:
    """Markdown of one table: our metrics on the test split (mean ± std over seeds) beside the paper's.

    Args:
        table: the paper table.
        rows: its rows to print, in order.
        summaries: ``{row id: summary}``; a row without one prints "not run".
    """
    cols = COLUMNS[table.kind]
    paper_cols = [c for c in cols if any(c[0] in r.paper for r in rows)]
    header = ["Row", "Config", "Seeds", *[c[1] for c in cols], *[f"paper {c[1]}" for c in paper_cols]]
    lines = []
    for row in rows:
        s = summaries.get(row.id)
        if s is None or not s.seeds:
            ours = ["not run"] + ["–"] * (len(cols) - 1)
            n = "0"
        else:
            ours = [_cell(s.get("test", key), pct) for key, _, pct in cols]
            n = str(len(s.seeds))
        paper = [_fmt(row.paper.get(key), pct) for key, _, pct in paper_cols]
        lines.append([row.label, f"`{row.id}`", n, *ours, *paper])
    return f"**Table {table.name}: {table.title}**\n\n" + _md_table(header, lines)


def robustness_markdown(table: PaperTable, rows: Sequence[PaperRow], summaries: dict[str, RowSummary]) -> str:
    """Markdown of the robustness split (like the paper's Table 6): F1 on the test split, on the
    challenging split, and ΔF1 = challenging - test (per seed, then mean ± std). Rows without a
    challenging result are left out; an empty string when there are none."""
    key = table.f1_key
    pct = table.kind == "tusimple"
    unit = " (%)" if pct else ""
    lines = []
    for row in rows:
        s = summaries.get(row.id)
        if s is None or s.get("challenging", key) is None:
            continue
        cells = [_cell(s.get(split, key), pct) for split in SPLITS]
        lines.append([row.label, f"`{row.id}`", str(len(s.seeds)), *cells])
    if not lines:
        return ""
    header = ["Row", "Config", "Seeds", f"F1 all{unit}", f"F1 challenging{unit}", f"ΔF1{unit}"]
    return f"**Table {table.name}, robustness (all vs challenging clips, like Table 6)**\n\n" + _md_table(header, lines)


def write_csv(path: str | Path, table: PaperTable, rows: Sequence[PaperRow], summaries: dict[str, RowSummary]) -> None:
    """One line per row: ids, seeds, ``{split}/{metric}_mean`` and ``_std`` of every logged metric and
    split, and ``paper/{metric}``. Blank where a value is missing."""
    metrics = sorted(
        {
            (split, name)
            for s in summaries.values()
            for split, values in s.mean.items()
            if split in SPLITS
            for name in values
        },
        key=lambda sm: (SPLITS.index(sm[0]), sm[1]),
    )
    paper = sorted({k for r in rows for k in r.paper})
    header = ["table", "row", "label", "n_seeds", "seeds"]
    header += [f"{split}/{name}_{stat}" for split, name in metrics for stat in ("mean", "std")]
    header += [f"paper/{k}" for k in paper]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for row in rows:
            s = summaries.get(row.id)
            line: list[object] = [table.name, row.id, row.label]
            line += [len(s.seeds), " ".join(map(str, s.seeds))] if s else [0, ""]
            for split, name in metrics:
                stat = s.get(split, name) if s else None
                line += ["", ""] if stat is None else ["" if math.isnan(v) else f"{v:.6g}" for v in stat]
            line += [f"{row.paper[k]:.6g}" if k in row.paper else "" for k in paper]
            writer.writerow(line)


def plot_table(
    path: str | Path, table: PaperTable, rows: Sequence[PaperRow], summaries: dict[str, RowSummary], subtitle: str = ""
) -> bool:
    """Bar plot of the headline F1 per row (test and, where run, challenging split) with ±std error bars.

    Returns:
        False when no row has a result (nothing is written).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    done = [r for r in rows if r.id in summaries and summaries[r.id].get("test", table.f1_key) is not None]
    if not done:
        return False
    scale = 100.0 if table.kind == "tusimple" else 1.0
    splits = [sp for sp in ("test", "challenging") if any(summaries[r.id].get(sp, table.f1_key) for r in done)]
    width = 0.8 / len(splits)
    fig, ax = plt.subplots(figsize=(max(6.0, 0.9 * len(done) + 2), 4.2))
    for i, split in enumerate(splits):
        means, errs = [], []
        for r in done:
            stat = summaries[r.id].get(split, table.f1_key)
            means.append(stat[0] * scale if stat else math.nan)
            errs.append(0.0 if stat is None or math.isnan(stat[1]) else stat[1] * scale)
        xs = [j + (i - (len(splits) - 1) / 2) * width for j in range(len(done))]
        ax.bar(xs, means, width, yerr=errs, capsize=3, label="all test clips" if split == "test" else "challenging")
    ax.set_xticks(range(len(done)))
    ax.set_xticklabels([r.label for r in done], rotation=30, ha="right", fontsize=8)
    ax.set_ylabel(("F1 (%)" if scale == 100.0 else "F1") + (" @ IoU 0.5" if table.kind == "iou" else ""))
    ax.set_title(f"Table {table.name}: {table.title}" + (f"\n{subtitle}" if subtitle else ""), fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True
