"""``stamlane show``: a picture grid of clips with their targets and lanes, for checking a conversion.

Each row is one sample at the network size: its T frames (key last, as the network sees them, aligned
when ``--align`` asks), then the key frame with the instance target tinted per lane and the labelled
lanes (mapped from original pixels with ``net_from_orig``) drawn as dots.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import cv2
import numpy as np
from stamlane_eval.cli_tools import OneLineParser, parse_or_status, parse_wxh

from stamlane.data.alignment import ALIGN_MODES
from stamlane.data.clips import ClipDataset
from stamlane.data.layouts import FORMATS, make_clips
from stamlane.data.options import ClipOptions
from stamlane.data.transforms import ClipTransform
from stamlane.safety.boundary import run_command
from stamlane.safety.guard import atomic_path, check_outputs, temporary_name

__all__ = ["build_parser", "main", "render_grid"]

PALETTE = [(0, 0, 255), (0, 255, 0), (255, 0, 0), (0, 255, 255), (255, 0, 255), (255, 255, 0), (0, 128, 255)]


def render_grid(dataset: ClipDataset, indices: list[int]) -> np.ndarray:
    """BGR uint8 grid: one row per sample, T frames then the key frame with targets and lanes."""
    rows = []
    for i in indices:
        s = dataset[i]
        frames = (s["frames"].numpy().transpose(0, 2, 3, 1) * 255).round().astype(np.uint8)
        tiles = [cv2.cvtColor(f, cv2.COLOR_RGB2BGR) for f in frames]
        key = tiles[-1].copy()
        inst = s["instance"].numpy()
        for k in range(1, int(inst.max()) + 1):
            key[inst == k] = PALETTE[(k - 1) % len(PALETTE)]
        m = np.asarray(s["meta"]["net_from_orig"])
        for lane in ClipTransform.map_lanes(s["lanes"], m):
            for x, y in lane:
                cv2.circle(key, (round(float(x)), round(float(y))), 2, (255, 255, 255), -1, lineType=cv2.LINE_AA)
        tiles.append(key)
        row = np.concatenate([np.pad(t, ((2, 2), (2, 2), (0, 0)), constant_values=40) for t in tiles], axis=1)
        cv2.putText(
            row, s["meta"]["raw_file"][-60:], (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA
        )
        rows.append(row)
    return np.concatenate(rows, axis=0)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="stamlane show", description=__doc__.splitlines()[0])
    p.add_argument("--root", required=True, help="data root")
    p.add_argument("--labels", required=True, nargs="+", help="label (TuSimple) or list files, relative to root")
    p.add_argument("--out", required=True, help="output image (.png or .jpg)")
    p.add_argument("--n", type=int, default=8, help="samples to show (spread over the set)")
    p.add_argument("--format", default="tusimple", choices=FORMATS)
    p.add_argument("--num-frames", type=int, default=4)
    p.add_argument("--stride", type=int, default=1)
    p.add_argument("--size", type=parse_wxh, default=(128, 256), help="network size WxH (default 256x128)")
    p.add_argument("--align", default="none", choices=ALIGN_MODES)
    p.add_argument("--cache-dir", default=None)
    p.add_argument("--label-dir", default=None, help="ApolloScape: folder mirroring the images with .lines.txt")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parse_or_status(build_parser(), argv)
    if isinstance(args, int):
        return args
    return run_command("stamlane show", lambda: _show(args))


def _show(args: argparse.Namespace) -> int:
    if args.n < 1:
        raise ValueError(f"--n must be >= 1, got {args.n}")
    out = Path(args.out)
    labels = [Path(args.root) / name for name in args.labels]
    check_outputs(  # a picture never replaces a frame, a label or the alignment cache of the data
        [out, temporary_name(out)], [*labels, args.label_dir, args.cache_dir], protected=[args.root]
    )
    clip = ClipOptions(args.num_frames, args.stride, args.size, align=args.align, cache_dir=args.cache_dir)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        label_dir = args.label_dir if args.format == "apollo" else None
        ds: ClipDataset = make_clips(args.format, args.root, args.labels, label_dir, clip=clip)
    if len(ds) == 0:
        raise ValueError(f"no samples in {' '.join(args.labels)} under {args.root}")
    indices = sorted({int(i) for i in np.linspace(0, len(ds) - 1, min(args.n, len(ds)))})
    grid = render_grid(ds, indices)
    with atomic_path(out) as tmp:
        if not cv2.imwrite(str(tmp), grid):
            raise ValueError(f"cannot write {out} (unknown image extension?)")
    print(f"wrote {out} ({len(indices)} clips of {args.num_frames} frames)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
