"""``stamlane synth``: write a synthetic clip set in the TuSimple layout."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from stamlane_eval.cli_tools import OneLineParser, parse_or_status, parse_wxh

from stamlane.safety.boundary import run_command
from stamlane.safety.budget import check_workers
from stamlane.safety.guard import check_outputs
from stamlane.safety.owner import claim, mark
from stamlane.synth.config import FACTORS, LABEL_LANES, SynthConfig, counts_of_total
from stamlane.synth.dataset import generate_dataset
from stamlane.synth.layout import DEMO_SPLITS, EVAL_KEY_STEP, REVEAL_FRAMES, TRAIN_KEY_STEP, SplitCounts
from stamlane.synth.tusimple_layout import LAYOUTS
from stamlane.synth.worlds import WORLDS

SYNTH_OWNER = {"command": "synth"}
"""What ``synth --out``'s owner file says: a folder synth wrote (`stamlane.safety.owner`); with the layout and the
set it writes (`_owner`)."""

__all__ = ["build_parser", "main"]
_RANDOMISABLE = tuple(name for name, world in WORLDS.items() if world.randomisable)
"""The worlds ``--randomise`` takes (their sensor draws the colour cast)."""


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="stamlane synth",
        description="Write synthetic road clips (clips/<id>/1..T.jpg, train/val/test/challenging.json, "
        "frame_labels/, homographies/); with --layout tusimple in TuSimple's own layout (clips/<date>/<id>/, "
        "label_data_0313.json .. test_label.json, the last frame labelled, h_samples 160-710 at 720 rows).",
    )
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--clips", type=int, default=100, help="clips of train+val+test (80/10/10 %%, >= 1 each when >= 3)")
    p.add_argument(
        "--challenging-clips",
        type=int,
        default=None,
        help=f"clips of the challenging split (default clips/10, at least one per factor: {len(FACTORS)})",
    )
    p.add_argument(
        "--reveal-clips", type=int, default=None, help="clips of the reveal split (default 3 per 10 of --clips, >= 3)"
    )
    p.add_argument(
        "--reveal-traffic-clips",
        type=int,
        default=None,
        help="clips of the reveal-traffic split (default 2 per 10 of --clips, >= 2)",
    )
    p.add_argument("--train-factors", type=int, default=0, help="factor clips added to the train split (default 0)")
    p.add_argument("--val-factors", type=int, default=0, help="factor clips added to the val split (default 0)")
    p.add_argument(
        "--train-motion", type=int, default=0, help="clips with the reveal splits' ego motion added to train"
    )
    p.add_argument(
        "--demo",
        action="store_true",
        help="the demo's own set (what `stamlane demo` generates; every count, size and key step its default)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--size",
        type=parse_wxh,
        default=(SynthConfig.height, SynthConfig.width),
        help=f"frame size WxH (default {SynthConfig.width}x{SynthConfig.height})",
    )
    p.add_argument("--frames", type=int, default=20, help="frames per clip (default 20)")
    p.add_argument("--fps", type=float, default=SynthConfig.fps, help="frame rate of the simulated camera")
    p.add_argument(
        "--layout",
        choices=LAYOUTS,
        default="stamlane",
        help="stamlane: clips/<id>/, every key-step-th frame labelled (default); tusimple: TuSimple's own layout",
    )
    p.add_argument(
        "--train-key-step",
        type=int,
        default=None,
        help=f"labelled key frames of train clips (0: the last; default {TRAIN_KEY_STEP}, tusimple 0)",
    )
    p.add_argument(
        "--eval-key-step",
        type=int,
        default=None,
        help=f"labelled key frames of the other splits (0: the last; default {EVAL_KEY_STEP}, tusimple 0)",
    )
    p.add_argument(
        "--world",
        choices=tuple(WORLDS),
        default="classic",
        help="; ".join(f"{name}: {world.description}" for name, world in WORLDS.items())
        + " (default classic; docs/data.md)",
    )
    p.add_argument(
        "--randomise", action="store_true", help=f"worlds {', '.join(_RANDOMISABLE)}: a random colour cast per clip"
    )
    p.add_argument(
        "--label-lanes",
        choices=LABEL_LANES,
        default="all",
        help="all: label every mark in view (default); adjacent: TuSimple's convention, the marks of the ego lane and "
        "of the lanes beside it",
    )
    p.add_argument("--workers", type=int, default=1, help="processes rendering clips in parallel")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parse_or_status(build_parser(), argv)
    if isinstance(args, int):
        return args
    return run_command("stamlane synth", lambda: _synth(args))


def _synth(args: argparse.Namespace) -> int:
    check_outputs(folders=[args.out])  # a folder, or missing under a writable one
    if args.clips < 1:
        print(f"stamlane synth: --clips must be >= 1, got {args.clips}", file=sys.stderr)
        return 2
    flags = {
        "challenging-clips": args.challenging_clips,
        "reveal-clips": args.reveal_clips,
        "reveal-traffic-clips": args.reveal_traffic_clips,
        "train-factors": args.train_factors,
        "val-factors": args.val_factors,
        "train-motion": args.train_motion,
    }
    for flag, n in flags.items():
        if n is not None and n < 0:
            print(f"stamlane synth: --{flag} must be >= 0, got {n}", file=sys.stderr)
            return 2
    # by default every factor has a clip: a small set's challenging-<factor>.json files are never empty
    counts = counts_of_total(args.clips, **{f.removesuffix("-clips").replace("-", "_"): n for f, n in flags.items()})
    # never written over: a folder holding anything synth did not write (its owner file), whatever the names; one of
    # synth's own holding a whole set (an interrupted one is written again)
    if (Path(args.out) / "dataset.json").exists():  # written last by either layout: a whole set
        print(f"stamlane synth: {args.out} already holds a set (dataset.json); give another --out", file=sys.stderr)
        return 2
    tusimple = args.layout == "tusimple"
    if args.demo and tusimple:
        print(
            "stamlane synth: --demo writes the demo's own set, in the generator's layout: drop --layout",
            file=sys.stderr,
        )
        return 2
    for flag, default in (("train_key_step", TRAIN_KEY_STEP), ("eval_key_step", EVAL_KEY_STEP)):
        if tusimple and getattr(args, flag):
            print(
                f"stamlane synth: TuSimple's layout labels the last frame alone: --{flag.replace('_', '-')} must be 0, "
                f"got {getattr(args, flag)}",
                file=sys.stderr,
            )
            return 2
        if getattr(args, flag) is None:
            setattr(args, flag, 0 if tusimple else default)
        if getattr(args, flag) < 0:
            print(
                f"stamlane synth: --{flag.replace('_', '-')} must be >= 0, got {getattr(args, flag)}", file=sys.stderr
            )
            return 2
    if args.workers < 1:
        print(f"stamlane synth: --workers must be >= 1, got {args.workers}", file=sys.stderr)
        return 2
    check_workers(args.workers, "--workers", minimum=1)
    if args.randomise and not WORLDS[args.world].randomisable:
        print(
            f"stamlane synth: --randomise is an option of the dashcam worlds (--world {', '.join(_RANDOMISABLE)})",
            file=sys.stderr,
        )
        return 2
    cfg = SynthConfig(
        height=args.size[0],
        width=args.size[1],
        num_frames=args.frames,
        fps=args.fps,
        world=args.world,
        randomise=args.randomise,
        label_lanes=args.label_lanes,
    )
    settings = {"train_key_step": args.train_key_step, "eval_key_step": args.eval_key_step, "seed": args.seed}
    settings |= {"layout": args.layout}
    if args.demo:  # the demo's set, as ``data.synth``'s defaults make it (stamlane.data.options.SynthOptions)
        counts = DEMO_SPLITS
        settings = {"train_key_step": TRAIN_KEY_STEP, "eval_key_step": EVAL_KEY_STEP, "seed": 0, "layout": "stamlane"}
        cfg = SynthConfig(world=args.world, randomise=args.randomise, label_lanes=args.label_lanes)
    # an interrupted set is written again only as it was asked: another layout or set would leave its files beside
    owner = _owner(args.layout, counts, cfg, settings)
    claim(args.out, owner, "--out", strict=True)
    start = time.perf_counter()
    mark(args.out, owner)
    info = generate_dataset(args.out, counts, **settings, config=cfg, progress=not args.quiet, workers=args.workers)
    seconds = time.perf_counter() - start
    long = counts.reveal + counts.reveal_traffic + counts.train_motion
    frames = (counts.total() - long) * cfg.num_frames + long * REVEAL_FRAMES
    print(
        f"wrote {' / '.join(str(st['clips']) for st in info['statistics'].values())} "
        f"{' / '.join(info['statistics'])} clips to {args.out} ({frames / max(seconds, 1e-9):.1f} frames/s)"
    )
    for split, st in info["statistics"].items():
        if st["clips"]:
            print(
                f"  {split:12s} lane points hidden by an occluder {100 * st['hidden_fraction']:.1f} %, "
                f"of those visible in an aligned history frame {100 * st['revealed_fraction_of_hidden']:.1f} %, "
                f"unaligned lane shift {st['unaligned_shift_px']:.1f} px (T=4, stride 1)"
            )
    return 0


def _owner(layout: str, counts: SplitCounts, cfg: SynthConfig, settings: dict[str, object]) -> dict[str, str]:
    """The owner file of a set: its layout, and the rest of what names and counts its files, in words. A folder an
    interrupted run left is written again only by the same layout and set (an other one would leave the first
    one's label files and clips beside the new ones: refused in one line by `stamlane.safety.owner.claim`)."""
    counted = ", ".join(f"{name} {n}" for name, n in counts.as_dict().items() if n)
    steps = f"key steps {settings['train_key_step']}/{settings['eval_key_step']}, seed {settings['seed']}"
    world = f"{cfg.world} world{' randomised' if cfg.randomise else ''}, labels {cfg.label_lanes}"
    described = (
        f"{cfg.width}x{cfg.height}, {cfg.num_frames} frames at {cfg.fps:g} fps, {steps}, {world}; clips: {counted}"
    )
    return SYNTH_OWNER | {"layout": layout, "set": described}


if __name__ == "__main__":
    sys.exit(main())
