"""``stamlane ablate``: run the paper's ablation tables over seeds and write their results.

    stamlane ablate --table 3 [--rows f4_parallel_gates ...] [--seeds 0 1 2] [--data-root DIR]
                    [--max-steps N | --minutes M] [--out outputs/ablate] [--base configs/demo.yaml]
                    [-- <stamlane fit arguments, applied after the base, before the row>]

Each row of a table (``configs/paper/tables.yaml``) is trained once per seed with ``base + ablation.yaml
+ rows/<id>.yaml`` and tested on the test split and the challenging split. Resumable: a run with a
``result.json`` is not run again (rows shared by several tables run once), and a run killed midway
continues from its last checkpoint. ``--out`` is locked to the settings of its first call (base, data,
budget, extra arguments): another setting needs another ``--out``.

Writes ``<out>/table<N>.csv``, ``table<N>.md`` (mean ± std over seeds beside the paper's numbers, and the
robustness split: F1 on all vs challenging clips, ΔF1, like the paper's Table 6) and ``table<N>.png``
(F1 per row with ±std error bars), and prints the markdown. Exit status: 0, 1 when a run failed (its
traceback is in its ``error.txt``; the other runs go on), 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import traceback
from pathlib import Path
from typing import Any

from stamlane_eval.cli_tools import OneLineParser, parse_or_status

from stamlane.experiments.report import plot_table, robustness_markdown, table_markdown, write_csv
from stamlane.experiments.results import load_result, result_path, run_dir, save_result, summarize
from stamlane.experiments.runner import RunSpec, run
from stamlane.experiments.tables import PaperRow, PaperTable, TableIndex, load_tables

__all__ = ["main"]

_SETTINGS = "settings.json"


def _parser() -> argparse.ArgumentParser:
    from stamlane.synth.generator import DEFAULT_SYNTHETIC_ROOT

    p = OneLineParser(
        prog="stamlane ablate",
        description="Run the paper's ablation tables (configs/paper/tables.yaml) over seeds; write CSV, "
        "markdown and a plot with mean ± std. Arguments after `--` go to every `stamlane fit`, after the base config and before the row's.",
    )
    p.add_argument("--table", nargs="+", metavar="N", help="table number(s): 1 2 3 4 7 8")
    p.add_argument("--rows", nargs="+", metavar="ID", help="only these rows (ids as in --list)")
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2], metavar="S", help="seeds (default 0 1 2)")
    p.add_argument(
        "--data-root", help=f"data root (default: the base config's; for synthetic clips {DEFAULT_SYNTHETIC_ROOT})"
    )
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--max-steps", type=int, help="training steps per run (default: the base config's)")
    budget.add_argument("--minutes", type=float, help="training wall-clock limit per run (trainer.max_time)")
    p.add_argument("--out", default="outputs/ablate", help="results folder (default outputs/ablate)")
    p.add_argument("--base", help="base config (default: the index's default_base, configs/demo.yaml)")
    p.add_argument("--tables", help="table index (default configs/paper/tables.yaml)")
    p.add_argument(
        "--challenging",
        default="challenging.json",
        help="label file of the challenging split under the data root (default challenging.json; "
        "skipped where absent); 'none' to skip",
    )
    p.add_argument("--accelerator", help="trainer.accelerator for every run (cpu, gpu, auto; default the base's)")
    p.add_argument("--threads", type=int, help="torch threads (default: torch's)")
    p.add_argument("--keep-checkpoints", action="store_true", help="keep each run's checkpoints")
    p.add_argument("--report-only", action="store_true", help="run nothing; write the tables from finished runs")
    p.add_argument("--list", action="store_true", help="print the tables and their rows, then exit")
    return p


def _fail(message: str) -> int:
    print(f"stamlane ablate: {message}", file=sys.stderr)
    return 2


def _settings(args: argparse.Namespace, index: TableIndex, base: Path, extra: list[str]) -> dict[str, Any]:
    """What every run of an ``--out`` folder must share (hardware and seeds may differ)."""
    return {
        "base": str(base),
        "layers": [str(p) for p in index.layers],
        "data_root": str(Path(args.data_root).resolve()) if args.data_root else None,
        "max_steps": args.max_steps,
        "minutes": args.minutes,
        "challenging": args.challenging,
        "extra": extra,
    }


def _check_settings(out: Path, settings: dict[str, Any]) -> str | None:
    """Write the settings of a new ``--out``; for an existing one, the error message when they differ."""
    path = out / _SETTINGS
    if path.is_file():
        old = json.loads(path.read_text())
        diff = [k for k in sorted(set(old) | set(settings)) if old.get(k) != settings.get(k)]
        if diff:
            k = diff[0]
            return (
                f"{out} holds runs made with other settings ({k}: {old.get(k)!r}, now {settings.get(k)!r}); "
                f"use another --out"
            )
        return None
    out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(settings, indent=2))
    return None


def _list(index: TableIndex) -> None:
    print(f"tables of {index.path} (base {index.default_base}):")
    for t in index.tables.values():
        print(f"\nTable {t.name}: {t.title} [{t.kind}]")
        for r in t.rows:
            print(f"  {r.id:32s} {r.label}")


def _results(out: Path, row: PaperRow, seeds: list[int]) -> dict[int, dict[str, Any]]:
    found = {}
    for seed in seeds:
        result = load_result(result_path(out, row.id, seed))
        if result is not None:
            found[seed] = result
    return found


def _write_reports(out: Path, table: PaperTable, seeds: list[int], settings: dict[str, Any], command: str) -> str:
    summaries, hardware, steps, roots = {}, set(), set(), set()
    for row in table.rows:
        results = _results(out, row, seeds)
        if results:
            summaries[row.id] = summarize(row.id, results)
            hardware |= {str(r.get("hardware")) for r in results.values()}
            steps |= {int(r.get("steps", 0)) for r in results.values()}
            roots |= {str(r.get("data_root")) for r in results.values()}
    data = "; ".join(sorted(roots)) or settings.get("data_root") or "the base config's data root"
    budget = f"{'/'.join(map(str, sorted(steps)))} training steps" if steps else "no finished run"
    caption = (
        f"Data: {data}. Base: `{Path(settings['base']).name}`. {budget} per run, seeds "
        f"{' '.join(map(str, seeds))}. Hardware: {'; '.join(sorted(hardware)) or '-'}.\n"
        f"Command: `{command}`\n"
    )
    md = table_markdown(table, table.rows, summaries) + "\n" + caption
    robust = robustness_markdown(table, table.rows, summaries)
    if robust:
        md += "\n" + robust
    (out / f"table{table.name}.md").write_text(md)
    write_csv(out / f"table{table.name}.csv", table, table.rows, summaries)
    plot_table(out / f"table{table.name}.png", table, table.rows, summaries, subtitle=f"{data}; {budget}")
    return md


def _run_pending(
    out: Path, rows: list[PaperRow], args: argparse.Namespace, index: TableIndex, base: Path, extra: list[str]
) -> int:
    """Run every (row, seed) without a result; the number of failed runs."""
    from tqdm import tqdm

    pending = [(r, s) for r in rows for s in args.seeds if not result_path(out, r.id, s).is_file()]
    skipped = len(rows) * len(args.seeds) - len(pending)
    if skipped:
        print(f"stamlane ablate: {skipped} run(s) already finished in {out}, not run again", file=sys.stderr)
    failed = 0
    for row, seed in tqdm(pending, desc="ablation runs", unit="run", disable=not pending):
        folder = run_dir(out, row.id, seed)
        spec = RunSpec(
            configs=(base, *index.layers),
            row=row.config,
            seed=seed,
            out_dir=folder,
            max_steps=args.max_steps,
            minutes=args.minutes,
            data_root=str(Path(args.data_root).resolve()) if args.data_root else None,
            accelerator=args.accelerator,
            challenging=None if args.challenging == "none" else args.challenging,
            extra=tuple(extra),
            keep_checkpoints=args.keep_checkpoints,
        )
        try:
            result = run(spec)
        except Exception:  # one failed row must not lose the others: recorded, reported, status 1
            failed += 1
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "error.txt").write_text(traceback.format_exc())
            last = traceback.format_exc().strip().splitlines()[-1]
            print(f"stamlane ablate: {row.id} seed {seed} failed: {last} (see {folder / 'error.txt'})", file=sys.stderr)
            continue
        (folder / "error.txt").unlink(missing_ok=True)
        save_result(result_path(out, row.id, seed), {"row": row.id, **result})
    return failed


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``stamlane ablate`` (``argv`` without the subcommand)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    extra: list[str] = []
    if "--" in argv:
        cut = argv.index("--")
        argv, extra = argv[:cut], argv[cut + 1 :]
    args = parse_or_status(_parser(), argv)
    if isinstance(args, int):
        return args
    try:
        index = load_tables(args.tables)
    except (OSError, ValueError) as err:
        return _fail(str(err))
    if args.list:
        _list(index)
        return 0
    if not args.table:
        return _fail("--table is required (see --list)")
    if args.max_steps is not None and args.max_steps < 1:
        return _fail(f"--max-steps must be >= 1, got {args.max_steps}")
    if args.minutes is not None and args.minutes <= 0:
        return _fail(f"--minutes must be > 0, got {args.minutes}")
    if args.threads is not None and args.threads < 1:
        return _fail(f"--threads must be >= 1, got {args.threads}")
    if len(set(args.seeds)) != len(args.seeds):
        return _fail(f"--seeds must be distinct, got {args.seeds}")
    if args.data_root and not Path(args.data_root).is_dir():
        return _fail(f"--data-root {args.data_root} is not a folder")
    base = Path(args.base).resolve() if args.base else index.default_base
    if not base.is_file():
        return _fail(f"--base {args.base} not found")
    try:
        tables = [index.table(name) for name in args.table]
        if args.rows:
            known = {r.id for t in tables for r in t.rows}
            unknown = [r for r in args.rows if r not in known]
            if unknown:
                raise ValueError(f"no row {unknown[0]!r} in table(s) {' '.join(args.table)} (see --list)")
    except ValueError as err:
        return _fail(str(err))
    rows: list[PaperRow] = []
    for table in tables:
        for row in table.rows:
            if (not args.rows or row.id in args.rows) and row.id not in {r.id for r in rows}:
                rows.append(row)

    out = Path(args.out)
    settings = _settings(args, index, base, extra)
    if args.report_only:
        saved = out / _SETTINGS
        if not saved.is_file():
            return _fail(f"{out} holds no ablation runs ({saved} missing)")
        settings = json.loads(saved.read_text())
        failed = 0
    else:
        problem = _check_settings(out, settings)
        if problem:
            return _fail(problem)
        if args.threads is not None:
            import torch

            torch.set_num_threads(args.threads)
        failed = _run_pending(out, rows, args, index, base, extra)

    command = shlex.join(["stamlane", "ablate", *argv, *(["--", *extra] if extra else [])])
    for table in tables:
        print(_write_reports(out, table, args.seeds, settings, command))
    print(f"stamlane ablate: tables written to {out}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
