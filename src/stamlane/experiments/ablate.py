"""``stamlane ablate``: the experiment engine on the paper's ablation tables.

    stamlane ablate --table N [N ...] [--rows ID ...] [--seeds 0 1 2] [--recipe paper|cpu] [--steps N]
                    [--pretrain-steps N] [--data DIR] [--base configs/demo.yaml] [--splits test challenging]
                    [--bf16 auto|true|false] [--out outputs/ablate] [--tables configs/paper/tables.yaml]
                    [--list] [--report-only] [-- <stamlane fit arguments of every run>]

Every row of the tables asked for (``configs/paper/tables.yaml``) is trained per seed with ``base + ablation.yaml
+ rows/<id>.yaml`` (rows several tables share are trained once) by `stamlane.experiments.engine` with the named
recipe: ``paper`` (default) every row from scratch for ``--steps`` (default 1,500); ``cpu`` the demo's two stages
(``--pretrain-steps`` single-frame steps from scratch, then each row for ``--steps`` from those weights). The final
weights are scored on the splits (TuSimple F1 and IoU F1, intervals over clips and seeds), every multi-frame row
with its history probed (history use), every row against one frame, pre-aligned STAM and, in Tables 2 and 8, the
table's baseline. Writes ``<out>/summary.json``, ``tables.md`` (the paper's tables, then every row's details),
``summary.csv`` and ``history_use.png``, and prints the paper's tables. Resumable: finished runs are reused;
``--out`` is locked to its settings. Arguments after ``--`` go to every ``stamlane fit``, after the base config and
before the row's (``-- --trainer.accelerator=gpu``).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from stamlane_eval.cli_tools import OneLineParser, parse_or_status

from stamlane.experiments import workspace
from stamlane.experiments.engine import Experiment
from stamlane.experiments.recipes import RECIPES, Row
from stamlane.experiments.runner import check_fit_arguments
from stamlane.experiments.store import ExperimentError
from stamlane.experiments.table_index import PaperRow, TableIndex, baseline_pairs, load_tables
from stamlane.safety.paths import MAX_CONFIG_BYTES, require

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    from stamlane.synth.layout import DEFAULT_SYNTHETIC_ROOT

    p = OneLineParser(prog="stamlane ablate", description=__doc__.split("\n")[0], epilog=workspace.FIT_ARGUMENTS_HELP)
    p.add_argument("--table", nargs="+", metavar="N", help="table number(s): 1 2 3 4 7 8")
    p.add_argument("--rows", nargs="+", metavar="ID", help="only these rows of the tables (ids as in --list)")
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2], metavar="S", help="seeds (default 0 1 2)")
    p.add_argument("--recipe", choices=sorted(RECIPES), default="paper", help="paper: one stage; cpu: two stages")
    p.add_argument("--steps", type=int, help="steps of each row (default: the recipe's, 1500 / 300)")
    p.add_argument("--pretrain-steps", type=int, help="cpu recipe: single-frame steps of stage 1 (default 1200)")
    p.add_argument("--data", type=Path, help=f"data root, a TuSimple-layout set (default {DEFAULT_SYNTHETIC_ROOT})")
    p.add_argument("--base", type=Path, help="base config (default: the index's, configs/demo.yaml)")
    p.add_argument(
        "--splits",
        nargs="+",
        type=workspace.split_name,
        default=["test", "challenging"],
        help="label files scored (stems)",
    )
    workspace.add_bf16_argument(p)
    p.add_argument("--out", type=Path, default=Path("outputs/ablate"), help="results folder (default outputs/ablate)")
    p.add_argument("--tables", type=Path, help="table index (default configs/paper/tables.yaml)")
    p.add_argument("--list", action="store_true", help="print the tables and their rows, then exit")
    p.add_argument("--report-only", action="store_true", help="train nothing: the tables of <out>/summary.json")
    return p


def _list(index: TableIndex) -> None:
    print(f"tables of {index.path} (base {index.default_base}):")
    for t in index.tables.values():
        print(f"\nTable {t.name}: {t.title} [{t.kind}]" + (f", baseline {t.baseline}" if t.baseline else ""))
        for r in t.rows:
            print(f"  {r.id:32s} {r.label}")


def _rows(index: TableIndex, tables: list[str], only: list[str] | None, base: Path) -> list[Row]:
    chosen: dict[str, PaperRow] = {}
    for name in tables:
        for row in index.table(name).select(None):
            if not only or row.id in only:
                chosen.setdefault(row.id, row)
    unknown = sorted(set(only or []) - set(chosen))
    if unknown:
        raise ValueError(f"no row {unknown[0]!r} in table(s) {' '.join(tables)} (see --list)")
    layers = [str(p) for p in index.layers]
    return [Row(r.id, r.label, (str(base), *layers, str(r.config)), paper=r.id) for r in chosen.values()]


def _pairs(rows: list[Row]) -> list[tuple[str, str]]:
    """Every row against one frame and pre-aligned STAM (where trained), and against its table's baseline."""
    from stamlane.experiments.paper_report import SINGLE_ROW, STAM_ROW

    names = {r.name for r in rows}
    found = [(r.name, ref) for r in rows for ref in (SINGLE_ROW, STAM_ROW) if ref in names and ref != r.name]
    found += baseline_pairs({r.name: r.name for r in rows})
    return list(dict.fromkeys(found))


def _report(out: Path, index: TableIndex, tables: list[str]) -> str:
    from stamlane.experiments.paper_report import paper_tables
    from stamlane.experiments.plots import plot_history_use
    from stamlane.experiments.summary import Summary
    from stamlane.experiments.tables import tables as detail_tables
    from stamlane.experiments.tables import write_csv
    from stamlane.safety.guard import write_atomic

    summary = Summary.read(out / "summary.json")
    text = paper_tables([summary], index, tables)
    write_atomic(out / "tables.md", text + "\n" + detail_tables(summary) + "\n")
    write_csv(out / "summary.csv", summary)
    plot_history_use(summary, out / "history_use.png")
    return text


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``stamlane ablate`` (``argv`` without the subcommand)."""
    argv, extra = workspace.fit_arguments(list(sys.argv[1:] if argv is None else argv))
    args = parse_or_status(build_parser(), argv)
    if isinstance(args, int):
        return args
    from stamlane.safety.boundary import run_command

    return run_command("stamlane ablate", lambda: _ablate(args, extra), ExperimentError)


def _ablate(args: argparse.Namespace, extra: list[str]) -> int:
    index = load_tables(args.tables)
    if args.list:
        _list(index)
        return 0
    if not args.table:
        raise ValueError("--table is required (see --list)")
    for flag in ("steps", "pretrain_steps"):
        if getattr(args, flag) is not None and getattr(args, flag) < 1:
            raise ValueError(f"--{flag.replace('_', '-')} must be >= 1, got {getattr(args, flag)}")
    if len(set(args.seeds)) != len(args.seeds):
        raise ValueError(f"--seeds must be distinct, got {args.seeds}")
    if args.report_only:
        if not (args.out / "summary.json").is_file():
            raise ValueError(f"{args.out} holds no summary.json (nothing run there)")
        print(_report(args.out, index, args.table))
        return 0
    base = args.base.resolve() if args.base else index.default_base
    if not base.is_file():
        raise ValueError(f"--base {args.base} not found")
    require(base, "--base", limit=MAX_CONFIG_BYTES)  # a config over 16 MiB: refused before the data are made
    if extra:  # before the data are made: a fit argument every run would refuse is said now
        check_fit_arguments(base, extra)
    rows = _rows(index, args.table, args.rows, base)
    recipe = RECIPES[args.recipe]
    if args.pretrain_steps and recipe.pretrain is None:
        raise ValueError("--pretrain-steps is for the two-stage recipe (--recipe cpu)")
    recipe = replace(recipe, steps=args.steps or recipe.steps)
    recipe = replace(recipe, pretrain_steps=args.pretrain_steps or recipe.pretrain_steps)
    workspace.check_data(args.data, must_exist=True)
    root = workspace.prepare_data(args.data, args.out, generate=False)
    missing = [s for s in args.splits if not (root / f"{s}.json").is_file()]
    if missing:
        raise ValueError(f"--splits: {root} has no {missing[0]}.json")
    bf16 = workspace.bf16_of(args.bf16)
    experiment = Experiment(
        rows, recipe, args.seeds, root, args.out, bf16=bf16, splits=tuple(args.splits), extra=tuple(extra)
    )
    outputs = [args.out / "summary.json", args.out / "tables.md"]
    # the runs never land among the frames and labels, nor replace the base or the index; a second run on --out: refused
    with workspace.claimed_out(args.out, outputs, [base, index.path], protected=[root]):
        experiment.run(_pairs(rows))
    print(_report(args.out, index, args.table))
    print(f"stamlane ablate: tables written to {args.out / 'tables.md'}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
