"""``stamlane align``: precompute ``key_from_hist`` for every clip of a dataset into a JSON cache.

    stamlane align DATA_ROOT --cache CACHE_DIR [--num-frames 5] [--stride 1] [--key-frames last|all]
                   [--horizon-row ROW] [--strategy chain|direct] [--workers 1] [--visualize DIR]
                   [--write-frames OUT]

Walks ``DATA_ROOT`` for clip folders (any folder with numbered frames ``<n>.jpg``/``<n>.png``), and for each
key frame estimates the homography of its ``num_frames - 1`` previous frames (every ``stride``-th). Writes
one JSON per clip folder (layout in ``stamlane.align.cache``); clip folders whose JSON already covers the
request are skipped, so an interrupted run resumes. numpy/OpenCV only: no torch import.

``--write-frames OUT`` also writes the aligned frames of every requested key frame (``--key-frames last``:
the last frame of each folder, TuSimple's labelled ``20.jpg``; ``all``: every frame, e.g. CULane / VIL-100,
whose frames are all labelled) under ``OUT/<clip folder relative to root>/`` (see ``stamlane.align.export``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np
from stamlane_eval.cli_tools import OneLineParser, parse_or_status
from tqdm import tqdm

from stamlane.align.cache import (
    CacheDict,
    alignment_from_json,
    alignment_to_json,
    cache_file,
    find_clip_dirs,
    list_frames,
    merge_cache,
    read_cache,
)
from stamlane.align.export import MANIFEST_NAME, mirror, missing_outputs, write_aligned_frames
from stamlane.align.homography import (
    DEFAULT_HORIZON_FRACTION,
    AlignConfig,
    Alignment,
    FramePrep,
    estimate_prepared,
    resolve_horizon_row,
)
from stamlane.align.warp import Strategy, alignments_to_key
from stamlane.safety.budget import check_workers
from stamlane.safety.guard import atomic_path, check_outputs, make_folder
from stamlane.safety.images import read_image

__all__ = ["AlignJob", "ClipResult", "build_parser", "main", "process_clip"]


@dataclass(frozen=True)
class AlignJob:
    """What to compute for every clip folder (picklable, sent to the workers)."""

    root: Path
    cache_dir: Path
    num_frames: int = 5
    stride: int = 1
    key_frames: str = "last"
    horizon: int | None = None
    """First row of the ground region in pixels; None: ``round(0.45 * H)`` of each clip's frames."""
    strategy: Strategy = "chain"
    visualize_dir: Path | None = None
    frames_dir: Path | None = None


class ClipResult(NamedTuple):
    """What ``process_clip`` did to one clip folder."""

    status: str
    """``"done"`` (cache computed) or ``"skipped"`` (the cache already covered the request)."""
    pairs: int
    """frame pairs estimated."""
    ok: int
    """of which succeeded."""
    written: int = 0
    """files written under ``--write-frames`` (key frame copies included)."""
    unaligned: int = 0
    """of which history frames written UNWARPED because their alignment failed."""
    unreadable: tuple[str, ...] = ()
    """frames that could not be read (missing, truncated, not an image): their pairs are cached as failed."""


def requested_pairs(num_frames_in_clip: int, job: AlignJob) -> dict[int, list[int]]:
    """``{key index: [history indices, oldest first]}`` of one clip."""
    keys = range(num_frames_in_clip) if job.key_frames == "all" else [num_frames_in_clip - 1]
    out = {}
    for k in keys:
        hist = [k - job.stride * j for j in range(job.num_frames - 1, 0, -1)]
        out[k] = [i for i in hist if i >= 0]
    return out


def _covered(existing: CacheDict, frames: list[Path], pairs: dict[int, list[int]]) -> bool:
    """Whether every requested pair has a whole entry (a damaged one, `alignment_from_json`, is estimated again)."""

    def whole(key: str, hist: str) -> bool:
        entries = existing.get(key)
        if not isinstance(entries, dict) or hist not in entries:
            return False
        try:
            alignment_from_json(entries[hist])
        except ValueError:
            return False
        return True

    return all(whole(frames[k].name, frames[i].name) for k, hist in pairs.items() for i in hist)


class _Clip:
    """Frames of one clip read and prepared on first use."""

    def __init__(self, frames: list[Path], job: AlignJob, cfg: AlignConfig) -> None:
        self.frames, self.job, self.cfg = frames, job, cfg
        self.images: dict[int, np.ndarray | None] = {}
        self.preps: dict[tuple[int, int], FramePrep] = {}
        self.pairs: dict[tuple[int, int], Alignment] = {}

    def image(self, i: int) -> np.ndarray | None:
        if i not in self.images:
            self.images[i] = read_image(self.frames[i])  # None: missing, truncated or not an image
        return self.images[i]

    def estimate(self, i: int, k: int) -> Alignment:
        """Alignment of frame ``i`` to frame ``k``, computed once (chains of several key frames share links)."""
        if (i, k) not in self.pairs:
            self.pairs[(i, k)] = self._estimate(i, k)
        return self.pairs[(i, k)]

    def _estimate(self, i: int, k: int) -> Alignment:
        hist, key = self.image(i), self.image(k)
        if hist is None or key is None:
            bad = self.frames[i if hist is None else k].name
            return Alignment.failed(f"could not read {bad}")
        if hist.shape != key.shape:
            return Alignment.failed(
                f"size mismatch: {self.frames[i].name} {hist.shape} vs {self.frames[k].name} {key.shape}"
            )
        row = resolve_horizon_row(self.job.horizon, key.shape[0])
        return estimate_prepared(self.prep(i, row), self.prep(k, row), self.cfg)

    def prep(self, i: int, row: int) -> FramePrep:
        if (i, row) not in self.preps:
            image = self.image(i)
            assert image is not None  # _estimate read both frames before it asks
            self.preps[(i, row)] = FramePrep(image, row, self.cfg)
        return self.preps[(i, row)]


def process_clip(clip_dir: Path, job: AlignJob) -> ClipResult:
    """Compute and write one clip folder's cache (and its aligned frames with ``job.frames_dir``)."""
    frames = list_frames(clip_dir)
    pairs = requested_pairs(len(frames), job)
    path = cache_file(job.cache_dir, job.root, clip_dir)
    existing = read_cache(path)
    covered = _covered(existing, frames, pairs)
    out_dir = mirror(job.frames_dir, job.root, clip_dir) if job.frames_dir is not None else None
    if covered and (out_dir is None or not missing_outputs(out_dir, frames, pairs)):
        return ClipResult("skipped", 0, 0)
    cv2.setNumThreads(1)
    cfg = AlignConfig()
    clip = _Clip(frames, job, cfg)
    n_pairs = n_ok = 0
    new: CacheDict = {}
    if not covered:
        for k, hist in pairs.items():
            seq = [*hist, k]  # oldest first, key last
            key = clip.image(k)
            shape = key.shape[:2] if key is not None else (720, 1280)  # only for checks; every pair fails then

            def estimate(a: int, b: int, seq: list[int] = seq) -> Alignment:
                return clip.estimate(seq[a], seq[b])

            alignments = alignments_to_key(
                len(seq),
                estimate,
                shape,
                resolve_horizon_row(job.horizon, shape[0]),
                cfg,
                job.strategy,
            )
            entry = new.setdefault(frames[k].name, {})
            for i, alignment in zip(hist, alignments, strict=True):
                entry[frames[i].name] = alignment_to_json(alignment)
                n_pairs += 1
                n_ok += bool(alignment.ok)
        existing = merge_cache(path, new)  # under a lock: a concurrent run's entries are kept
        if job.visualize_dir is not None:
            _visualize(clip, clip_dir, pairs, job)
    written = unaligned = 0
    if out_dir is not None:
        written, unaligned = write_aligned_frames(out_dir, frames, pairs, existing, clip.image)
    unreadable = tuple(str(clip.frames[i]) for i, image in sorted(clip.images.items()) if image is None)
    return ClipResult("skipped" if covered else "done", n_pairs, n_ok, written, unaligned, unreadable)


def _visualize(clip: _Clip, clip_dir: Path, pairs: dict[int, list[int]], job: AlignJob) -> None:
    from stamlane.align.visualize import draw_alignment  # only when asked for

    k = max(pairs)
    if not pairs[k]:
        return
    i = pairs[k][-1]  # the nearest history frame
    hist, key = clip.image(i), clip.image(k)
    if hist is None or key is None or hist.shape != key.shape:
        return
    row = resolve_horizon_row(job.horizon, key.shape[0])
    picture = draw_alignment(hist, key, clip.estimate(i, k), row, clip.cfg)
    rel = clip_dir.resolve().relative_to(job.root.resolve())
    name = "__".join(rel.parts) or "root"
    assert job.visualize_dir is not None  # asked for (--visualize)
    make_folder(job.visualize_dir, "--visualize")
    target = job.visualize_dir / f"{name}_{clip.frames[k].stem}_{clip.frames[i].stem}.jpg"
    with atomic_path(target) as tmp:  # whole or not at all; a full disk is said, not skipped
        if not cv2.imwrite(str(tmp), picture):
            raise OSError(f"--visualize: cannot write {target}")


def _run_one(task: tuple[Path, AlignJob]) -> ClipResult:
    return process_clip(*task)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="stamlane align", description="Precompute key_from_hist for every clip of a dataset into a JSON cache."
    )
    p.add_argument("root", type=Path, help="dataset root to walk for clip folders")
    p.add_argument("--cache", type=Path, default=None, help="cache folder (default outputs/align/<root name>)")
    p.add_argument("--num-frames", type=int, default=5, help="frames per clip including the key frame (default 5)")
    p.add_argument("--stride", type=int, default=1, help="step between the frames used (default 1)")
    p.add_argument("--key-frames", choices=("last", "all"), default="last", help="which frames are key frames")
    p.add_argument(
        "--horizon-row",
        type=int,
        default=None,
        help=f"first image row of the ground region in pixels (default round({DEFAULT_HORIZON_FRACTION} x height))",
    )
    p.add_argument(
        "--strategy", choices=("chain", "direct"), default="chain", help="see stamlane.align.align_clip (default chain)"
    )
    p.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    p.add_argument("--visualize", type=Path, default=None, metavar="DIR", help="write a picture per clip here")
    p.add_argument(
        "--write-frames",
        type=Path,
        default=None,
        metavar="OUT",
        help="also write each key frame's history frames warped onto it under OUT/<clip folder>/ "
        "as <key>_back<n>.jpg, with aligned.json saying which alignments failed (written unwarped)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv: list[str]) -> int:
    """Run ``stamlane align``; returns the exit status (2 on bad input)."""
    args = parse_or_status(build_parser(), argv)
    if isinstance(args, int):
        return args
    problems = [
        (args.num_frames < 2, f"--num-frames must be >= 2, got {args.num_frames}"),
        (args.stride < 1, f"--stride must be >= 1, got {args.stride}"),
        (args.workers < 1, f"--workers must be >= 1, got {args.workers}"),
        (args.horizon_row is not None and args.horizon_row < 0, f"--horizon-row must be >= 0, got {args.horizon_row}"),
        (not args.root.is_dir(), f"dataset root {args.root} is not a folder"),
        (
            args.write_frames is not None and args.write_frames.exists() and not args.write_frames.is_dir(),
            f"--write-frames {args.write_frames} is not a folder",
        ),
    ]
    for bad, message in problems:
        if bad:
            print(f"stamlane align: {message}", file=sys.stderr)
            return 2
    cache_dir = args.cache or Path("outputs") / "align" / args.root.resolve().name
    for option, out in (("--write-frames", args.write_frames), ("--visualize", args.visualize), ("--cache", cache_dir)):
        try:  # warped frames and pictures never land among the frames they are made from (symlinks resolved)
            check_outputs(folders=[out], protected=[args.root] if option != "--cache" else [])
        except ValueError as err:
            print(f"stamlane align: {option} {err}", file=sys.stderr)
            return 2
    try:
        check_workers(args.workers, "--workers", minimum=1)
    except ValueError as err:
        print(f"stamlane align: {err}", file=sys.stderr)
        return 2
    root = args.root.resolve()  # clip folders are then absolute; cache_file reads relative ones as under root
    clips = find_clip_dirs(root)
    if not clips:
        print(f"stamlane align: no clip folders (numbered frames <n>.jpg/.png) under {args.root}", file=sys.stderr)
        return 2
    job = AlignJob(
        root,
        cache_dir,
        args.num_frames,
        args.stride,
        args.key_frames,
        args.horizon_row,
        args.strategy,
        args.visualize,
        args.write_frames,
    )
    if args.write_frames is not None:
        try:
            args.write_frames.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            print(f"stamlane align: cannot create --write-frames {args.write_frames}: {err}", file=sys.stderr)
            return 2
    tasks = [(clip, job) for clip in clips]
    bar = tqdm(total=len(tasks), desc="align", unit="clip", disable=args.quiet)
    done = skipped = pairs = ok = written = unaligned = 0
    unreadable: tuple[str, ...] = ()
    results: Iterator[ClipResult]
    if args.workers == 1:
        results = map(_run_one, tasks)
        pool = None
    else:
        pool = get_context("spawn").Pool(args.workers)
        results = pool.imap_unordered(_run_one, tasks, chunksize=1)
    try:
        for result in results:
            done += result.status == "done"
            skipped += result.status == "skipped"
            pairs, ok = pairs + result.pairs, ok + result.ok
            written, unaligned = written + result.written, unaligned + result.unaligned
            unreadable += result.unreadable
            bar.update(1)
    except (OSError, ValueError) as err:  # e.g. a full disk under --write-frames, a --horizon-row below the frames
        if pool is not None:
            pool.terminate()
        print(f"stamlane align: {err}", file=sys.stderr)
        return 2
    finally:
        bar.close()
        if pool is not None:
            pool.close()
            pool.join()
    rate = f", {100 * ok / pairs:.1f} % ok" if pairs else ""
    print(f"aligned {done} clip folders ({skipped} already cached), {pairs} frame pairs{rate}; cache: {cache_dir}")
    if args.write_frames is not None:
        print(
            f"wrote {written} frames to {args.write_frames}; {unaligned} history frames written UNWARPED "
            f"(alignment failed: ok=false in each folder's {MANIFEST_NAME})"
        )
    if unreadable:  # not a success: the data has frames nobody can use (their pairs are cached as failed)
        more = f" and {len(unreadable) - 1} more" if len(unreadable) > 1 else ""
        print(
            f"stamlane align: cannot read frame {unreadable[0]}{more} (missing, truncated or not an image)",
            file=sys.stderr,
        )
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
