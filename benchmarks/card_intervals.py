"""A model card's TuSimple F1 with its clip-bootstrap interval, and paired differences, from prediction files.

    python benchmarks/card_intervals.py GT PRED [PRED ...] [--names A B ...] [--resamples N]

``GT`` is a TuSimple label file (a split of a synthetic set, say ``reveal.json``); each ``PRED`` a
``predictions.json`` of ``stamlane predict`` on that split (another model, or the same one with a history probe,
``--data.history_source key``). Every file is scored as lane.py scores it, without the 200 ms limit (the run
times of a shared CPU say nothing about the model). Prints, per prediction file, the F1 with its 95 % interval,
and for every later file the difference ``first - later`` with its paired interval. The intervals resample whole
clips (an image's clip is the folder of its ``raw_file``: the synthetic splits label several key frames per clip),
by `stamlane_eval.stats`; they hold the weights fixed and say nothing about another training seed.

Exit status 2, with one line on stderr, where a file cannot be read or a prediction file does not hold the gt's
images.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path, PurePosixPath

import numpy as np
from stamlane_eval.io import read_tusimple
from stamlane_eval.stats import RESAMPLES, bootstrap, f1_of_rates, paired_bootstrap, tusimple_rates
from stamlane_eval.tusimple import evaluate


def rates_by_image(gt: list[dict], pred_file: Path) -> tuple[list[str], np.ndarray]:
    """The per-image ``(fp, fn)`` rates of one prediction file, in ``raw_file`` order, with those names."""
    preds = read_tusimple(pred_file)
    result = evaluate(preds, gt, time_limit=False)
    names = [record["raw_file"] for record in preds]
    order = np.argsort(names, kind="stable")
    return [names[i] for i in order], tusimple_rates(result.per_image)[order]


def percent(low: float, high: float, sign: str = "") -> str:
    """An interval in %, as the docs write it; ``sign="+"`` for a difference."""
    return f"[{100 * low:{sign}.1f}, {100 * high:{sign}.1f}]"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("gt", type=Path, help="TuSimple label json-lines of the split")
    parser.add_argument("preds", type=Path, nargs="+", help="predictions.json files of that split")
    parser.add_argument("--names", nargs="+", help="a name per prediction file (default: its folder's name)")
    parser.add_argument("--resamples", type=int, default=RESAMPLES, help=f"bootstrap resamples (default {RESAMPLES})")
    args = parser.parse_args(argv)
    if args.resamples < 100:  # stamlane_eval.stats' floor, checked before any file is read
        print(f"card_intervals: error: --resamples must be >= 100, got {args.resamples}", file=sys.stderr)
        return 2
    names = args.names or [path.parent.name for path in args.preds]
    if len(names) != len(args.preds):
        print(f"card_intervals: error: {len(names)} names for {len(args.preds)} prediction files", file=sys.stderr)
        return 2
    try:
        gt = read_tusimple(args.gt)
        scored = [rates_by_image(gt, path) for path in args.preds]
    except (OSError, ValueError) as err:  # the io and the evaluator raise ValueError subclasses
        print(f"card_intervals: error: {err}", file=sys.stderr)
        return 2
    images = scored[0][0]  # every file holds the gt's images once each (evaluate refuses any other), sorted alike
    clips = [str(PurePosixPath(name).parent) for name in images]
    print(f"{args.gt.name}: {len(images)} images in {len(set(clips))} clips, TuSimple F1 in %, 95 % intervals")
    rates = [r for _, r in scored]
    for name, values in zip(names, rates, strict=True):
        one = bootstrap(values, f1_of_rates, groups=clips, resamples=args.resamples)
        print(f"  {name}: {100 * one.value:.1f} {percent(one.low, one.high)}")
    for name, values in zip(names[1:], rates[1:], strict=True):
        diff = paired_bootstrap(rates[0], values, f1_of_rates, groups=clips, resamples=args.resamples)
        print(f"  {names[0]} - {name}: {100 * diff.value:+.1f} {percent(diff.low, diff.high, '+')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
