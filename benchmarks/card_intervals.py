"""A model card's TuSimple F1 with its clip-bootstrap interval, and paired differences, from prediction files.

    python benchmarks/card_intervals.py GT PRED [PRED ...] [--names A B ...] [--resamples N] [--iou 0.5]

``GT`` is a TuSimple label file (a split of a synthetic set, say ``reveal.json``); each ``PRED`` a
``predictions.json`` of ``stamlane predict`` on that split (another model, or the same one with a history probe,
``--data.history_source key``). Every file is scored as lane.py scores it, without the 200 ms limit (the run
times of a shared CPU say nothing about the model). Prints, per prediction file, the F1 with its 95 % interval,
and for every later file the difference ``first - later`` with its paired interval. The intervals resample whole
clips (an image's clip is the folder of its ``raw_file``: the synthetic splits label several key frames per clip),
by `stamlane_eval.stats`; they hold the weights fixed and say nothing about another training seed.

``--iou T`` scores the CULane-style IoU F1 at threshold ``T`` instead (0.5 or 0.3), as the experiments score it
(`stamlane.experiments.split_scores`): the labelled rows of each lane as its points, the line width scaled to the
frame width (`stamlane.predict.image_score.iou_width`), the frame size from the set's ``dataset.json`` or its first
frame (``--size WxH`` to give it).

Exit status 2, with one line on stderr naming the file or option, where a file cannot be read (not JSON lines, a
``dataset.json`` without its frame size, a first frame outside the set's folder), a prediction file does not hold
the gt's images once each, the gt names an image twice, or the split has fewer than two clips (`_harness`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from _harness import Within, clips_of, fail, option_problem
from stamlane_eval import culane
from stamlane_eval.cli_tools import parse_wxh
from stamlane_eval.io import MAX_IMAGE_SIDE, read_tusimple, tusimple_points
from stamlane_eval.stats import (
    RESAMPLES,
    bootstrap,
    culane_counts,
    f1_of_counts,
    f1_of_rates,
    paired_bootstrap,
    tusimple_rates,
)
from stamlane_eval.tusimple import TuSimpleInputError, evaluate

MAX_RESAMPLES = 20_000  # the bootstrap holds resamples x images weights (100 MB at 640 images)


def rates_by_image(gt: list[dict], pred_file: Path, gt_file: Path | None = None) -> tuple[list[str], np.ndarray]:
    """The per-image ``(fp, fn)`` rates of one prediction file, in ``raw_file`` order, with those names.

    Raises:
        ValueError: the files cannot be scored as lane.py scores them, naming the file (``gt_file``, or ``gt``) and
            the line.
    """
    preds = read_tusimple(pred_file)
    try:
        result = evaluate(preds, gt, time_limit=False)
    except TuSimpleInputError as err:  # its line, in the file it names
        where = {"gt": gt_file or "gt", "pred": pred_file}.get(err.source or "", None)
        line = f": line {err.line}" if err.line is not None else ""
        raise ValueError(f"{where}{line}: {err.message}" if where else err.message) from None
    names = [record["raw_file"] for record in preds]
    order = np.argsort(names, kind="stable")
    return [names[i] for i in order], tusimple_rates(result.per_image)[order]


def counts_by_image(
    gt: list[dict], pred_file: Path, threshold: float, size: tuple[int, int], gt_file: Path | None = None
) -> tuple[list[str], np.ndarray]:
    """The per-image ``(tp, fp, fn)`` lane counts of one prediction file at IoU ``threshold``, in ``raw_file`` order,
    with those names; the images are checked as for the TuSimple F1 (`rates_by_image`: the gt's, once each)."""
    from stamlane.predict.image_score import iou_width

    names, _ = rates_by_image(gt, pred_file, gt_file)
    lanes = {record["raw_file"]: record["lanes"] for record in read_tusimple(pred_file)}
    labels = {record["raw_file"]: record for record in gt}
    result = culane.evaluate(
        [tusimple_points(lanes[name], labels[name]["h_samples"]) for name in names],
        [tusimple_points(labels[name]["lanes"], labels[name]["h_samples"]) for name in names],
        (threshold,),
        iou_width(size),
        size,
    )
    return names, culane_counts(result.per_image, threshold)


def frame_size(text: str | None, gt_path: Path) -> tuple[int, int]:
    """``(H, W)`` from ``--size WxH``, else the set's (`stamlane.experiments.split_scores.image_size`)."""
    if text is None:
        from stamlane.experiments.split_scores import image_size

        return image_size(gt_path.parent, gt_path.stem)
    try:
        return parse_wxh(text, MAX_IMAGE_SIDE)
    except argparse.ArgumentTypeError as err:
        raise ValueError(f"--size: {err}") from None


def percent(low: float, high: float, sign: str = "") -> str:
    """An interval in %, as the docs write it; ``sign="+"`` for a difference."""
    return f"[{100 * low:{sign}.1f}, {100 * high:{sign}.1f}]"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("gt", type=Path, help="TuSimple label json-lines of the split")
    parser.add_argument("preds", type=Path, nargs="+", help="predictions.json files of that split")
    parser.add_argument("--names", nargs="+", help="a name per prediction file (default: its folder's name)")
    parser.add_argument("--resamples", type=int, default=RESAMPLES, help=f"bootstrap resamples (default {RESAMPLES})")
    parser.add_argument("--iou", type=float, help="score the IoU F1 at this threshold (0.5, 0.3) instead")
    parser.add_argument("--size", help="the frames' WxH for --iou (default: the set's dataset.json or first frame)")
    args = parser.parse_args(argv)
    # stamlane_eval.stats' floor; the ceiling bounds its weights
    if (problem := option_problem(vars(args), ranges={"resamples": Within(100, MAX_RESAMPLES)})) is not None:
        return fail("card_intervals", problem)
    if args.iou is not None and not 0 <= args.iou < 1:
        return fail("card_intervals", f"--iou must be in [0, 1), got {args.iou}")
    names = args.names or [path.parent.name for path in args.preds]
    if len(names) != len(args.preds):
        return fail("card_intervals", f"{len(names)} names for {len(args.preds)} prediction files")
    try:
        gt = read_tusimple(args.gt)
        if args.iou is None:
            scored = [rates_by_image(gt, path, args.gt) for path in args.preds]
            metric, statistic = "TuSimple F1", f1_of_rates
        else:
            size = frame_size(args.size, args.gt)
            scored = [counts_by_image(gt, path, args.iou, size, args.gt) for path in args.preds]
            metric, statistic = f"IoU F1 @{args.iou:g}", f1_of_counts
        images = scored[0][0]  # every file holds the gt's images once each (evaluate refuses any other), sorted alike
        clips = clips_of(images, args.gt)
    except (OSError, ValueError) as err:  # the io, the evaluator and _harness raise ValueError subclasses
        return fail("card_intervals", err)
    print(f"{args.gt.name}: {len(images)} images in {len(set(clips))} clips, {metric} in %, 95 % intervals")
    rates = [r for _, r in scored]
    for name, values in zip(names, rates, strict=True):
        one = bootstrap(values, statistic, groups=clips, resamples=args.resamples)
        print(f"  {name}: {100 * one.value:.1f} {percent(one.low, one.high)}")
    for name, values in zip(names[1:], rates[1:], strict=True):
        diff = paired_bootstrap(rates[0], values, statistic, groups=clips, resamples=args.resamples)
        print(f"  {names[0]} - {name}: {100 * diff.value:+.1f} {percent(diff.low, diff.high, '+')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
