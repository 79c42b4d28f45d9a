"""Before and after ``stamlane adapt``, on real labelled frames, with paired bootstrap intervals over the frames.

    python benchmarks/adapt_intervals.py BEFORE.json AFTER.json [AFTER.json ...] [--only FRAMES.txt]
                                         [--resamples 10000] [--out table.json]

Reads the per-checkpoint files of ``benchmarks/real_roads.py`` (``<out>/<name>.json``: its per-image lane.py
numbers of the six labelled photos and of the video's labelled frames) for the model before adaptation and for one
or more adapted checkpoints (one per seed), and prints, for each set of frames, lane.py's F1 (from the mean FP and FN
rates, as lane.py) and accuracy: before, each seed, their mean ± std, and the difference after − before with a 95 %
paired bootstrap interval over the frames (the seeds averaged per frame first). ``--only`` keeps the frames whose
``raw_file`` is listed in a file (one a line): a dev or sealed split.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path
from typing import Any

import numpy as np
from _harness import BenchInputError, fail, guard_out, read_json_object, write_result

SETS = {"photos": ("labelled_frames",), "video": ("video", "labelled_frames")}


def _frames(record: dict[str, Any], path: tuple[str, ...]) -> list[dict[str, Any]]:
    node: Any = record
    for key in path:
        node = node.get(key) if isinstance(node, dict) else None
    return list(node.get("per_image") or []) if isinstance(node, dict) else []


def f1(fp: np.ndarray, fn: np.ndarray) -> np.ndarray:
    """lane.py's F1 from its FP and FN rates (each the mean over images), along the last axis."""
    precision, recall = 1.0 - fp.mean(axis=-1), 1.0 - fn.mean(axis=-1)
    total = precision + recall
    return np.where(total > 0, 2 * precision * recall / np.where(total > 0, total, 1.0), 0.0)


def _table(before: list[dict[str, Any]], after: list[list[dict[str, Any]]], resamples: int) -> dict[str, Any]:
    names = [r["raw_file"] for r in before]
    runs = [{r["raw_file"]: r for r in run} for run in after]
    if any(set(run) != set(names) for run in runs):
        raise BenchInputError("the checkpoints were scored on other frames")

    def arrays(records: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (
            np.array([float(r["fp"]) for r in records]),
            np.array([float(r["fn"]) for r in records]),
            np.array([float(r["acc"]) for r in records]),
        )

    fp0, fn0, acc0 = arrays(before)
    seeds = [arrays([run[n] for n in names]) for run in runs]
    fp1 = np.mean([s[0] for s in seeds], axis=0)
    fn1 = np.mean([s[1] for s in seeds], axis=0)
    acc1 = np.mean([s[2] for s in seeds], axis=0)
    rng = np.random.default_rng(0)
    idx = rng.integers(0, len(names), (resamples, len(names)))
    diff_f1 = f1(fp1[idx], fn1[idx]) - f1(fp0[idx], fn0[idx])
    diff_acc = acc1[idx].mean(axis=1) - acc0[idx].mean(axis=1)
    per_seed = [float(f1(s[0], s[1])) for s in seeds]
    per_seed_acc = [float(s[2].mean()) for s in seeds]

    def spread(values: list[float]) -> float:
        return statistics.stdev(values) if len(values) > 1 else 0.0

    return {
        "frames": len(names),
        "before_f1": float(f1(fp0, fn0)),
        "after_f1_seeds": per_seed,
        "after_f1_mean": statistics.fmean(per_seed),
        "after_f1_std": spread(per_seed),
        "diff_f1": float(f1(fp1, fn1) - f1(fp0, fn0)),
        "diff_f1_interval": [float(np.percentile(diff_f1, 2.5)), float(np.percentile(diff_f1, 97.5))],
        "before_accuracy": float(acc0.mean()),
        "after_accuracy_seeds": per_seed_acc,
        "after_accuracy_mean": statistics.fmean(per_seed_acc),
        "after_accuracy_std": spread(per_seed_acc),
        "diff_accuracy": float(acc1.mean() - acc0.mean()),
        "diff_accuracy_interval": [float(np.percentile(diff_acc, 2.5)), float(np.percentile(diff_acc, 97.5))],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="adapt_intervals", description=__doc__.split("\n\n")[0])
    parser.add_argument("before", type=Path, help="real_roads.py's file of the model before adaptation")
    parser.add_argument("after", type=Path, nargs="+", help="real_roads.py's files of the adapted checkpoints")
    parser.add_argument("--only", type=Path, help="keep the frames whose raw_file is listed here (one a line)")
    parser.add_argument("--resamples", type=int, default=10000)
    parser.add_argument("--out", type=Path, help="write the table as json here too")
    args = parser.parse_args(argv)
    if (refused := guard_out("adapt_intervals", args.out)) is not None:  # before any work
        return refused
    try:
        records = [read_json_object(p, "a real_roads.py file") for p in (args.before, *args.after)]
        keep = set(args.only.read_text().split()) if args.only else None
        tables = _tables(records, keep, args.resamples)
    except (OSError, ValueError) as err:  # BenchInputError is a ValueError
        return fail("adapt_intervals", err)
    if args.out:
        write_result(args.out, tables, indent=2, quiet=True)
    return 0


def _tables(records: list[dict[str, Any]], keep: set[str] | None, resamples: int) -> dict[str, Any]:
    """Each set's table (`_table`), printed as it is made."""
    tables = {}
    for name, path in SETS.items():
        frames = [_frames(r, path) for r in records]
        if keep is not None:
            frames = [[f for f in run if f["raw_file"] in keep] for run in frames]
        if not frames[0]:
            continue
        table = tables[name] = _table(frames[0], frames[1:], resamples)
        lo, hi = table["diff_f1_interval"]
        alo, ahi = table["diff_accuracy_interval"]
        print(
            f"{name} ({table['frames']} frames): F1 {100 * table['before_f1']:.1f} -> "
            f"{100 * table['after_f1_mean']:.1f} ± {100 * table['after_f1_std']:.1f} "
            f"(seeds {', '.join(f'{100 * v:.1f}' for v in table['after_f1_seeds'])}), "
            f"{100 * table['diff_f1']:+.1f} [{100 * lo:+.1f}, {100 * hi:+.1f}]; accuracy "
            f"{100 * table['before_accuracy']:.1f} -> {100 * table['after_accuracy_mean']:.1f} ± "
            f"{100 * table['after_accuracy_std']:.1f}, {100 * table['diff_accuracy']:+.1f} "
            f"[{100 * alo:+.1f}, {100 * ahi:+.1f}]"
        )
    return tables


if __name__ == "__main__":
    sys.exit(main())
