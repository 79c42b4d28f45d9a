"""The pictures of an experiment summary: history use against the labels' headroom (`plot_reveal`), per challenging
factor (`plot_history_use`), validation curves of the runs (`plot_val_curves`), and the one series style they
share (colour-blind-safe colours, markers and line styles: `series_style`)."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypedDict

import numpy as np
from stamlane_eval.names import metric_name

from stamlane.experiments.metrics import TUSIMPLE_F1
from stamlane.experiments.summary import Difference, Summary
from stamlane.experiments.tables import REVEAL_SPLITS, headroom
from stamlane.safety.guard import atomic_path

__all__ = [
    "NEUTRAL",
    "QUIET_POINTS",
    "SERIES_COLOURS",
    "SERIES_LINES",
    "SERIES_MARKERS",
    "RevealPoint",
    "SeriesStyle",
    "plot_history_use",
    "plot_reveal",
    "plot_val_curves",
    "reveal_points",
    "series_style",
]

QUIET_POINTS = 2.0
"""`plot_reveal` names a challenging factor only where its headroom or a model's history use reaches this many F1
points: the factors with neither crowd the origin, and their names would cover each other."""


SERIES_COLOURS = ("blue", "orange", "bluish green", "vermillion", "sky blue", "reddish purple", "black")
"""The Okabe-Ito colours plots give their series, in order (`stamlane.predict.overlay.OKABE_ITO`; its yellow is
left out: faint on white)."""


SERIES_MARKERS = ("o", "s", "^", "D")


SERIES_LINES = ("-", "--", ":", "-.")


NEUTRAL = "#888888"
"""The colour of what is not a model's series (an oracle's headroom, a reference line)."""


class SeriesStyle(TypedDict):
    """Keyword arguments of matplotlib's ``plot`` that draw one series (`series_style`)."""

    color: str
    marker: str
    linestyle: str


def series_style(k: int) -> SeriesStyle:
    """The matplotlib ``color``, ``marker`` and ``linestyle`` of the ``k``-th series of a plot: a colour-blind-safe
    colour (`SERIES_COLOURS`), a marker of its own beside its neighbours' (series that overlap stay apart), and
    past the colours another line style: no two of the first 28 series look alike."""
    from stamlane.predict.overlay import OKABE_ITO

    r, g, b = OKABE_ITO[SERIES_COLOURS[k % len(SERIES_COLOURS)]]
    return {
        "color": f"#{r:02x}{g:02x}{b:02x}",
        "marker": SERIES_MARKERS[k % len(SERIES_MARKERS)],
        "linestyle": SERIES_LINES[k // len(SERIES_COLOURS) % len(SERIES_LINES)],
    }


@dataclass(frozen=True)
class RevealPoint:
    """One point of `plot_reveal`: a multi-frame model's history use on a view against the labels' headroom at
    THAT model's clip length (a 2-frame model is placed by what one history frame can show, not four)."""

    model: str
    view: str
    frames: int
    headroom: Difference
    use: Difference


def reveal_points(summary: Summary) -> list[RevealPoint]:
    """Every (multi-frame model, reveal kind or challenging factor) with both its history use (real − key copied,
    TuSimple F1) and the headroom of its own span (aligned history oracle of ``frames`` frames − key oracle)."""
    views = [v for v in summary.views() if ":" in v and v.split(":")[0] in ("challenging", *REVEAL_SPLITS)]
    found = []
    for m in (m for m in summary.models if m.probes):
        for view in views:
            room = headroom(summary, view, m.frames)
            use = summary.difference(m.name, f"{m.name}@key", view, TUSIMPLE_F1.key)
            if room is not None and use is not None:
                found.append(RevealPoint(m.name, view, m.frames, room, use))
    return found


def plot_reveal(summary: Summary, path: Path) -> Path | None:
    """History use (real − key copied, TuSimple F1 points, clip intervals) of each multi-frame model per kind of
    the reveal splits and per challenging factor, against the headroom of the labels at the model's own clip
    length (`reveal_points`): a model that reads what its history shows lies near the diagonal; None without
    probes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    multi = [m for m in summary.models if m.probes]
    if not multi:
        return None
    points = reveal_points(summary)
    fig, ax = plt.subplots(figsize=(7, 5))
    top = 5.0
    named: set[str] = set()  # each view named once, beside its highest point; quiet challenging factors unnamed
    labels: list[tuple[str, float, float]] = []
    for colour, m in enumerate(multi):
        for p in (p for p in points if p.model == m.name):
            x, y = 100 * p.headroom.diff, 100 * p.use.diff
            err = [[100 * (p.use.diff - p.use.ci95[0])], [100 * (p.use.ci95[1] - p.use.diff)]]
            marker = "o" if p.view.startswith("challenging") else "s"
            ax.errorbar(x, y, yerr=err, fmt=marker, color=series_style(colour)["color"], capsize=2, alpha=0.85)
            quiet = p.view.startswith("challenging") and x < QUIET_POINTS and abs(y) < QUIET_POINTS
            if p.view not in named and not quiet:
                highest = max(100 * q.use.diff for q in points if q.view == p.view)
                labels.append((p.view.split(":")[1], x, highest))
                named.add(p.view)
            top = max(top, x, y)
        ax.plot([], [], "s", color=series_style(colour)["color"], label=m.label)
    placed: list[tuple[float, float]] = []  # names that would cover one another are moved down, one line at a time
    for text, x, y in sorted(labels, key=lambda label: -label[2]):
        while any(abs(x - px) < 0.15 * top and abs(y - py) < 0.035 * top for px, py in placed):
            y -= 0.04 * top
        placed.append((x, y))
        ax.annotate(text, (x, y), fontsize=7, xytext=(5, 2), textcoords="offset points")
    ax.plot([0, top], [0, top], color=NEUTRAL, linestyle="--", linewidth=0.8, label="history use = headroom")
    ax.axhline(0, color="grey", linewidth=0.6)
    spans = sorted({m.frames for m in multi})
    span = f"{spans[0]} frames" if len(spans) == 1 else "each model's clip length"
    ax.set_xlabel(f"headroom of the labels, {span} (F1 points)")
    ax.set_ylabel("history use: real − key copied (F1 points)")
    ax.set_title(
        "History use against headroom (squares: reveal kinds, dots: challenging factors;\n"
        f"unnamed dots: factors within {QUIET_POINTS:g} points of 0 on both axes)",
        fontsize=9,
    )
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_path(path) as tmp:  # a picture whole or not at all (the temporary name keeps the suffix)
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path


def plot_history_use(summary: Summary, path: Path) -> Path | None:
    """A bar chart: per factor of the challenging split, each multi-frame model's history use (TuSimple F1 points,
    real minus key frame copied, with its clip interval) beside the headroom of the labels; None without probes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    multi = [m for m in summary.models if m.probes]
    if not multi:
        return None
    views = ["challenging", *(v for v in summary.views() if v.startswith("challenging:"))]
    series = []
    frames = max(m.frames for m in multi)
    series.append(("headroom (oracle)", [headroom(summary, v, frames) for v in views]))
    series += [
        (m.label, [summary.difference(m.name, f"{m.name}@key", v, TUSIMPLE_F1.key) for v in views]) for m in multi
    ]
    fig, ax = plt.subplots(figsize=(10, 4))
    width = 0.8 / len(series)
    for k, (name, diffs) in enumerate(series):
        x = np.arange(len(views)) + (k - (len(series) - 1) / 2) * width
        y = [100 * d.diff if d else np.nan for d in diffs]
        err = np.array([[100 * (d.diff - d.ci95[0]), 100 * (d.ci95[1] - d.diff)] if d else [0, 0] for d in diffs]).T
        colour = NEUTRAL if k == 0 else series_style(k - 1)["color"]  # the headroom first, then each model
        ax.bar(x, y, width, yerr=err, capsize=2, label=name, color=colour, hatch="//" if k == 0 else None)
    ax.axhline(0, color="grey", linewidth=0.8)
    ax.set_xticks(np.arange(len(views)), [v.split(":")[-1] for v in views], rotation=20)
    ax.set_ylabel("F1 points: real history − key frame copied")
    ax.set_title("Does the model read its history? (challenging split, 95 % intervals over clips)")
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    with atomic_path(path) as tmp:  # a picture whole or not at all (the temporary name keeps the suffix)
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path


def plot_val_curves(out: Path, runs: Sequence[tuple[str, str, int]], seeds: Sequence[int], path: Path) -> Path:
    """Validation F1 over training steps of the runs ``(name, label, first step)`` of an experiment folder, one line
    per run and seed (from each run's ``metrics.csv``), one colour per run; a dotted line where a second stage
    starts."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from stamlane.experiments.store import RunStore
    from stamlane.safety.budget import MAX_RECORD_BYTES
    from stamlane.safety.guard import read_inside

    store = RunStore(out)
    f1 = metric_name("tusimple", "f1", stage="val")  # as the callback logs it
    fig, ax = plt.subplots(figsize=(7, 4))
    for colour, (name, label, first) in enumerate(runs):
        labelled = False
        for seed in seeds:
            metrics = store.run_dir(store.run_name(name, seed)) / "metrics.csv"
            # a record of the run folder: read only inside it, bounded (a link out of it or a FIFO is refused)
            text = read_inside(metrics, metrics.parent, MAX_RECORD_BYTES, "metrics") if metrics.is_file() else ""
            rows = list(csv.DictReader(text.splitlines()))
            points = [(int(r["step"]) + 1 + first, float(r[f1])) for r in rows if r.get(f1)]
            if points:
                seeds_label = f"{label} ({len(seeds)} seeds)" if len(seeds) > 1 else label
                ax.plot(*zip(*points), **series_style(colour), alpha=0.8, label=None if labelled else seeds_label)
                labelled = True
    for start in {first for _, _, first in runs if first}:
        ax.axvline(start, color=NEUTRAL, linestyle=":", linewidth=1)
    ax.set(xlabel="training step (a second stage right of the dotted line)", ylabel="validation F1 (TuSimple)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return path
