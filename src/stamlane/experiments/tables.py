"""Markdown tables of one experiment summary: what ``stamlane demo`` prints, what ``stamlane report`` writes.

Markdown throughout (it reads as well in a terminal as in docs/results.md). Numbers are percent: a value is
``mean ± std over seeds [95 % interval, clips resampled]``; a difference ``+d [clips] s[seeds]``, **bold** where
every interval excludes 0 (the only differences the docs claim). `tables` gives one summary's models, their
history use, the paired differences, every factor with its headroom, and the recall per visibility class;
`write_csv` the same numbers for spreadsheets. The paper's tables are `stamlane.experiments.paper_report`, the
plots `stamlane.experiments.plots`.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from stamlane_eval.names import parse_metric_name

from stamlane.experiments.metrics import CLASS_RECALL, CULANE_F1, TEMPORAL_STABILITY, TUSIMPLE_F1
from stamlane.experiments.summary import Difference, ModelEntry, Summary, Value

__all__ = [
    "NO_HEADROOM",
    "PROBE_COLUMNS",
    "REVEAL_SPLITS",
    "SPAN_COLUMNS",
    "SPLITS",
    "diff_text",
    "headroom",
    "markdown_table",
    "reads_history",
    "tables",
    "value_text",
    "write_csv",
]

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


SPAN_COLUMNS = ((2, 1), (4, 1), (8, 1), (2, 2), (4, 2), (8, 2))


NO_HEADROOM = 0.01
"""Below this headroom (1 F1 point, history oracle minus key-frame oracle) a factor is marked as one where history
cannot show: the fitted lines already bridge what the key frame does not show."""


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


def reads_history(summary: Summary, model: str, view: str, metric: str = TUSIMPLE_F1.key) -> bool:
    """A model is said to read its history on a view only where its history use (real history minus the key
    frame copied) is positive and both its intervals (clips, seeds) exclude 0."""
    d = summary.difference(model, f"{model}@key", view, metric)
    return d is not None and d.diff > 0 and d.supported


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """A markdown table: the header row, its rule, one row per cell list, then an empty line."""
    return [
        "| " + " | ".join(header) + " |",
        "|" + "---|" * len(header),
        *("| " + " | ".join(r) + " |" for r in rows),
        "",
    ]


def _kept(summary: Summary, only: Sequence[str] | None) -> list[ModelEntry]:
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
    iou = CULANE_F1[0].key
    lines += markdown_table(
        [
            "model",
            "frames",
            "test F1",
            "challenging F1",
            f"test {CULANE_F1[0].label}",
            f"challenging {CULANE_F1[0].label}",
        ],
        [
            [
                m.label,
                str(m.frames),
                *(value_text(summary.value(m.name, TUSIMPLE_F1.key, s)) for s in SPLITS),
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
            for metric in (TUSIMPLE_F1.key, iou):
                cells = [diff_text(summary.difference(a, b, s, metric)) for s in SPLITS]
                rows.append([f"{label[a]} − {label[b]}", metric, *cells])
        lines += [
            "Paired differences between models (points):",
            "",
            *markdown_table(["models", "metric", *SPLITS], rows),
        ]
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


def _reveal(summary: Summary, models: list[ModelEntry], pairs: list[tuple[str, str]]) -> list[str]:
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
    for metric in (TUSIMPLE_F1.key, CULANE_F1[0].key):
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
        lines += [
            f"{metric}:",
            "",
            *markdown_table(["view", "key", "aligned", "unaligned", "headroom", "alignment"], rows),
        ]
    for metric in (TUSIMPLE_F1.key, CULANE_F1[0].key):
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
            *markdown_table(header, rows),
        ]
    rows = []
    for a, b in pairs:
        for metric in (TUSIMPLE_F1.key, CULANE_F1[0].key):
            rows.append([f"{a} − {b}", metric, *(diff_text(summary.difference(a, b, v, metric)) for v in views)])
    if rows:
        lines += ["Paired differences between models on the reveal splits (points):", ""]
        lines += markdown_table(["models", "metric", *(f"`{v}`" for v in views)], rows)
    kinds = sum(":" in v for v in views)
    lines += [_multiple_note(kinds * (len(PROBE_COLUMNS) + 2) * max(len(multi), 1)), ""]
    return lines


def _spans(summary: Summary) -> list[str]:
    """Headroom (aligned history oracle − key-frame oracle, TuSimple F1) per span on every split with masks."""
    splits = [v for v in summary.views() if ":" not in v and summary.value("oracle:key", TUSIMPLE_F1.key, v)]
    if not splits:
        return []
    rows = []
    for split in splits:
        key = summary.value("oracle:key", TUSIMPLE_F1.key, split)
        row = [f"`{split}`", value_text(key)]
        for t, stride in SPAN_COLUMNS:
            subject = _oracle("history", t, stride)
            v, d = (
                summary.value(subject, TUSIMPLE_F1.key, split),
                summary.difference(subject, "oracle:key", split, TUSIMPLE_F1.key),
            )
            row.append(f"{value_text(v)} ({diff_text(d)})" if v else "– (beyond the masks)")
        rows.append(row)
    header = ["split", "key oracle", *(f"T={t}" + (f" every {s}" if s > 1 else "") for t, s in SPAN_COLUMNS)]
    return [
        "Headroom per span, from the labels (TuSimple F1 %): the aligned history oracle of T frames taken every "
        "s-th, and in brackets its difference to the key-frame oracle; frames at 20 fps (`reveal-traffic`: 5 fps):",
        "",
        *markdown_table(header, rows),
    ]


def _history_use(summary: Summary, models: list[ModelEntry]) -> list[str]:
    if not models:
        return []
    rows = []
    for m in models:
        for metric in (TUSIMPLE_F1.key, CULANE_F1[0].key):
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
        *markdown_table(
            ["model", "metric", "split", "real − key copied", "real − another clip's", "reads its history"], rows
        ),
    ]


def headroom(summary: Summary, view: str, frames: int) -> Difference | None:
    """What ``frames`` frames of aligned history can show on ``view`` beyond the key frame: the history oracle minus
    the key-frame oracle (TuSimple F1); None where the summary has no oracles."""
    return summary.difference(f"oracle:history-{frames}f", "oracle:key", view, TUSIMPLE_F1.key)


def _factors(summary: Summary, models: list[ModelEntry], pairs: list[tuple[str, str]]) -> list[str]:
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
        first = summary.value(models[0].name, TUSIMPLE_F1.key, view)
        row = [f"`{view.split(':', 1)[1]}`", str(first.images if first else "–")]
        if frames:
            h = headroom(summary, view, frames)
            note = " (no headroom: history cannot show here)" if h is not None and h.diff < NO_HEADROOM else ""
            row.append(diff_text(h) + note)
        row += [value_text(summary.value(m.name, TUSIMPLE_F1.key, view)) for m in models]
        row += [diff_text(summary.difference(m.name, f"{m.name}@key", view, TUSIMPLE_F1.key)) for m in multi]
        row += [diff_text(summary.difference(a, b, view, TUSIMPLE_F1.key)) for a, b in pairs]
        rows.append(row)
    text = (
        "Challenging split per factor, TuSimple F1 (%); headroom = F1 of lanes fitted to the labelled points visible "
        "in the key frame or its aligned history minus to those visible in the key frame (what perfect use of the "
        "history can add):"
    )
    tested = len(factors) * (bool(frames) + len(multi) + len(pairs))
    return [text, "", *markdown_table(header, rows), _multiple_note(tested), ""]


def _recall(summary: Summary, models: list[ModelEntry]) -> list[str]:
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
        *markdown_table(["model", "split", "visible", "revealed", "hidden"], rows),
    ]


def _temporal(summary: Summary, models: list[ModelEntry], pairs: list[tuple[str, str]]) -> list[str]:
    frames = next(
        (v for v in summary.views() if ":" not in v and summary.value(models[0].name, TEMPORAL_STABILITY[0].key, v)),
        None,
    )
    if frames is None:
        return []
    first = summary.value(models[0].name, TEMPORAL_STABILITY[0].key, frames)
    assert first is not None  # frames is a view where this value was found
    rows = [[m.label, *(value_text(summary.value(m.name, t.key, frames)) for t in TEMPORAL_STABILITY)] for m in models]
    lines = [
        f"Temporal stability (RVLD's Rs / Rj / Rm, %): the clips of `{frames}` ({first.images} clips) predicted frame "
        "after frame, each frame with its own history; of the annotated lanes matched between consecutive frames, "
        "the share predicted above the IoU threshold in both frames (stable), in one (jump), in neither (missing):",
        "",
        *markdown_table(["model", *(t.label for t in TEMPORAL_STABILITY)], rows),
    ]
    probed = [m.name for m in models if summary.difference(m.name, f"{m.name}@key", frames, TEMPORAL_STABILITY[0].key)]
    if probed:  # history use: the same weights with the key frame copied into every history slot
        lines += ["`M − M@key`: the same weights with the key frame copied into every history slot (history use).", ""]
        pairs = [*pairs, *((name, f"{name}@key") for name in probed)]
    if pairs:
        keys = [t.key for t in TEMPORAL_STABILITY if parse_metric_name(t.key).quantity in ("rs", "rj")]
        diff_rows = [[f"{a} − {b}", *(diff_text(summary.difference(a, b, frames, k)) for k in keys)] for a, b in pairs]
        lines += markdown_table(["models", *keys], diff_rows)
    factors = [v for v in summary.views() if v.startswith(f"{frames}:")]
    if factors:
        key = TEMPORAL_STABILITY[0].key
        rows = [
            [f"`{v.split(':', 1)[1]}`", *(value_text(summary.value(m.name, key, v)) for m in models)]
            + [diff_text(summary.difference(a, b, v, key)) for a, b in pairs]
            for v in factors
        ]
        lines += [
            f"{TEMPORAL_STABILITY[0].label} per factor:",
            "",
            *markdown_table(["factor", *(m.label for m in models), *(f"{a} − {b}" for a, b in pairs)], rows),
        ]
    return lines


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
