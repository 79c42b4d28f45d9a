"""``stamlane adapt``: a model adapted to your camera from your own unlabelled video (docs/adapt.md).

    stamlane adapt --ckpt_path MODEL --source VIDEO|DIR [--out DIR] [--steps N] [--seed S] [--synthetic ROOT]

Reads the source as ``stamlane predict --source`` does, labels its frames with the model's own predictions where a
clip agrees with itself over the ground plane (`stamlane.training.adapt`), fine-tunes the model on them mixed with
labelled synthetic clips, and writes ``OUT/adapted.ckpt`` (open it with ``stamlane predict --ckpt_path
OUT/adapted.ckpt``, ``stamlane stream --ckpt``, ...) and ``OUT/adapt.json`` (the settings and the pseudo-labels'
statistics). Bad input is one line on stderr and exit status 2, before anything is written.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from stamlane_eval.cli_tools import OneLineParser, parse_or_status

from stamlane.safety.boundary import run_command
from stamlane.safety.budget import MAX_FRAMES, MAX_WORKERS
from stamlane.safety.guard import check_outputs, exclusive, temporary_name, write_atomic
from stamlane.weights import DEFAULT, resolve

__all__ = ["CHECKPOINT_NAME", "MIN_KEY_FRAMES", "RECORD_NAME", "AdaptError", "build_parser", "main", "run"]

CHECKPOINT_NAME = "adapted.ckpt"
RECORD_NAME = "adapt.json"
MIN_KEY_FRAMES = 8
"""Key frames with a full history of their own the source must give at least (a clip of T frames at stride s needs
``(T - 1) s`` frames before its key frame): fewer are too few to adapt on."""


class AdaptError(ValueError):
    """Bad input of ``stamlane adapt`` (one line, exit status 2)."""


MAX_STEPS = 100_000
"""Optimizer steps one adaptation may ask (hours on a CPU: docs/results/timings/): a flag sizes no endless run."""
MAX_BATCH = 64
"""Real or synthetic clips in one batch: a flag sizes no batch that cannot fit in memory."""
MAX_SYNTHETIC_CLIPS = 1000
"""Synthetic clips generated when ``--synthetic`` is not given."""
MAX_TOLERANCE = 64
"""Network pixels of misregistration the agreement may allow (a dilation of that radius)."""


def _int_in(low: int, high: int | None = None) -> Callable[[str], int]:
    """An argparse type: an integer in ``[low, high]`` (no upper bound when ``high`` is None)."""

    def parse(text: str) -> int:
        value = int(text)
        if value < low or (high is not None and value > high):
            span = f">= {low}" if high is None else f"in {low}..{high:,}"
            raise argparse.ArgumentTypeError(f"expected an integer {span}, got {text}")
        return value

    return parse


def _positive_float(text: str, zero: bool = False) -> float:
    value = float(text)
    if not math.isfinite(value) or value < 0 or (value == 0 and not zero):
        raise argparse.ArgumentTypeError(f"expected a finite number {'>= 0' if zero else '> 0'}, got {text}")
    return value


def _weight(text: str) -> float:
    return _positive_float(text, zero=True)


_positive_int = _int_in(1)
_count = _int_in(0)


def _probability(text: str) -> float:
    value = float(text)
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in [0, 1], got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    from stamlane.predict.pseudo_labels import PseudoLabelConfig
    from stamlane.training.adapt import AdaptConfig

    base, pseudo = AdaptConfig(), PseudoLabelConfig()
    parser = OneLineParser(
        prog="stamlane adapt",
        description="Adapt a model to your camera from unlabelled frames: pseudo-labels that agree over each clip "
        "(the ground homography carries every history frame's lanes onto the key frame), mixed with labelled "
        "synthetic clips (docs/adapt.md).",
    )
    add = parser.add_argument
    add("--ckpt_path", required=True, help=f"the model to adapt: a checkpoint or a shipped name (e.g. {DEFAULT})")
    add("--source", required=True, help="a video file or a folder of frames of one drive (unlabelled)")
    add("--out", type=Path, help="output folder (default outputs/adapt/<model>-<source>)")
    add("--steps", type=_int_in(1, MAX_STEPS), default=base.steps, help=f"optimizer steps (default {base.steps})")
    add("--seed", type=int, default=base.seed, help="seed of the batches (default 0)")
    add("--lr", type=_positive_float, default=base.lr, help=f"encoder and decoder learning rate (default {base.lr})")
    add(
        "--fusion-lr-scale",
        type=_positive_float,
        default=base.fusion_lr_scale,
        help="the STAM's rate / --lr (default 100)",
    )
    add("--real-batch", type=_int_in(1, MAX_BATCH), default=base.real_batch, help="real clips per batch (default 2)")
    add(
        "--synthetic-batch",
        type=_int_in(0, MAX_BATCH),
        default=base.synthetic_batch,
        help="synthetic clips per batch (default 2)",
    )
    add("--real-weight", type=_weight, default=base.real_weight, help="the real clips' loss weight (default 1)")
    add("--hi", type=_probability, default=pseudo.hi, help=f"lane above this probability (default {pseudo.hi})")
    add("--lo", type=_probability, default=pseudo.lo, help=f"background below it (default {pseudo.lo})")
    add(
        "--min-agree",
        type=_int_in(0, MAX_FRAMES),
        default=pseudo.min_agree,
        help="history frames that must agree (default 2)",
    )
    add(
        "--tolerance",
        type=_int_in(0, MAX_TOLERANCE),
        default=pseudo.tolerance_px,
        help="network px of misregistration (default 1)",
    )
    add("--min-lane-pixels", type=_positive_int, default=base.min_lane_pixels, help="per kept frame (default 50)")
    add("--max-frames", type=_positive_int, help="read only the first N frames of the source")
    add("--synthetic", type=Path, help="a synthetic set (its train.json) to mix in (default: 16 clips generated)")
    add(
        "--synthetic-clips",
        type=_int_in(1, MAX_SYNTHETIC_CLIPS),
        default=16,
        help="clips generated when --synthetic is not given",
    )
    add("--threads", type=_int_in(1, MAX_WORKERS), default=2, help="torch threads (default 2)")
    add("--no-progress", action="store_true", help="no progress bars")
    return parser


def _config(args: argparse.Namespace) -> Any:
    from stamlane.predict.pseudo_labels import PseudoLabelConfig
    from stamlane.training.adapt import AdaptConfig

    pseudo = PseudoLabelConfig(hi=args.hi, lo=args.lo, min_agree=args.min_agree, tolerance_px=args.tolerance)
    return AdaptConfig(
        steps=args.steps,
        lr=args.lr,
        fusion_lr_scale=args.fusion_lr_scale,
        real_batch=args.real_batch,
        synthetic_batch=args.synthetic_batch,
        real_weight=args.real_weight,
        min_lane_pixels=args.min_lane_pixels,
        seed=args.seed,
        pseudo=pseudo,
    )


def _outputs(args: argparse.Namespace, ckpt: Path, source: Path) -> Path:
    """The output folder, checked against every input before anything is read at length or written."""
    out = args.out if args.out is not None else Path("outputs/adapt") / f"{ckpt.stem}-{source.stem}"
    beside = [ckpt.parent, *([source.parent] if source.is_file() else [])]
    for folder in beside:
        if out.resolve() == folder.resolve():
            raise AdaptError(f"--out {out}: the output would be written beside the input in {folder}")
    files = [out / CHECKPOINT_NAME, out / RECORD_NAME]
    check_outputs(
        [*files, *(temporary_name(f) for f in files)],
        reads=[ckpt, source, args.synthetic],
        folders=[out],
        protected=[source if source.is_dir() else None, args.synthetic],
    )
    return out


def _frames(source: Path, clip: Any, max_frames: int | None, stack: Any, progress: bool = True) -> Any:
    """The source's frames as ``predict --source`` reads them (`FramesDataModule`), at most ``max_frames``."""
    from stamlane.data.datamodule import FramesDataModule, SequenceWarning

    frames = FramesDataModule(str(source), clip, progress=progress)  # a video's decoding bar too
    stack.append(frames)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SequenceWarning)  # unrelated pictures agree on nothing: refused
        try:
            frames.prepare_data()
            frames.setup("predict")
        except SequenceWarning as err:
            raise AdaptError(f"{err} (adapt needs one drive: the frames of a video)") from None
    dataset = frames.dataset
    if dataset is None:  # setup made it
        raise AdaptError(f"--source {source}: no frames read")
    if max_frames is not None:
        dataset.entries = dataset.entries[:max_frames]
    need = (clip.num_frames - 1) * clip.stride + MIN_KEY_FRAMES
    if len(dataset) < need:
        raise AdaptError(
            f"--source {source} has {len(dataset)} frames: a model of {clip.num_frames}-frame clips at stride "
            f"{clip.stride} needs at least {need} to adapt on ({MIN_KEY_FRAMES} key frames with a history)"
        )
    return dataset


def run(args: argparse.Namespace) -> int:
    import torch

    from stamlane.data.anchor import anchor_clips, read_anchor
    from stamlane.training.adapt import (
        adapt_student,
        pseudo_label,
        summary_record,
        teacher_pass,
        write_adapted,
    )
    from stamlane.training.stored import StoredModel

    torch.set_num_threads(args.threads)
    config = _config(args)
    ckpt, source = Path(resolve(args.ckpt_path)), Path(args.source)
    if not ckpt.is_file():
        raise AdaptError(f"--ckpt_path {args.ckpt_path}: no such checkpoint (a file, or a shipped model's name)")
    if not source.exists():
        raise AdaptError(f"--source {source} does not exist (a video file or a folder of frames)")
    if args.synthetic is not None and not (args.synthetic / "train.json").is_file():
        raise AdaptError(f"--synthetic {args.synthetic} holds no train.json (a set of `stamlane synth`)")
    out = _outputs(args, ckpt, source)
    stored = StoredModel.open(ckpt)  # read once, the network from the closed registry
    module, clip = stored.module, stored.settings.clip
    if clip is None:
        raise AdaptError(f"--ckpt_path {ckpt} records no data options: how its clips are read is unknown")
    if clip.num_frames < 2 and config.pseudo.min_agree > 0:
        raise AdaptError(
            f"--ckpt_path {ckpt} reads single frames: no history to agree with (give --min-agree 0 for plain "
            "confidence thresholds)"
        )
    if config.pseudo.min_agree > clip.num_frames - 1:
        raise AdaptError(
            f"--min-agree {config.pseudo.min_agree}: the model's clips have {clip.num_frames - 1} history frames"
        )
    clip = replace(clip, align="fly" if clip.align != "none" else "none", cache_dir=None)
    start = time.perf_counter()
    held: list[Any] = []
    progress = not args.no_progress
    dataset = _frames(source, clip, args.max_frames, held, progress)
    seen = teacher_pass(module, dataset, progress=progress)
    labelled = pseudo_label(seen, config)
    stats = labelled.stats
    print(
        f"stamlane adapt: {stats['kept']} of {stats['with_history']} key frames pseudo-labelled "
        f"(lane {100 * stats['lane_share']:.1f} %, background {100 * stats['background_share']:.1f} %, ignored "
        f"{100 * stats['ignored_share']:.1f} % of their pixels)",
        file=sys.stderr,
    )
    if not len(labelled.clips):
        raise AdaptError(
            f"--source {source}: no key frame has {config.min_lane_pixels} lane pixels its clip agrees on "
            "(lower --hi, --min-agree or --min-lane-pixels, or check that the model finds lanes on these frames)"
        )
    with tempfile.TemporaryDirectory(prefix="stamlane-anchor-") as scratch:
        synthetic = None
        if config.synthetic_batch > 0:
            if args.synthetic is not None:
                synthetic, named = read_anchor(args.synthetic, clip), str(args.synthetic)
            else:
                synthetic = anchor_clips(scratch, clip, args.synthetic_clips, seed=0)
                named = f"{args.synthetic_clips} generated dashcam3 clips (seed 0)"
        else:
            named = "none"
        history = adapt_student(module, labelled, synthetic, config, progress=progress)
    record = summary_record(ckpt, source, config, labelled, history, named, time.perf_counter() - start)
    out.mkdir(parents=True, exist_ok=True)
    with exclusive(out):
        write_adapted(ckpt, module, out / CHECKPOINT_NAME, record)
        write_atomic(out / RECORD_NAME, json.dumps(record, indent=2) + "\n")
    print(f"stamlane adapt: wrote {out / CHECKPOINT_NAME} ({record['minutes']} min)", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``stamlane adapt``; returns the exit status."""
    args = parse_or_status(build_parser(), sys.argv[1:] if argv is None else argv)
    if isinstance(args, int):
        return args
    status = run_command("stamlane adapt", lambda: run(args), AdaptError)
    return int(status)
