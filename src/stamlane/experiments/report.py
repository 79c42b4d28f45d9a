"""Tables of experiment summaries: what ``stamlane demo`` prints, what ``stamlane report`` writes.

Markdown throughout (it reads as well in a terminal as in docs/results.md). Numbers are percent: a value is
``mean ± std over seeds [95 % interval, clips resampled]``; a difference ``+d [clips] s[seeds]``, **bold** where
every interval excludes 0 (the only differences the docs claim). `tables` gives one summary's models, their
history use, the paired differences, every factor with its headroom, and the recall per visibility class;
`paper_tables` the paper's tables from one or several summaries (run sets); `replication` the rows trained in
several run sets side by side; `write_csv` and `plot_history_use` the same numbers for spreadsheets and eyes.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from stamlane_eval.names import metric_name, parse_metric_name

from stamlane.experiments.metrics import CLASS_RECALL, CULANE, TEMPORAL, TUSIMPLE
from stamlane.experiments.summary import Difference, Summary, Value
from stamlane.experiments.table_index import PaperTable, TableIndex

__all__ = [
    "SINGLE_ROW",
    "STAM_ROW",
    "RevealPoint",
    "paper_tables",
    "plot_history_use",
    "plot_reveal",
    "plot_val_curves",
    "reads_history",
    "replication",
    "reveal_points",
    "series_style",
    "tables",
    "write_csv",
]

SINGLE_ROW, STAM_ROW = "f1_keyonly", "f4_mixed_cs_features"
"""The paper rows every other row is compared with: one frame, and pre-aligned STAM (mixed C-S, the paper's
choice; the history-carrying reading)."""
SPLITS = ("test", "challenging")
REVEAL_SPLITS = ("reveal", "reveal-traffic")
"""The splits where the history reveals lanes (`stamlane.experiments.engine.REVEAL_SPLITS`)."""
PROBE_COLUMNS = (
    ("key", "real − key copied"),
    ("warped_key", "real − key warped out and back"),
    ("reversed", "real − reversed history"),
    ("other_clip", "real − another clip's"),
)
"""The history probes of the reveal tables, real minus probe; beside them the history aligned by the generator's
exact homographies minus ORB's, and minus the key frame copied (history use with exact alignment)."""
QUIET_POINTS = 2.0
"""`plot_reveal` names a challenging factor only where its headroom or a model's history use reaches this many F1
points: the factors with neither crowd the origin, and their names would cover each other."""
SPAN_COLUMNS = ((2, 1), (4, 1), (8, 1), (2, 2), (4, 2), (8, 2))
NO_HEADROOM = 0.01
"""Below this headroom (1 F1 point, history oracle minus key-frame oracle) a factor is marked as one where history
cannot show: the fitted lines already bridge what the key frame does not show."""


SERIES_COLOURS = ("blue", "orange", "bluish green", "vermillion", "sky blue", "reddish purple", "black")
"""The Okabe-Ito colours plots give their series, in order (`stamlane.predict.overlay.OKABE_ITO`; its yellow is
left out: faint on white)."""
SERIES_MARKERS = ("o", "s", "^", "D")
SERIES_LINES = ("-", "--", ":", "-.")
NEUTRAL = "#888888"
"""The colour of what is not a model's series (an oracle's headroom, a reference line)."""


def series_style(k: int) -> dict[str, str]:
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


def value_text(v: Value | None) -> str:
    if v is None:
        return "–"
    std = f" ± {100 * v.std:.1f}" if v.std is not None else ""
    ci = f" [{100 * v.ci95[0]:.1f}, {100 * v.ci95[1]:.1f}]" if v.ci95 else ""
    return f"{100 * v.mean:.1f}{std}{ci}"


def diff_text(d: Difference | None) -> str:
    if d is None:
        return "–"
    text = f"{100 * d.diff:+.1f} [{100 * d.ci95[0]:+.1f}, {100 * d.ci95[1]:+.1f}]"
    if d.seed_ci95:
        text += f" s[{100 * d.seed_ci95[0]:+.1f}, {100 * d.seed_ci95[1]:+.1f}]"
    return f"**{text}**" if d.supported else text


def reads_history(summary: Summary, model: str, view: str, metric: str = TUSIMPLE.key) -> bool:
    """A model is said to read its history on a view only where its history use (real history minus the key
    frame copied) is positive and both its intervals (clips, seeds) exclude 0."""
    d = summary.difference(model, f"{model}@key", view, metric)
    return d is not None and d.diff > 0 and d.supported


def _md(header: Sequence[str], rows: list[Sequence[str]]) -> list[str]:
    return [
        "| " + " | ".join(header) + " |",
        "|" + "---|" * len(header),
        *("| " + " | ".join(r) + " |" for r in rows),
        "",
    ]


def _kept(summary: Summary, only: Sequence[str] | None) -> list:
    if not only:
        return summary.models
    names = {m.name for m in summary.models}
    unknown = sorted(set(only) - names)
    if unknown:
        raise KeyError(f"no model {' '.join(unknown)} in the summary; models: {' '.join(sorted(names))}")
    return [m for m in summary.models if m.name in only]


def tables(summary: Summary, only: Sequence[str] | None = None) -> str:
    """Every table of one summary (see the module docstring); ``only``: just these models and their pairs."""
    models = _kept(summary, only)
    names = {m.name for m in models}
    label = {m.name: m.label for m in models}
    recipe = summary.recipe
    stages = (
        f"{recipe.get('pretrain_steps')} + {recipe.get('steps')}"
        if recipe.get("pretrain_steps")
        else recipe.get("steps")
    )
    lines = [
        f"Seeds {len(summary.seeds)} ({', '.join(map(str, summary.seeds))}); recipe {recipe.get('name')}, "
        f"{stages} steps per model; {'bfloat16' if summary.bf16 else 'float32'}. F1 % mean ± std over seeds "
        f"[95 % interval, clips resampled]; differences +d [clips] s[seeds], bold where both exclude 0.",
        "",
    ]
    iou = CULANE[0].key
    lines += _md(
        ["model", "frames", "test F1", "challenging F1", f"test {CULANE[0].label}", f"challenging {CULANE[0].label}"],
        [
            [
                m.label,
                str(m.frames),
                *(value_text(summary.value(m.name, TUSIMPLE.key, s)) for s in SPLITS),
                *(value_text(summary.value(m.name, iou, s)) for s in SPLITS),
            ]
            for m in models
        ],
    )
    lines += _history_use(summary, [m for m in models if m.probes])
    pairs = list(dict.fromkeys((d.a, d.b) for d in summary.differences if d.kind == "models" and {d.a, d.b} <= names))
    if pairs:
        rows = []
        for a, b in pairs:
            for metric in (TUSIMPLE.key, iou):
                cells = [diff_text(summary.difference(a, b, s, metric)) for s in SPLITS]
                rows.append([f"{label[a]} − {label[b]}", metric, *cells])
        lines += ["Paired differences between models (points):", "", *_md(["models", "metric", *SPLITS], rows)]
    lines += _factors(summary, models, pairs)
    lines += _reveal(summary, models, pairs)
    lines += _spans(summary)
    lines += _recall(summary, models)
    lines += _temporal(summary, models, pairs)
    return "\n".join(lines)


def _oracle(kind: str, frames: int, stride: int = 1) -> str:
    from stamlane.experiments.engine import oracle_subject

    return oracle_subject(kind, frames, stride)


def _multiple_note(cells: int) -> str:
    return (
        f"{cells} intervals per metric in these per-kind cells: at 95 % each, about {cells / 20:.1f} would exclude 0 "
        "by chance alone; a lone bold cell is weak evidence."
    )


def _reveal(summary: Summary, models: list, pairs: list[tuple[str, str]]) -> list[str]:
    """The reveal splits: the oracles' absolute values and differences, each model's value and its history probes."""
    views = [v for v in summary.views() if v.split(":")[0] in REVEAL_SPLITS]
    if not views:
        return []
    multi = [m for m in models if m.probes]
    frames = max((m.frames for m in multi), default=4)
    key, aligned, unaligned = (_oracle(k, frames) for k in ("key", "history", "unaligned"))
    lines = [
        f"Where the history reveals lanes (`reveal`: 12 frames, an occluder in the key frame alone, strong ego "
        f"motion; `reveal-traffic`: close and same-speed traffic at 5 fps, so {frames} frames span "
        f"{(frames - 1) / 5:.1f} s). Oracles: lanes fitted to the labelled points visible in the key frame (key), "
        f"or in it and its {frames - 1} history frames aligned (aligned) or unaligned (points only the history "
        "shows placed where that frame has them); absolute values, then headroom = aligned − key and alignment = "
        "aligned − unaligned (points):",
        "",
    ]
    for metric in (TUSIMPLE.key, CULANE[0].key):
        rows = []
        for view in views:
            rows.append(
                [
                    f"`{view}`",
                    *(value_text(summary.value(o, metric, view)) for o in (key, aligned, unaligned)),
                    diff_text(summary.difference(aligned, key, view, metric)),
                    diff_text(summary.difference(aligned, unaligned, view, metric)),
                ]
            )
        lines += [f"{metric}:", "", *_md(["view", "key", "aligned", "unaligned", "headroom", "alignment"], rows)]
    for metric in (TUSIMPLE.key, CULANE[0].key):
        rows = []
        for m in models:
            for view in views:
                row = [m.label, f"`{view}`", value_text(summary.value(m.name, metric, view))]
                if m.probes:
                    row += [
                        diff_text(summary.difference(m.name, f"{m.name}@{p}", view, metric)) for p, _ in PROBE_COLUMNS
                    ]
                    exact = f"{m.name}@exact"  # minus ORB's alignment, minus the key frame copied
                    row += [diff_text(summary.difference(exact, b, view, metric)) for b in (m.name, f"{m.name}@key")]
                else:
                    row += ["–"] * (len(PROBE_COLUMNS) + 2)
                rows.append(row)
        header = ["model", "view", "real history", *(label for _, label in PROBE_COLUMNS)]
        header += ["exact − ORB alignment", "exact − key copied"]
        lines += [
            f"Models on the reveal splits, {metric}: the same weights with their history probed (points); the key "
            "frame warped out through each history frame's homography and aligned back is the matched null (the "
            "blur and black wedges of real history, no new content):",
            "",
            *_md(header, rows),
        ]
    rows = []
    for a, b in pairs:
        for metric in (TUSIMPLE.key, CULANE[0].key):
            rows.append([f"{a} − {b}", metric, *(diff_text(summary.difference(a, b, v, metric)) for v in views)])
    if rows:
        lines += ["Paired differences between models on the reveal splits (points):", ""]
        lines += _md(["models", "metric", *(f"`{v}`" for v in views)], rows)
    kinds = sum(":" in v for v in views)
    lines += [_multiple_note(kinds * (len(PROBE_COLUMNS) + 2) * max(len(multi), 1)), ""]
    return lines


def _spans(summary: Summary) -> list[str]:
    """Headroom (aligned history oracle − key-frame oracle, TuSimple F1) per span on every split with masks."""
    splits = [v for v in summary.views() if ":" not in v and summary.value("oracle:key", TUSIMPLE.key, v)]
    if not splits:
        return []
    rows = []
    for split in splits:
        key = summary.value("oracle:key", TUSIMPLE.key, split)
        row = [f"`{split}`", value_text(key)]
        for t, stride in SPAN_COLUMNS:
            subject = _oracle("history", t, stride)
            v, d = (
                summary.value(subject, TUSIMPLE.key, split),
                summary.difference(subject, "oracle:key", split, TUSIMPLE.key),
            )
            row.append(f"{value_text(v)} ({diff_text(d)})" if v else "– (beyond the masks)")
        rows.append(row)
    header = ["split", "key oracle", *(f"T={t}" + (f" every {s}" if s > 1 else "") for t, s in SPAN_COLUMNS)]
    return [
        "Headroom per span, from the labels (TuSimple F1 %): the aligned history oracle of T frames taken every "
        "s-th, and in brackets its difference to the key-frame oracle; frames at 20 fps (`reveal-traffic`: 5 fps):",
        "",
        *_md(header, rows),
    ]


def _history_use(summary: Summary, models: list) -> list[str]:
    if not models:
        return []
    rows = []
    for m in models:
        for metric in (TUSIMPLE.key, CULANE[0].key):
            for split in SPLITS:
                key = summary.difference(m.name, f"{m.name}@key", split, metric)
                other = summary.difference(m.name, f"{m.name}@other_clip", split, metric)
                if key is None and other is None:
                    continue
                verdict = "yes" if reads_history(summary, m.name, split, metric) else "no"
                rows.append([m.label, metric, split, diff_text(key), diff_text(other), verdict])
    return [
        "History use: the same weights scored with their real history minus with the key frame copied into every "
        "history slot, and minus with another clip's history (points); a model reads its history where the "
        "first is positive and both its intervals exclude 0:",
        "",
        *_md(["model", "metric", "split", "real − key copied", "real − another clip's", "reads its history"], rows),
    ]


def _headroom(summary: Summary, view: str, frames: int) -> Difference | None:
    return summary.difference(f"oracle:history-{frames}f", "oracle:key", view, TUSIMPLE.key)


def _factors(summary: Summary, models: list, pairs: list[tuple[str, str]]) -> list[str]:
    factors = [v for v in summary.views() if v.startswith("challenging:")]
    if not factors:
        return []
    multi = [m for m in models if m.probes]
    frames = max((m.frames for m in multi), default=0)
    header = ["factor", "images", f"headroom ({frames} frames)"] if frames else ["factor", "images"]
    header += [m.label for m in models]
    header += [f"{m.name}: history use" for m in multi]
    header += [f"{a} − {b}" for a, b in pairs]
    rows = []
    for view in factors:
        first = summary.value(models[0].name, TUSIMPLE.key, view)
        row = [f"`{view.split(':', 1)[1]}`", str(first.images if first else "–")]
        if frames:
            h = _headroom(summary, view, frames)
            note = " (no headroom: history cannot show here)" if h is not None and h.diff < NO_HEADROOM else ""
            row.append(diff_text(h) + note)
        row += [value_text(summary.value(m.name, TUSIMPLE.key, view)) for m in models]
        row += [diff_text(summary.difference(m.name, f"{m.name}@key", view, TUSIMPLE.key)) for m in multi]
        row += [diff_text(summary.difference(a, b, view, TUSIMPLE.key)) for a, b in pairs]
        rows.append(row)
    text = (
        "Challenging split per factor, TuSimple F1 (%); headroom = F1 of lanes fitted to the labelled points visible "
        "in the key frame or its aligned history minus to those visible in the key frame (what perfect use of the "
        "history can add):"
    )
    tested = len(factors) * (bool(frames) + len(multi) + len(pairs))
    return [text, "", *_md(header, rows), _multiple_note(tested), ""]


def _recall(summary: Summary, models: list) -> list[str]:
    rows = []
    for m in models:
        for split in [v for v in summary.views() if ":" not in v or v.split(":")[0] in REVEAL_SPLITS]:
            cells = [value_text(summary.value(m.name, r.key, split)) for r in CLASS_RECALL]
            if any(c != "–" for c in cells):
                rows.append([m.label, split, *cells])
    if not rows:
        return []
    return [
        "Recall of labelled key-frame points by paint visibility (%): visible in the key frame / hidden there but "
        "visible in a history frame of the model's clip (revealed) / hidden in every frame:",
        "",
        *_md(["model", "split", "visible", "revealed", "hidden"], rows),
    ]


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
            headroom = _headroom(summary, view, m.frames)
            use = summary.difference(m.name, f"{m.name}@key", view, TUSIMPLE.key)
            if headroom is not None and use is not None:
                found.append(RevealPoint(m.name, view, m.frames, headroom, use))
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
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _temporal(summary: Summary, models: list, pairs: list[tuple[str, str]]) -> list[str]:
    frames = next(
        (v for v in summary.views() if ":" not in v and summary.value(models[0].name, TEMPORAL[0].key, v)), None
    )
    if frames is None:
        return []
    first = summary.value(models[0].name, TEMPORAL[0].key, frames)
    rows = [[m.label, *(value_text(summary.value(m.name, t.key, frames)) for t in TEMPORAL)] for m in models]
    lines = [
        f"Temporal stability (RVLD's Rs / Rj / Rm, %): the clips of `{frames}` ({first.images} clips) predicted frame "
        "after frame, each frame with its own history; of the annotated lanes matched between consecutive frames, "
        "the share predicted above the IoU threshold in both frames (stable), in one (jump), in neither (missing):",
        "",
        *_md(["model", *(t.label for t in TEMPORAL)], rows),
    ]
    probed = [m.name for m in models if summary.difference(m.name, f"{m.name}@key", frames, TEMPORAL[0].key)]
    if probed:  # history use: the same weights with the key frame copied into every history slot
        lines += ["`M − M@key`: the same weights with the key frame copied into every history slot (history use).", ""]
        pairs = [*pairs, *((name, f"{name}@key") for name in probed)]
    if pairs:
        keys = [t.key for t in TEMPORAL if parse_metric_name(t.key).quantity in ("rs", "rj")]
        diff_rows = [[f"{a} − {b}", *(diff_text(summary.difference(a, b, frames, k)) for k in keys)] for a, b in pairs]
        lines += _md(["models", *keys], diff_rows)
    factors = [v for v in summary.views() if v.startswith(f"{frames}:")]
    if factors:
        key = TEMPORAL[0].key
        rows = [
            [f"`{v.split(':', 1)[1]}`", *(value_text(summary.value(m.name, key, v)) for m in models)]
            + [diff_text(summary.difference(a, b, v, key)) for a, b in pairs]
            for v in factors
        ]
        lines += [
            f"{TEMPORAL[0].label} per factor:",
            "",
            *_md(["factor", *(m.label for m in models), *(f"{a} − {b}" for a, b in pairs)], rows),
        ]
    return lines


# ---------------------------------------------------------------------------------------------- paper tables
def _by_row(summary: Summary) -> dict[str, str]:
    """paper row id -> model name in ``summary``."""
    return {m.paper_row or m.name: m.name for m in summary.models}


def paper_tables(
    summaries: Sequence[Summary], index: TableIndex, which: Sequence[str], splits: Sequence[str] = SPLITS
) -> str:
    """The paper's tables ``which`` from summaries holding its rows (several summaries: run sets, each row taken
    from the first that has it and compared with one frame and STAM of THAT run set), one column per split of
    ``splits`` (``reveal reveal-traffic``: the splits where the history reveals lanes). An IoU table (7, 8) comes
    twice, at IoU 0.5 and 0.3; every row carries its history use where it was probed."""
    lines: list[str] = []
    for name in which:
        table = index.table(name)
        metrics = (TUSIMPLE.key,) if table.kind == "tusimple" else tuple(m.key for m in CULANE)
        for metric in metrics:
            lines += _paper_table(table, summaries, metric, splits)
    return "\n".join(lines)


def _paper_table(table: PaperTable, summaries: Sequence[Summary], metric: str, splits: Sequence[str]) -> list[str]:
    rows_in = [_by_row(s) for s in summaries]
    where = {}  # row -> the first run set that measured it in this metric
    for i, found in enumerate(rows_in):
        for row, name in found.items():
            if any(summaries[i].value(name, metric, s) for s in splits):
                where.setdefault(row, i)
    several = len(summaries) > 1
    what = "F1" if metric == TUSIMPLE.key else f"IoU F1 @{parse_metric_name(metric).threshold:g}"

    def versus(i: int, row: str, other: str | None) -> str:
        a, b = rows_in[i].get(row), rows_in[i].get(other) if other else None
        if a is None or b is None or a == b:
            return "–"
        return " / ".join(diff_text(summaries[i].difference(a, b, s, metric)) for s in splits)

    def history(i: int, row: str) -> str:
        name = rows_in[i][row]
        found = [summaries[i].difference(name, f"{name}@key", s, metric) for s in splits]
        return " / ".join(diff_text(d) for d in found) if any(found) else "–"

    run = [r for r in table.rows if r.id in where]
    seeds = sorted({len(s.seeds) for s in summaries})
    columns = " / ".join({"challenging": "chall."}.get(s, s) for s in splits)
    header = ["row", f"paper {what}", *(["run set"] if several else []), *splits]
    header += [f"− 1 frame ({columns})", f"− STAM ({columns})"]
    header += [f"− baseline ({columns})"] if table.baseline else []
    header += [f"history use ({columns})"]
    rows = []
    references = {SINGLE_ROW, STAM_ROW, table.baseline} - {None}
    used = {where[r.id] for r in run if r.id not in references}
    for r in table.rows:
        paper = f"{100 * r.paper[metric]:.2f}" if metric in r.paper else "–"
        if r.id not in where:
            blanks = [""] * (len(header) - 3 - several)
            rows.append([f"{r.label} (`{r.id}`)", paper, *([""] if several else []), "not run", *blanks])
            continue
        places = [where[r.id]]
        if r.id in references:  # shown for every run set the table's other rows are compared inside
            measured = {i for i, found in enumerate(rows_in) if r.id in found}
            places = sorted(({*used, *places} & measured) or set(places))
        for i in places:
            name = rows_in[i][r.id]
            cells = [f"{r.label} (`{r.id}`)", paper, *([str(i + 1)] if several else [])]
            cells += [value_text(summaries[i].value(name, metric, s)) for s in splits]
            cells += [versus(i, r.id, SINGLE_ROW), versus(i, r.id, STAM_ROW)]
            cells += [versus(i, r.id, table.baseline)] if table.baseline else []
            cells.append(history(i, r.id))
            rows.append(cells)
    title = (
        f"**Table {table.name}: {table.title}**{'' if metric == TUSIMPLE.key else ', ' + what} "
        f"({len(run)} of {len(table.rows)} rows run, {'/'.join(map(str, seeds))} seeds)"
    )
    return [title, "", *_md(header, rows)]


def replication(summaries: Sequence[Summary], index: TableIndex) -> str:
    """The rows trained in more than one run set, side by side (F1 and the difference from one frame), and how far
    the first two sets agree: the correlation of the rows' differences from one frame on the challenging clips,
    how often their signs agree, how many differences claimed in one set are claimed in the other."""
    label = {r.id: r.label for t in index.tables.values() for r in t.rows}
    rows_in = [_by_row(s) for s in summaries]
    rows = []
    for row in dict.fromkeys(r for found in rows_in for r in found):
        places = [i for i, found in enumerate(rows_in) if row in found]
        if len(places) < 2:
            continue
        for i in places:
            name, single = rows_in[i][row], rows_in[i].get(SINGLE_ROW)
            versus = "–"
            if single and single != name:
                versus = " / ".join(diff_text(summaries[i].difference(name, single, s, TUSIMPLE.key)) for s in SPLITS)
            cells = [value_text(summaries[i].value(name, TUSIMPLE.key, s)) for s in SPLITS]
            rows.append([f"{label.get(row, row)} (`{row}`)", str(i + 1), *cells, versus])
    lines = _md(["row", "run set", "test F1", "challenging F1", "− 1 frame (test / chall.)"], rows)
    return "\n".join([*lines, *_agreement(summaries, rows_in)]) + "\n"


def _agreement(summaries: Sequence[Summary], rows_in: list[dict[str, str]]) -> list[str]:
    if len(summaries) < 2:
        return []
    pairs, claims = [], []
    for row in (set(rows_in[0]) & set(rows_in[1])) - {SINGLE_ROW}:
        found = []
        for i in (0, 1):
            single = rows_in[i].get(SINGLE_ROW)
            found.append(
                summaries[i].difference(rows_in[i][row], single, "challenging", TUSIMPLE.key) if single else None
            )
        if None in found:
            continue
        pairs.append([d.diff for d in found])
        claimed = [d.supported for d in found]
        if any(claimed):
            claims.append(all(claimed) and np.sign(pairs[-1][0]) == np.sign(pairs[-1][1]))
    if len(pairs) < 3:
        return []
    d = np.array(pairs)
    r = float(np.corrcoef(d[:, 0], d[:, 1])[0, 1])
    same = int((np.sign(d[:, 0]) == np.sign(d[:, 1])).sum())
    return [
        f"Rows trained in run sets 1 and 2: {len(d)}. Their difference from one frame on the challenging clips, set 1 "
        f"against set 2: correlation {r:+.2f}, the same sign in {same} of {len(d)}, and {sum(claims)} of "
        f"{len(claims)} differences claimed in one set (both intervals exclude 0) claimed in the other."
    ]


# ---------------------------------------------------------------------------------------------- csv, plots
def write_csv(path: Path, summary: Summary) -> None:
    """Every value and difference of a summary, one line each (``kind, subject, b, view, metric, value, low, high,
    seed_low, seed_high, std, seeds``)."""
    from stamlane.safety.guard import atomic_path

    with atomic_path(path) as tmp, tmp.open("w", newline="") as f:  # written whole, then renamed
        w = csv.writer(f)
        w.writerow(
            ["kind", "subject", "b", "view", "metric", "value", "low", "high", "seed_low", "seed_high", "std", "seeds"]
        )
        subjects = [(m.name, m.values) for m in summary.models]
        subjects += [(f"{m.name}@{s}", v) for m in summary.models for s, v in m.probes.items()]
        subjects += list(summary.oracles.items())
        for subject, values in subjects:
            for metric, per_view in values.items():
                for view, v in per_view.items():
                    low, high = v.ci95 or (None, None)
                    w.writerow(["value", subject, "", view, metric, v.mean, low, high, "", "", v.std, v.seeds])
        for d in summary.differences:
            s_low, s_high = d.seed_ci95 or (None, None)
            w.writerow(
                [d.kind, d.a, d.b, d.view, d.metric, d.diff, d.ci95[0], d.ci95[1], s_low, s_high, "", len(d.seed_diffs)]
            )


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
    series.append(("headroom (oracle)", [_headroom(summary, v, frames) for v in views]))
    series += [(m.label, [summary.difference(m.name, f"{m.name}@key", v, TUSIMPLE.key) for v in views]) for m in multi]
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
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
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
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
