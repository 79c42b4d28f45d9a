"""Markdown tables of a ``stamlane demo`` summary (the ones in docs/results.md are made with this).

    python benchmarks/demo_tables.py outputs/demo/summary.json [--out docs/results/demo-cpu-recipe/tables.md]
    python benchmarks/demo_tables.py outputs/demo/summary.json --models stam4 single   # only these, and their pairs
    python benchmarks/demo_tables.py outputs/demo/summary.json --paper configs/paper/tables.yaml [--tables 2 3 4 7 8]
    python benchmarks/demo_tables.py SUMMARY_1 SUMMARY_2 --paper configs/paper/tables.yaml   # two run sets
    python benchmarks/demo_tables.py SUMMARY_1 SUMMARY_2 --paper configs/paper/tables.yaml --replication

Prints, in F1 %: each model's test and challenging F1 as mean ± seed std [95 % interval]; the paired
differences as ``+d [clips] s[seeds]`` (95 % intervals with the test clips resampled and over the training
seeds, Student t; bold where both exclude 0); per factor of the challenging split, each model's F1 and the
paired differences against the single frame (and aligned against unaligned). With ``--paper``: the paper's
tables instead, each row's F1 beside the paper's and its paired differences against one frame, against
pre-aligned STAM (mixed C-S, the paper's choice) and, in Tables 2 and 8, against the table's baseline row
(unaligned frames summed); Tables 7 and 8 (the paper's ApolloScape tables) in the demo's IoU F1, once at IoU 0.5
and once at 0.3. Rows not in the summary are listed as not run.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
from pathlib import Path


def _f1(m: dict) -> str:
    std = f" ± {100 * m['f1_std']:.1f}" if m.get("f1_std") is not None else ""
    ci = m.get("f1_ci95")
    interval = f" [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]" if ci else ""
    return f"{100 * m['f1_mean']:.1f}{std}{interval}"


def _diff(c: dict | None) -> str:
    """``+d [clips] s[seeds]`` in F1 points: the difference, its interval with the test clips resampled and, where
    there are several seeds, its interval over the training seeds; bold when every interval excludes 0."""
    if c is None:
        return "–"
    text = f"{100 * c['f1_diff']:+.1f} [{100 * c['ci95'][0]:+.1f}, {100 * c['ci95'][1]:+.1f}]"
    if c.get("seed_ci95"):
        text += f" s[{100 * c['seed_ci95'][0]:+.1f}, {100 * c['seed_ci95'][1]:+.1f}]"
    return f"**{text}**" if _supported(c) else text


def _supported(c: dict) -> bool:
    """A difference every interval of which (clips; seeds, where there are several) excludes 0: one we claim."""
    intervals = [c["ci95"], *([c["seed_ci95"]] if c.get("seed_ci95") else [])]
    return all(not low <= 0 <= high for low, high in intervals)


def _by_pair(summary: dict) -> dict[tuple[str, str, str], dict]:
    """The comparisons of a summary by (A, B, split)."""
    return {(c["a"], c["b"], c["split"]): c for c in summary["comparisons"]}


def _with_seed_interval(summary: dict) -> dict:
    """``summary`` whose comparisons of whole splits all carry ``seed_ci95``: a summary written before the demo
    kept per-seed differences gets them from its runs' own scores (per factor there are none to get)."""
    from stamlane_eval.stats import seed_interval

    summary = copy.deepcopy(summary)
    runs = {m["name"]: {r["seed"]: r for r in m.get("runs", [])} for m in summary["models"]}
    for c in summary["comparisons"]:
        if "seed_ci95" in c or c["split"] not in ("test", "challenging") or len(summary["seeds"]) < 2:
            continue
        a, b = runs[c["a"]], runs[c["b"]]
        c["seed_diffs"] = [a[s][c["split"]]["f1"] - b[s][c["split"]]["f1"] for s in sorted(a)]
        c["seed_ci95"] = list(seed_interval(c["seed_diffs"]).interval)
    return summary


def tables(summary: dict, only: list[str] | None = None) -> str:
    """The demo's tables; ``only``: just these models (names in the summary) and the comparisons among them."""
    summary = _with_seed_interval(summary)
    if only:
        unknown = sorted(set(only) - {m["name"] for m in summary["models"]})
        if unknown:
            raise SystemExit(f"demo_tables: no model {' '.join(unknown)} in the summary")
        summary["models"] = [m for m in summary["models"] if m["name"] in only]
        summary["comparisons"] = [c for c in summary["comparisons"] if c["a"] in only and c["b"] in only]
    models = summary["models"]
    seeds = len(summary["seeds"])
    lines = [
        f"Seeds {seeds} ({', '.join(map(str, summary['seeds']))}); {summary['steps']} steps per model "
        f"({summary['pretrain_steps']} + {summary['finetune_steps']}). F1 % mean ± std over seeds [95 % interval of "
        f"the seed-averaged per-image rates, clips resampled].",
        "",
        "| model | frames | test F1 | challenging F1 |",
        "|---|---|---|---|",
    ]
    lines += [f"| {m['label']} | {m['frames']} | {_f1(m['test'])} | {_f1(m['challenging'])} |" for m in models]
    by = _by_pair(summary)
    pairs = list(dict.fromkeys((c["a"], c["b"]) for c in summary["comparisons"]))
    label = {m["name"]: m["label"] for m in models}
    lines += ["", "| paired difference (F1 points) | test | challenging |", "|---|---|---|"]
    for a, b in pairs:
        lines.append(
            f"| {label[a]} − {label[b]} | {_diff(by.get((a, b, 'test')))} | {_diff(by.get((a, b, 'challenging')))} |"
        )
    factors = list(models[0].get("factors", {}))
    if factors:
        head = "| factor | images | " + " | ".join(m["label"] for m in models) + " | "
        head += " | ".join(f"{a} − {b}" for a, b in pairs) + " |"
        lines += ["", head, "|" + "---|" * (2 + len(models) + len(pairs))]
        for f in factors:
            cells = [_f1(m["factors"][f]) for m in models]
            cells += [_diff(by.get((a, b, f"challenging:{f}"))) for a, b in pairs]
            lines.append(f"| `{f}` | {models[0]['factors'][f]['images']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _paper_row(name: str) -> str:
    """The row of the paper's tables that the demo model ``name`` is."""
    from stamlane.demo import MODELS

    return next(m.paper for m in MODELS if m.name == name)


METRIC_COLUMNS = {"tusimple": (("tusimple", "f1"),), "iou": (("iou@0.5", "f1@0.5"), ("iou@0.3", "f1@0.3"))}
"""Per metric kind of the paper's tables: the demo's metric keys and the paper's column each is set beside."""


def _as_metric(summary: dict, key: str) -> dict:
    """``summary`` seen through the metric ``key``: each model's splits and factors and the comparisons are
    those of that metric (``"tusimple"``: the summary as it is; ``"iou@0.5"``: the IoU F1 at 0.5); models not
    scored with it (summaries written before the demo scored IoU) are left out."""
    if key == "tusimple":
        return summary
    view = copy.deepcopy(summary)
    view["models"] = [m | m[key] for m in summary["models"] if key in m]
    view["comparisons"] = [c for c in summary.get("iou_comparisons", []) if c["metric"] == key]
    return view


def paper_tables(summaries: dict | list[dict], index: dict, which: list[str]) -> str:
    """The paper's tables ``which`` (keys of ``configs/paper/tables.yaml``) from demo summaries with ``--rows``;
    a table of IoU F1 (the paper's ApolloScape Tables 7 and 8) comes twice, at IoU 0.5 and at 0.3.

    With several summaries (run sets: each trained its own stage-1 weights, one frame and STAM), a row comes from
    the first summary that has it and is compared with one frame and STAM OF THAT SUMMARY (the pairs are the same
    key frames and the same stage-1 weights); a column then says which run set each row is from, and one frame and
    STAM are shown once for each run set a table's other rows come from. A table with a ``baseline`` row (Tables
    2 and 8) also has each row's difference from it."""
    summaries = [_with_seed_interval(s) for s in ([summaries] if isinstance(summaries, dict) else summaries)]
    lines = []
    for key in which:
        table = index["tables"][key]
        for metric, paper_key in METRIC_COLUMNS[table["metrics"]]:
            lines += _paper_table(key, table, [_as_metric(s, metric) for s in summaries], metric, paper_key)
    return "\n".join(lines)


def _paper_table(key: str, table: dict, summaries: list[dict], metric: str, paper_key: str) -> list[str]:
    """One of `paper_tables`, in one metric."""
    models = [{m.get("paper_row") or m["name"]: m for m in summary["models"]} for summary in summaries]
    by_row: dict[str, tuple[int, dict]] = {}
    for i, found in enumerate(models):
        for row, m in found.items():
            by_row.setdefault(row, (i, m))
    name_of = [{row: m["name"] for row, m in found.items()} for found in models]
    diffs = [_by_pair(summary) for summary in summaries]
    seeds = sorted({len(summary["seeds"]) for summary in summaries})
    several = len(summaries) > 1

    def paired(i: int, a: str, b: str, split: str) -> dict | None:
        """F1(a) - F1(b) in run set ``i``, from the comparison of (a, b) or, negated, of (b, a)."""
        if (a, b, split) in diffs[i]:
            return diffs[i][a, b, split]
        c = diffs[i].get((b, a, split))
        if c is None:
            return None
        seeds = c.get("seed_ci95")
        return {
            "f1_diff": -c["f1_diff"],
            "ci95": [-c["ci95"][1], -c["ci95"][0]],
            "seed_ci95": [-seeds[1], -seeds[0]] if seeds else None,
        }

    def versus(i: int, row: str, other: str) -> str:
        a, b = name_of[i].get(row), name_of[i].get(other)
        if a is None or b is None or a == b:
            return "–"
        return " / ".join(_diff(paired(i, a, b, split)) for split in ("test", "challenging"))

    single, stam = _paper_row("single"), _paper_row("stam4")
    baseline = table.get("baseline")
    references = tuple(r for r in (single, stam, baseline) if r)
    seed_text = "/".join(map(str, seeds)) + f" seed{'s' if seeds != [1] else ''}"
    set_head, set_rule = (" run set |", "---|") if several else ("", "")
    base_head, base_rule = (" − baseline (test / chall.) |", "---|") if baseline else ("", "")
    what = "F1" if metric == "tusimple" else f"IoU F1 @{metric.split('@')[1]}"
    run = [r for r in table["rows"] if r["id"] in by_row]
    lines = [
        f"**Table {key}: {table['title']}**{'' if metric == 'tusimple' else ', ' + what} "
        f"({len(run)} of {len(table['rows'])} rows run, {seed_text})",
        "",
        f"| row | paper {what} |{set_head} test | challenging | − 1 frame (test / chall.) | − STAM (test / chall.) "
        f"|{base_head}",
        f"|---|---|{set_rule}---|---|---|---|{base_rule}",
    ]
    used = {by_row[r["id"]][0] for r in run if r["id"] not in references}
    for r in table["rows"]:
        paper = f"{100 * r['paper'][paper_key]:.2f}"
        if r["id"] not in by_row:
            lines.append(
                f"| {r['label']} (`{r['id']}`) | {paper} |{' |' if several else ''} not run | | | |{' |' * bool(baseline)}"
            )
            continue
        places = [by_row[r["id"]][0]]
        if r["id"] in references:  # the reference of every run set the table's rows are compared inside
            places = sorted({*used, *places} & {i for i, found in enumerate(models) if r["id"] in found})
        for i in places:
            m = models[i][r["id"]]
            where = f" {i + 1} |" if several else ""
            base = f" {versus(i, r['id'], baseline)} |" if baseline else ""
            lines.append(
                f"| {r['label']} (`{r['id']}`) | {paper} |{where} {_f1(m['test'])} | {_f1(m['challenging'])} | "
                f"{versus(i, r['id'], single)} | {versus(i, r['id'], stam)} |{base}"
            )
    return [*lines, ""]


def replication(summaries: list[dict], index: dict) -> str:
    """The paper's rows trained in more than one run set, set beside set: F1 and the difference from one frame
    (``+d [clips] s[seeds]``) in each. What a second training of the same rows says about the intervals."""
    summaries = [_with_seed_interval(s) for s in summaries]
    label = {r["id"]: r["label"] for table in index["tables"].values() for r in table["rows"]}
    models = [{m.get("paper_row") or m["name"]: m for m in summary["models"]} for summary in summaries]
    single = _paper_row("single")
    lines = [
        "| row | run set | test F1 | challenging F1 | − 1 frame (test / chall.) |",
        "|---|---|---|---|---|",
    ]
    for row in dict.fromkeys(r for found in models for r in found):
        places = [i for i, found in enumerate(models) if row in found]
        if len(places) < 2:
            continue
        for i in places:
            m = models[i][row]
            versus = " / ".join(
                _diff(_from_single(summaries[i], models[i], row, split)) for split in ("test", "challenging")
            )
            lines.append(
                f"| {label.get(row, row)} (`{row}`) | {i + 1} | {_f1(m['test'])} | {_f1(m['challenging'])} | "
                f"{'–' if row == single else versus} |"
            )
    return "\n".join([*lines, "", *_agreement(summaries, models, single)]) + "\n"


def _from_single(summary: dict, models: dict, row: str, split: str) -> dict | None:
    """The comparison of paper row ``row`` with one frame on ``split`` in ``summary`` (``models``: its models by
    paper row), or None."""
    reference = models.get(_paper_row("single"), {}).get("name")
    return _by_pair(summary).get((models[row]["name"], reference, split))


def _agreement(summaries: list[dict], models: list[dict], single: str) -> list[str]:
    """How far the first two run sets agree on each row's difference from one frame on the challenging clips:
    their correlation over the rows trained in both, how often the sign is the same, and how many differences
    claimed in either set (both intervals exclude 0) are claimed in the other."""
    import numpy as np

    if len(summaries) < 2:
        return []
    pairs, claims = [], []
    for row in set(models[0]) & set(models[1]) - {single}:
        found = [_from_single(summaries[i], models[i], row, "challenging") for i in (0, 1)]
        if None in found:
            continue
        pairs.append([c["f1_diff"] for c in found])
        claimed = [_supported(c) for c in found]
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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("summary", type=Path, nargs="+", help="summary.json; with --paper, several run sets")
    p.add_argument("--out", type=Path)
    p.add_argument("--paper", type=Path, help="configs/paper/tables.yaml: print the paper's tables instead")
    p.add_argument("--tables", nargs="+", default=["2", "3", "4"], help="which of the paper's tables (--paper)")
    p.add_argument("--models", nargs="+", metavar="NAME", help="without --paper: only these models of the summary")
    p.add_argument(
        "--replication", action="store_true", help="with --paper: the rows of several run sets, side by side"
    )
    args = p.parse_args(argv)
    summaries = [json.loads(path.read_text()) for path in args.summary]
    if args.paper:
        import yaml

        index = yaml.safe_load(args.paper.read_text())
        text = replication(summaries, index) if args.replication else paper_tables(summaries, index, args.tables)
    elif len(summaries) > 1:
        p.error("several summaries go with --paper only")
    else:
        text = tables(summaries[0], args.models)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
