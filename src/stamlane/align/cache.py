"""The homography cache written by ``stamlane align`` and read by the data pipeline.

Layout: one JSON file per clip folder, ``<cache_dir>/<clip folder relative to root>.json``::

    {"<key frame file name>": {"<history frame file name>": {
        "key_from_hist": [[...], [...], [...]], "ok": true, "num_matches": 120, "num_inliers": 96, "reason": ""}}}

A clip folder is any folder holding numbered frames ``<n>.jpg`` / ``<n>.png`` (TuSimple
``clips/<date>/<id>/1..20.jpg``, synthetic ``clips/<id>/1..20.jpg``, VIL-100 ``JPEGImages/<video>/00000.jpg``);
a dataset root that is itself a clip folder is cached as ``<cache_dir>/__root__.json``.

The data pipeline's own cache (`PairCache`, ``align: fly``) keeps ORB frame-pair estimates by CONTENT instead: one
file per pair, named by the digest of both frames' pixels (`frame_digest`) with the estimation settings, the
OpenCV and numpy versions and `PAIR_CACHE_VERSION` (`pair_key`), in ``<data root>/`` `PAIR_CACHE_DIR`; entries in
the format above (`alignment_to_json`). A frame rewritten with other pixels has another digest, so a stale entry
is never read; every training run, prediction pass, probe, model and seed on the same frames reads the pairs the
first one estimated (`estimate_clip_cached`), and the homographies are the estimated ones bit for bit (JSON keeps
a float64 exactly).
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from stamlane.align.homography import AlignConfig, Alignment, FramePrep, estimate_prepared, resolve_horizon_row
from stamlane.align.warp import Strategy
from stamlane.safety.guard import GuardError, is_inside, read_inside, write_atomic

__all__ = [
    "FRAME_SUFFIXES",
    "PAIR_CACHE_DIR",
    "PAIR_CACHE_VERSION",
    "ROOT_CACHE_NAME",
    "PairCache",
    "alignment_from_json",
    "alignment_to_json",
    "cache_file",
    "estimate_clip_cached",
    "find_clip_dirs",
    "frame_digest",
    "list_frames",
    "load_alignment",
    "merge_cache",
    "pair_key",
    "read_cache",
    "write_cache",
]

FRAME_SUFFIXES = (".jpg", ".jpeg", ".png")
ROOT_CACHE_NAME = "__root__.json"

CacheDict = dict[str, dict[str, dict[str, Any]]]
"""A clip's cache (or an aligned folder's manifest): key frame name -> history frame name -> its JSON record."""


def list_frames(clip_dir: str | os.PathLike[str]) -> list[Path]:
    """The numbered frames ``<n>.jpg|.jpeg|.png`` of a folder, in frame-number order (oldest first)."""
    frames = [
        p for p in Path(clip_dir).iterdir() if p.suffix.lower() in FRAME_SUFFIXES and p.stem.isdigit() and p.is_file()
    ]
    return sorted(frames, key=lambda p: (int(p.stem), p.name))


def find_clip_dirs(root: str | os.PathLike[str], min_frames: int = 2) -> list[Path]:
    """Every folder under ``root`` (``root`` included) holding at least ``min_frames`` numbered frames, sorted."""
    root = Path(root)
    found = []
    for folder, _, files in os.walk(root):
        n = sum(1 for f in files if Path(f).suffix.lower() in FRAME_SUFFIXES and Path(f).stem.isdigit())
        if n >= min_frames:
            found.append(Path(folder))
    return sorted(found)


def cache_file(
    cache_dir: str | os.PathLike[str], root: str | os.PathLike[str], clip_dir: str | os.PathLike[str]
) -> Path:
    """``<cache_dir>/<clip_dir relative to root>.json``.

    Args:
        cache_dir: the cache's folder.
        root: the dataset root the command walked.
        clip_dir: a clip folder under ``root`` (absolute, or relative to ``root``).

    Raises:
        ValueError: when ``clip_dir`` is not inside ``root``.
    """
    root = Path(root).resolve()
    clip = Path(clip_dir)
    clip = (clip if clip.is_absolute() else root / clip).resolve()
    try:
        rel = clip.relative_to(root)
    except ValueError:
        raise ValueError(f"clip folder {clip_dir} is not inside the dataset root {root}") from None
    if rel == Path("."):
        return Path(cache_dir) / ROOT_CACHE_NAME
    return Path(cache_dir) / rel.parent / f"{rel.name}.json"


def alignment_to_json(alignment: Alignment) -> dict[str, Any]:
    """One cache entry."""
    return {
        "key_from_hist": np.asarray(alignment.key_from_hist, float).tolist(),
        "ok": bool(alignment.ok),
        "num_matches": int(alignment.num_matches),
        "num_inliers": int(alignment.num_inliers),
        "reason": str(alignment.reason),
    }


def alignment_from_json(entry: dict[str, Any]) -> Alignment:
    """Inverse of ``alignment_to_json``."""
    return Alignment(
        np.asarray(entry["key_from_hist"], np.float64).reshape(3, 3),
        int(entry.get("num_matches", 0)),
        int(entry.get("num_inliers", 0)),
        bool(entry.get("ok", False)),
        str(entry.get("reason", "")),
    )


def read_cache(path: str | os.PathLike[str]) -> CacheDict:
    """A clip's cache file, or ``{}`` when it does not exist or cannot be parsed."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError):
        return {}
    return data if isinstance(data, dict) else {}


def write_cache(path: str | os.PathLike[str], data: CacheDict) -> None:
    """Write a clip's cache file atomically (a crash never leaves a half-written file to be skipped later)."""
    write_atomic(path, json.dumps(data))


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    """An exclusive lock on ``<path>.lock`` (POSIX ``flock``) while the block runs: one writer at a time."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_name(path.name + ".lock"), "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def merge_cache(path: str | os.PathLike[str], entries: CacheDict) -> CacheDict:
    """Add ``entries`` (``{key frame: {history frame: alignment json}}``) to a clip's cache file and return the
    merged content. The read-merge-write runs under a file lock, so two ``stamlane align`` runs on one cache
    keep each other's entries (a plain read-then-write lost those the other run wrote in between)."""
    path = Path(path)
    with _locked(path):
        data = read_cache(path)
        for key, hist in entries.items():
            data.setdefault(key, {}).update(hist)
        write_cache(path, data)
    return data


@lru_cache(maxsize=64)
def _read_cached(path: str, mtime_ns: int) -> CacheDict:
    return read_cache(path)


def load_alignment(
    cache_dir: str | os.PathLike[str],
    root: str | os.PathLike[str],
    key_path: str | os.PathLike[str],
    hist_path: str | os.PathLike[str],
) -> Alignment | None:
    """The cached alignment of a history frame to a key frame, or ``None`` when it is not cached.

    Args:
        cache_dir: the cache's folder (``stamlane align ROOT --cache CACHE_DIR``).
        root: the dataset root the cache was made for.
        key_path: the key frame's file (absolute, or relative to ``root``).
        hist_path: the history frame's file, in the same clip folder.

    Returns:
        the ``Alignment`` (``key_from_hist`` float64 ``(3, 3)``; check ``ok``), or ``None`` when the file,
        the key frame or the history frame is missing from the cache, or the frames lie in different folders.
    """
    root = Path(root).resolve()
    key_path, hist_path = (p if p.is_absolute() else root / p for p in (Path(key_path), Path(hist_path)))
    key_path, hist_path = key_path.resolve(), hist_path.resolve()
    if key_path.parent != hist_path.parent:
        return None
    try:
        path = cache_file(cache_dir, root, key_path.parent).resolve()
        mtime = path.stat().st_mtime_ns
    except (ValueError, OSError):
        return None
    entry = _read_cached(str(path), mtime).get(key_path.name, {}).get(hist_path.name)
    return None if entry is None else alignment_from_json(entry)


# ---------------------------------------------------------------------- the content-keyed pair cache (align: fly)
PAIR_CACHE_DIR = Path(".stamlane-cache") / "alignment"
"""Where `PairCache` keeps its entries, relative to the data root."""
PAIR_CACHE_VERSION = 1
"""Part of every `pair_key`: raise it when `stamlane.align.homography.estimate_prepared` changes what it returns for
the same frames and settings, so that no entry of the old estimator is read."""
_MAX_ENTRY_BYTES = 1 << 16
"""An entry is a few hundred bytes; a larger file is not one of ours and is not read."""


def frame_digest(image: np.ndarray) -> str:
    """SHA-256 of a frame's shape, dtype and pixels (what the estimator reads), hex."""
    image = np.ascontiguousarray(image)
    digest = hashlib.sha256(f"{image.shape}{image.dtype.str}".encode())
    digest.update(image.data.cast("B"))
    return digest.hexdigest()


def pair_key(hist_digest: str, key_digest: str, horizon_row: int, config: AlignConfig) -> str:
    """The name of one pair's entry: a digest of both frames' digests, the (resolved) horizon row, every estimation
    setting, the OpenCV and numpy versions (their ORB, RANSAC and Lucas-Kanade are part of the result) and
    `PAIR_CACHE_VERSION`."""
    import cv2

    what = (PAIR_CACHE_VERSION, cv2.__version__, np.__version__, hist_digest, key_digest, int(horizon_row), config)
    return hashlib.sha256(repr(what).encode()).hexdigest()


class PairCache:
    """Frame-pair alignments kept by content under a data root (`PAIR_CACHE_DIR`), shared by every process.

    A write goes to a temporary file of the writing process and is renamed over the entry (`write_atomic`): a
    reader sees a whole entry or none, and two processes writing one pair write the same bytes (the estimate is a
    function of the pixels and the settings). A folder that cannot be written (a read-only data set) leaves the
    cache read-only, with one warning; an entry that cannot be read (missing, damaged, too large, or a link leading
    outside the data root) is a miss, estimated again and written over.

    Args:
        root: the data root; nothing is read or written outside it.
        folder: the cache folder relative to ``root``.
    """

    def __init__(self, root: str | os.PathLike[str], folder: str | os.PathLike[str] = PAIR_CACHE_DIR) -> None:
        self.root = Path(root)
        self.folder = self.root / folder
        self.writable = True
        self.hits = 0
        self.misses = 0

    def path(self, key: str) -> Path:
        """The entry file of ``key`` (two-character subfolders keep folders small)."""
        return self.folder / key[:2] / f"{key}.json"

    def get(self, key: str) -> Alignment | None:
        """The cached alignment of ``key``, or None."""
        try:
            entry = json.loads(read_inside(self.path(key), self.root, _MAX_ENTRY_BYTES, "alignment cache entry"))
            alignment = alignment_from_json(entry)
        except (GuardError, json.JSONDecodeError, KeyError, TypeError, ValueError):
            self.misses += 1
            return None
        self.hits += 1
        return alignment

    def put(self, key: str, alignment: Alignment) -> None:
        """Store ``alignment`` under ``key`` (atomically); a no-op once the folder proved unwritable."""
        if not self.writable:
            return
        path = self.path(key)
        try:
            if not is_inside(path.parent, self.root):  # a link out of the data root: nothing made or written there
                raise OSError(f"{path.parent} leads outside {self.root}")
            path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(path, json.dumps(alignment_to_json(alignment)))
        except OSError as err:
            self.writable = False
            warnings.warn(
                f"alignment cache {self.folder} cannot be written ({err}); estimating without it", stacklevel=2
            )


def estimate_clip_cached(
    frames: list[np.ndarray],
    cache: PairCache | None,
    memo: dict[str, Alignment] | None = None,
    *,
    horizon_row: int | None = None,
    config: AlignConfig | None = None,
    strategy: Strategy = "chain",
    digests: list[str] | None = None,
) -> list[Alignment]:
    """`stamlane.align.warp.estimate_clip` with every frame pair it estimates looked up first in ``memo`` (this
    process) and ``cache`` (every process; None: none) and stored in both when estimated: the same alignments bit
    for bit, each pair paid once. Frames are prepared (grey levels, features) only when a pair is missing.

    Args:
        frames: ``T`` uint8 images ``(H, W, 3)`` BGR or ``(H, W)``, oldest first, key frame last, one size.
        cache: the shared cache, or None.
        memo: pair key -> alignment, this process's copy (None: none).
        horizon_row, config, strategy: as `estimate_clip`.
        digests: the frames' `frame_digest` when the caller has them.

    Returns:
        ``T`` alignments, oldest first; the key frame's (last) is the identity with ``ok=True``.
    """
    from stamlane.align.warp import _check_frames, alignments_to_key

    frames = _check_frames(frames)
    if strategy not in ("direct", "chain"):
        raise ValueError(f"strategy must be 'direct' or 'chain', got {strategy!r}")
    cfg = config or AlignConfig()
    shape = frames[-1].shape[:2]
    row = resolve_horizon_row(horizon_row, shape[0])
    digests = digests or [frame_digest(f) for f in frames]
    preps: dict[int, FramePrep] = {}
    memo = {} if memo is None else memo

    def prep(i: int) -> FramePrep:
        if i not in preps:
            preps[i] = FramePrep(frames[i], row, cfg)
        return preps[i]

    def estimate(i: int, j: int) -> Alignment:
        key = pair_key(digests[i], digests[j], row, cfg)
        found = memo.get(key)
        if found is None and cache is not None:
            found = cache.get(key)
        if found is None:
            found = estimate_prepared(prep(i), prep(j), cfg)
            if cache is not None:
                cache.put(key, found)
        memo[key] = found
        return replace(found, key_from_hist=found.key_from_hist.copy())  # a caller may change its copy

    alignments = alignments_to_key(len(frames), estimate, shape, row, cfg, strategy)
    alignments.append(Alignment(np.eye(3), 0, 0, True, ""))
    return alignments
