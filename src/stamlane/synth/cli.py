"""``stamlane synth``: write a synthetic clip set in the TuSimple layout."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from stamlane_eval.cli_tools import OneLineParser, parse_or_status, parse_wxh

from stamlane.boundary import run_command
from stamlane.budget import check_workers
from stamlane.guard import check_outputs
from stamlane.synth.generator import EVAL_KEY_STEP, TRAIN_KEY_STEP, SynthConfig, generate_dataset

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="stamlane synth",
        description="Write synthetic road clips (clips/<id>/1..T.jpg, train/val/test/challenging.json, "
        "frame_labels/, homographies/) in the TuSimple layout.",
    )
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--clips", type=int, default=100, help="clips of train+val+test (80/10/10 %%, >= 1 each when >= 3)")
    p.add_argument(
        "--challenging-clips", type=int, default=None, help="clips of the challenging split (default clips/10)"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--size", type=parse_wxh, default=(360, 640), help="frame size WxH (default 640x360)")
    p.add_argument("--frames", type=int, default=20, help="frames per clip (default 20)")
    p.add_argument("--fps", type=float, default=SynthConfig.fps, help="frame rate of the simulated camera")
    p.add_argument(
        "--train-key-step", type=int, default=TRAIN_KEY_STEP, help="labelled key frames of train clips (0: the last)"
    )
    p.add_argument(
        "--eval-key-step", type=int, default=EVAL_KEY_STEP, help="labelled key frames of the other splits (0: the last)"
    )
    p.add_argument("--workers", type=int, default=1, help="processes rendering clips in parallel")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def split_counts(total: int) -> tuple[int, int, int]:
    """``(train, val, test)`` of ``total`` clips: 10 % each for val and test (>= 1 when total >= 3)."""
    if total < 3:
        return total, 0, 0
    val = test = max(1, round(total * 0.1))
    return total - val - test, val, test


def main(argv: list[str] | None = None) -> int:
    args = parse_or_status(_parser(), argv)
    if isinstance(args, int):
        return args
    return run_command("stamlane synth", lambda: _synth(args))


def _synth(args: argparse.Namespace) -> int:
    check_outputs(folders=[args.out])  # a folder, or missing under a writable one
    if args.clips < 1:
        print(f"stamlane synth: --clips must be >= 1, got {args.clips}", file=sys.stderr)
        return 2
    challenging = args.challenging_clips if args.challenging_clips is not None else args.clips // 10
    if challenging < 0:
        print(f"stamlane synth: --challenging-clips must be >= 0, got {challenging}", file=sys.stderr)
        return 2
    existing = [
        name for name in ("dataset.json", "train.json", "val.json", "test.json") if (Path(args.out) / name).exists()
    ]
    if existing:
        print(f"stamlane synth: {args.out} already holds a set ({existing[0]}); give another --out", file=sys.stderr)
        return 2
    for flag in ("train_key_step", "eval_key_step"):
        if getattr(args, flag) < 0:
            print(
                f"stamlane synth: --{flag.replace('_', '-')} must be >= 0, got {getattr(args, flag)}", file=sys.stderr
            )
            return 2
    if args.workers < 1:
        print(f"stamlane synth: --workers must be >= 1, got {args.workers}", file=sys.stderr)
        return 2
    check_workers(args.workers, "--workers", minimum=1)
    cfg = SynthConfig(height=args.size[0], width=args.size[1], num_frames=args.frames, fps=args.fps)
    train, val, test = split_counts(args.clips)
    start = time.perf_counter()
    info = generate_dataset(
        args.out,
        train=train,
        val=val,
        test=test,
        challenging=challenging,
        seed=args.seed,
        config=cfg,
        progress=not args.quiet,
        train_key_step=args.train_key_step,
        eval_key_step=args.eval_key_step,
        workers=args.workers,
    )
    seconds = time.perf_counter() - start
    frames = (train + val + test + challenging) * cfg.num_frames
    print(
        f"wrote {train}/{val}/{test}/{challenging} train/val/test/challenging clips to {args.out} "
        f"({frames / max(seconds, 1e-9):.1f} frames/s)"
    )
    for split, st in info["statistics"].items():
        if st["clips"]:
            print(
                f"  {split:12s} lane points hidden by vehicles {100 * st['hidden_fraction']:.1f} %, "
                f"of those visible in an aligned history frame {100 * st['revealed_fraction_of_hidden']:.1f} %, "
                f"unaligned lane shift {st['unaligned_shift_px']:.1f} px (T=4, stride 1)"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
