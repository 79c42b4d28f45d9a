"""The paper's tables from experiment summaries (`paper_tables`), and the rows trained in several run sets side by
side (`replication`); the formatting of values and differences is `stamlane.experiments.tables`'."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from stamlane_eval.names import parse_metric_name

from stamlane.experiments.metrics import CULANE_F1, TUSIMPLE_F1
from stamlane.experiments.summary import Difference, Summary
from stamlane.experiments.table_index import PaperTable, TableIndex
from stamlane.experiments.tables import SPLITS, diff_text, markdown_table, value_text

__all__ = [
    "SINGLE_ROW",
    "STAM_ROW",
    "paper_tables",
    "replication",
]

SINGLE_ROW, STAM_ROW = "f1_keyonly", "f4_mixed_cs_features"
"""The paper rows every other row is compared with: one frame, and pre-aligned STAM (mixed C-S, the paper's
choice; the history-carrying reading)."""


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
        metrics = (TUSIMPLE_F1.key,) if table.kind == "tusimple" else tuple(m.key for m in CULANE_F1)
        for metric in metrics:
            lines += _paper_table(table, summaries, metric, splits)
    return "\n".join(lines)


def _paper_table(table: PaperTable, summaries: Sequence[Summary], metric: str, splits: Sequence[str]) -> list[str]:
    rows_in = [_by_row(s) for s in summaries]
    where: dict[str, int] = {}  # row -> the first run set that measured it in this metric
    for i, found in enumerate(rows_in):
        for row, name in found.items():
            if any(summaries[i].value(name, metric, s) for s in splits):
                where.setdefault(row, i)
    several = len(summaries) > 1
    what = "F1" if metric == TUSIMPLE_F1.key else f"IoU F1 @{parse_metric_name(metric).threshold:g}"

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
        f"**Table {table.name}: {table.title}**{'' if metric == TUSIMPLE_F1.key else ', ' + what} "
        f"({len(run)} of {len(table.rows)} rows run, {'/'.join(map(str, seeds))} seeds)"
    )
    return [title, "", *markdown_table(header, rows)]


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
                versus = " / ".join(
                    diff_text(summaries[i].difference(name, single, s, TUSIMPLE_F1.key)) for s in SPLITS
                )
            cells = [value_text(summaries[i].value(name, TUSIMPLE_F1.key, s)) for s in SPLITS]
            rows.append([f"{label.get(row, row)} (`{row}`)", str(i + 1), *cells, versus])
    lines = markdown_table(["row", "run set", "test F1", "challenging F1", "− 1 frame (test / chall.)"], rows)
    return "\n".join([*lines, *_agreement(summaries, rows_in)]) + "\n"


def _agreement(summaries: Sequence[Summary], rows_in: list[dict[str, str]]) -> list[str]:
    if len(summaries) < 2:
        return []
    pairs, claims = [], []
    for row in (set(rows_in[0]) & set(rows_in[1])) - {SINGLE_ROW}:
        found: list[Difference] = []
        for i in (0, 1):
            single = rows_in[i].get(SINGLE_ROW)
            difference = (
                summaries[i].difference(rows_in[i][row], single, "challenging", TUSIMPLE_F1.key) if single else None
            )
            if difference is not None:
                found.append(difference)
        if len(found) < 2:  # a set without this difference
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
