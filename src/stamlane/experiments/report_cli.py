"""``stamlane report``: the tables of experiment summaries (``stamlane demo`` / ``stamlane ablate`` output).

    stamlane report SUMMARY                                    # one summary's tables (markdown)
    stamlane report SUMMARY --models stam4 single              # only these models and their differences
    stamlane report SUMMARY [SUMMARY ...] --paper [--tables 1 2 3 4 7 8]   # the paper's tables; several run sets
    stamlane report SUMMARY --paper --tables 1 2 --splits reveal reveal-traffic   # ... on other splits
    stamlane report SUMMARY_1 SUMMARY_2 --replication          # rows trained in both sets, side by side
    stamlane report SUMMARY --csv summary.csv --plot history_use.png --out tables.md

Reads summaries of format 2 (`stamlane.experiments.summary.FORMAT`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from stamlane_eval.cli_tools import OneLineParser, parse_or_status

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="stamlane report", description=__doc__.split("\n")[0])
    p.add_argument("summary", type=Path, nargs="+", help="summary.json; several with --paper / --replication")
    p.add_argument("--models", nargs="+", metavar="NAME", help="only these models of the summary")
    p.add_argument("--paper", action="store_true", help="the paper's tables (configs/paper/tables.yaml)")
    p.add_argument("--tables", nargs="+", default=["1", "2", "3", "4", "7", "8"], help="which of the paper's tables")
    p.add_argument(
        "--splits",
        nargs="+",
        default=["test", "challenging"],
        metavar="SPLIT",
        help="--paper: the splits of the tables' columns (default test challenging)",
    )
    p.add_argument("--index", type=Path, help="table index (default configs/paper/tables.yaml)")
    p.add_argument("--replication", action="store_true", help="rows trained in several run sets, side by side")
    p.add_argument("--csv", type=Path, help="also write every value and difference of the (first) summary as csv")
    p.add_argument("--plot", type=Path, help="also draw the history use per factor (png)")
    p.add_argument("--out", type=Path, help="also write the tables to this file")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parse_or_status(build_parser(), argv)
    if isinstance(args, int):
        return args
    from stamlane.experiments.summary import SummaryError
    from stamlane.safety.boundary import run_command

    return run_command("stamlane report", lambda: _report(args), SummaryError, KeyError)


def _report(args: argparse.Namespace) -> int:
    from stamlane.experiments.paper_report import paper_tables, replication
    from stamlane.experiments.plots import plot_history_use
    from stamlane.experiments.summary import Summary
    from stamlane.experiments.table_index import default_index_path, load_tables
    from stamlane.experiments.tables import tables, write_csv
    from stamlane.safety.guard import atomic_path, check_outputs, temporary_name, write_atomic

    outputs = [p for p in (args.out, args.csv, args.plot) if p is not None]
    index = args.index if args.index is not None else default_index_path() if args.paper or args.replication else None
    check_outputs(  # no output replaces a summary or the index, nor another output
        [*outputs, *map(temporary_name, outputs)], [*args.summary, index]
    )
    if len({p.resolve() for p in outputs}) != len(outputs):
        raise ValueError("--out, --csv and --plot must name different files")
    summaries = [Summary.read(path) for path in args.summary]
    if args.paper or args.replication:
        tables_index = load_tables(index)
        text = (
            replication(summaries, tables_index)
            if args.replication
            else paper_tables(summaries, tables_index, args.tables, args.splits)
        )
    elif len(summaries) > 1:
        raise ValueError("several summaries go with --paper or --replication")
    else:
        text = tables(summaries[0], args.models)
    if args.csv:
        write_csv(args.csv, summaries[0])
    if args.plot:
        with atomic_path(args.plot) as tmp:
            plot_history_use(summaries[0], tmp)
    if args.out:
        write_atomic(args.out, text + "\n")
    sys.stdout.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
