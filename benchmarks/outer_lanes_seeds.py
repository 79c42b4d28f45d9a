"""Where the lines go missing, over seeds: `benchmarks/outer_lanes.py` results of several fine-tunes per recipe.

    python benchmarks/outer_lanes_seeds.py OUTER-LANES.json [OUTER-LANES.json ...] --groups NEW CONTROL
                                           [--position adjacent] [--resamples 10000]

Each file is an ``outer-lanes.json`` written by ``benchmarks/outer_lanes.py``; its checkpoints named
``<group>-s<seed>`` (the file stems of ``--ckpt``) are read, the others left alone, several files as one (a run in
two of them is an error). Per group, the labelled lines of each position by what became of them
(`real_frames.CAUSES`: all seeds, then seed by seed); then, for the lines of ``--position``, the first group against
each later one: the share of seeds in which a line is absent from the lane probability map, in which lane.py
matches it, and the mean peak probability along it (``support.mean_max``), each line's value averaged over its
group's seeds first, the first group's minus the other's with a 95 % paired bootstrap interval that resamples the
photos (a photo's lines together: they share its road and its light).

Exit status 2 with one line where a file is unreadable or no result of ``outer_lanes.py``, a run is in two files, a
group is missing, or two groups were scored on other photos or lines.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from _harness import BenchInputError, Within, fail, option_problem, read_json_object
from real_frames import CAUSES
from real_roads_seeds import SEEDED  # a benchmark script beside this one: <group>-s<seed>
from stamlane_eval.stats import paired_bootstrap

POSITIONS = ("ego", "adjacent", "outer")
MEASURES = ("absent", "matched", "peak probability")
"""What is compared per line: absent from the map (share of seeds), matched by lane.py (share), ``mean_max``."""


def _lines(result: object, name: str, path: Path) -> list[tuple[str, int, dict]]:
    """``(photo, line index, line)`` of one checkpoint's result, in the file's order."""
    try:
        photos = result["photos"]  # type: ignore[index]
        return [(p["raw_file"], i, line) for p in photos for i, line in enumerate(p["lines"])]
    except (KeyError, TypeError):
        raise BenchInputError(f"{path}: {name} has no photos with lines (an outer_lanes.py result?)") from None


def read(*paths: Path) -> dict[str, dict[int, list[tuple[str, int, dict]]]]:
    """``group -> seed -> [(photo, line index, line)]`` of the seeded checkpoints in ``paths``.

    Raises:
        BenchInputError: a file unreadable or no result, or a run in two files.
    """
    groups: dict[str, dict[int, list[tuple[str, int, dict]]]] = {}
    found: dict[str, Path] = {}
    for path in paths:
        results = read_json_object(path, "outer-lanes result", ("results",))["results"]
        if not isinstance(results, dict):
            raise BenchInputError(f"{path}: 'results' is no object of checkpoints (an outer_lanes.py result?)")
        for name, result in results.items():
            match = SEEDED.match(name)
            if match is None:
                continue
            if found.setdefault(name, path) != path:
                raise BenchInputError(f"{name} is in {found[name]} and in {path}: name one of them")
            groups.setdefault(match["group"], {})[int(match["seed"])] = _lines(result, name, path)
    return groups


def causes_table(groups: dict[str, dict[int, list[tuple[str, int, dict]]]], names: list[str]) -> str:
    """Markdown: per group and position, the lines over all seeds by cause (seed by seed in brackets)."""
    lines = [
        "| group | seeds | position | lines a seed | " + " | ".join(CAUSES) + " |",
        "|---" * (4 + len(CAUSES)) + "|",
    ]
    for name in names:
        seeds = groups[name]
        for position in POSITIONS:
            # per seed, the lines of this position by cause
            counts = [
                [
                    sum(1 for *_, line in seeds[s] if line.get("position") == position and line.get("cause") == cause)
                    for cause in CAUSES
                ]
                for s in sorted(seeds)
            ]
            total = sum(counts[0])
            if total == 0:
                continue
            cells = [f"{sum(by_seed)} ({' / '.join(map(str, by_seed))})" for by_seed in zip(*counts)]
            lines.append(f"| {name} | {len(seeds)} | {position} | {total} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def per_line(seeds: dict[int, list[tuple[str, int, dict]]], position: str) -> tuple[list[tuple[str, int]], np.ndarray]:
    """The lines of ``position`` (``(photo, index)``) and, per line, `MEASURES` averaged over the seeds.

    Raises:
        BenchInputError: the seeds were scored on other photos or lines.
    """
    keys: list[tuple[str, int]] | None = None
    values = []
    for seed in sorted(seeds):
        chosen = [(photo, i, line) for photo, i, line in seeds[seed] if line.get("position") == position]
        these = [(photo, i) for photo, i, _ in chosen]
        if keys is not None and these != keys:
            raise BenchInputError(f"seed {seed} was scored on other photos or lines than seed {min(seeds)}")
        keys = these
        try:
            values.append(
                [
                    [line["cause"] == "absent", line["cause"] == "matched", float(line["support"]["mean_max"])]
                    for *_, line in chosen
                ]
            )
        except (KeyError, TypeError, ValueError):
            raise BenchInputError(f"seed {seed}: a line without its cause and support.mean_max") from None
    return keys or [], np.asarray(values, dtype=np.float64).mean(axis=0)


def compare(
    groups: dict[str, dict[int, list[tuple[str, int, dict]]]], names: list[str], position: str, resamples: int
) -> list[str]:
    """The first group against each later one on the lines of ``position``: `MEASURES`, paired over photos.

    Raises:
        BenchInputError: two groups scored on other photos or lines, or no line of ``position``.
    """
    first_keys, first = per_line(groups[names[0]], position)
    if not first_keys:
        raise BenchInputError(f"no {position} line in {names[0]}'s results")
    out = []
    for other in names[1:]:
        keys, values = per_line(groups[other], position)
        if keys != first_keys:
            raise BenchInputError(f"{names[0]} and {other} were scored on other photos or lines: not comparable")
        photos = [photo for photo, _ in keys]
        cells = []
        for column, measure in enumerate(MEASURES):
            estimate = paired_bootstrap(
                first[:, column], values[:, column], lambda m: float(m[0]), groups=photos, resamples=resamples
            )
            cells.append(f"{measure} {estimate.value:+.3f} [{estimate.low:+.3f}, {estimate.high:+.3f}]")
        count = len(set(photos))
        out.append(f"- {names[0]} − {other}, {len(keys)} {position} lines of {count} photos: " + "; ".join(cells))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", type=Path, nargs="+")
    parser.add_argument("--groups", nargs="+", required=True, help="the groups, the first compared with the others")
    parser.add_argument("--position", default="adjacent", help=f"the lines compared, of {' '.join(POSITIONS)}")
    parser.add_argument("--resamples", type=int, default=10000, help="bootstrap resamples")
    args = parser.parse_args(argv)
    if args.position not in POSITIONS:
        return fail("outer_lanes_seeds", f"--position: {args.position} not of {' '.join(POSITIONS)}")
    if (problem := option_problem(vars(args), ranges={"resamples": Within(100, 1_000_000)})) is not None:
        return fail("outer_lanes_seeds", problem)
    try:
        groups = read(*args.files)
        missing = [g for g in args.groups if g not in groups]
        if missing:
            raise BenchInputError(
                f"no <group>-s<seed> results of {', '.join(missing)} in {' '.join(map(str, args.files))}"
            )
        print(causes_table(groups, args.groups))
        print()
        print("\n".join(compare(groups, args.groups, args.position, args.resamples)))
    except BenchInputError as err:
        return fail("outer_lanes_seeds", err)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
