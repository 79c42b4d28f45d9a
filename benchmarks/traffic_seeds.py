"""The traffic diagnosis over seeds: `benchmarks/traffic_diagnosis.py` results of several fine-tunes per recipe.

    python benchmarks/traffic_seeds.py DIAGNOSIS.json [DIAGNOSIS.json ...] [--groups NAME ...]

Each file is a ``diagnosis.json`` written by ``benchmarks/traffic_diagnosis.py``; its checkpoints named
``<group>-s<seed>`` (the file stems of ``--ckpt``) are read, the others left alone, and several files are read as one
(a run in two of them is an error). Per kind of traffic and group: lane.py's F1 with the real (ORB-aligned) history,
with the key frame copied into every history slot, and with the exact history, and the history use (real − copies),
as mean ± std over the seeds; per pair of groups (the first named against each later one): the real-history F1 and
the use of the first minus the other's, seed by seed (the two runs of a seed side by side), with a Student-t
interval over the seeds (`stamlane_eval.stats.seed_interval`; t = 4.30 for 3 seeds). The intervals over clips of
each run are in its ``summary.md``.

Exit status 2 with one line where a file is unreadable or no diagnosis, a run is in two files, a group is missing,
or the groups of a pair share fewer than 2 seeds.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _harness import BenchInputError, fail, read_json_object
from real_roads_seeds import SEEDED  # a benchmark script beside this one: <group>-s<seed>
from stamlane_eval.stats import seed_interval

HISTORIES = ("real", "copies", "exact")
"""The histories each checkpoint is scored with, as ``traffic_diagnosis.py`` names them."""


def read(*paths: Path) -> dict[str, dict[str, dict[int, dict[str, float]]]]:
    """``kind -> group -> seed -> history -> F1 in %`` of the seeded checkpoints in ``paths``.

    Raises:
        BenchInputError: a file unreadable or no diagnosis, or a run in two files.
    """
    kinds: dict[str, dict[str, dict[int, dict[str, float]]]] = {}
    found: dict[str, Path] = {}
    for path in paths:
        diagnosis = read_json_object(path, "diagnosis", ("kinds",))
        if not isinstance(diagnosis["kinds"], dict):
            raise BenchInputError(f"diagnosis {path}: 'kinds' is no object of traffic_diagnosis.py's kinds")
        for kind, result in diagnosis["kinds"].items():
            try:
                models = result["summary"]["models"]
                scores = {name: {h: 100 * float(m[h]["f1"]["value"]) for h in HISTORIES} for name, m in models.items()}
            except (KeyError, TypeError, ValueError):
                raise BenchInputError(f"diagnosis {path}: kind {kind} has no models scored with {HISTORIES}") from None
            for name, score in scores.items():
                match = SEEDED.match(name)
                if match is None:
                    continue
                if found.setdefault(f"{kind}/{name}", path) != path:
                    raise BenchInputError(f"{name} is in {found[f'{kind}/{name}']} and in {path}: name one of them")
                kinds.setdefault(kind, {}).setdefault(match["group"], {})[int(match["seed"])] = score
    return kinds


def _spread(values: list[float], sign: str = "") -> str:
    """Mean ± std over seeds (``sign="+"``: the mean signed); one seed: its number alone."""
    mean = float(np.mean(values))
    return f"{mean:{sign}.1f}" if len(values) < 2 else f"{mean:{sign}.1f} ± {float(np.std(values, ddof=1)):.1f}"


def _paired(values: list[float]) -> str:
    estimate = seed_interval(values)
    seeds = " / ".join(f"{v:+.1f}" for v in values)
    return f"{estimate.value:+.1f} [{estimate.low:+.1f}, {estimate.high:+.1f}] ({seeds})"


def table(kinds: dict[str, dict[str, dict[int, dict[str, float]]]], groups: list[str]) -> str:
    """Markdown: per kind each group's F1 and use over seeds, then the first group against each later one.

    Raises:
        BenchInputError: a group missing from a kind, or a pair sharing fewer than 2 seeds.
    """
    lines = [
        "| kind | group | seeds | real-history F1 | copies F1 | exact F1 | use (real − copies) |",
        "|---|---|---|---|---|---|---|",
    ]
    for kind, by_group in kinds.items():
        missing = [g for g in groups if g not in by_group]
        if missing:
            raise BenchInputError(f"kind {kind} has no <group>-s<seed> runs of {', '.join(missing)}")
        for group in groups:
            seeds = by_group[group]
            f1 = {h: [seeds[s][h] for s in sorted(seeds)] for h in HISTORIES}
            use = [r - c for r, c in zip(f1["real"], f1["copies"])]
            cells = [_spread(f1["real"]), _spread(f1["copies"]), _spread(f1["exact"]), _spread(use, "+")]
            lines.append(f"| {kind} | {group} | {len(seeds)} | " + " | ".join(cells) + " |")
        first = by_group[groups[0]]
        for other in groups[1:]:
            shared = sorted(set(first) & set(by_group[other]))
            if len(shared) < 2:
                raise BenchInputError(f"{groups[0]} and {other} share {len(shared)} seed(s) on {kind}: 2 are needed")
            real = [first[s]["real"] - by_group[other][s]["real"] for s in shared]
            use = [
                (first[s]["real"] - first[s]["copies"]) - (by_group[other][s]["real"] - by_group[other][s]["copies"])
                for s in shared
            ]
            lines.append(
                f"| {kind} | {groups[0]} − {other}, paired | {len(shared)} | {_paired(real)} | | | {_paired(use)} |"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", type=Path, nargs="+")
    parser.add_argument("--groups", nargs="+", help="the groups to show, in this order (default: every group)")
    args = parser.parse_args(argv)
    try:
        kinds = read(*args.files)
        if not kinds:
            raise BenchInputError(f"no <group>-s<seed> checkpoint in {' '.join(map(str, args.files))}")
        groups = args.groups or sorted({g for by_group in kinds.values() for g in by_group})
        print(table(kinds, groups))
    except BenchInputError as err:
        return fail("traffic_seeds", err)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
