"""The homography cache written by ``stamlane align`` and read by the data pipeline.

Layout: one JSON file per clip folder, ``<cache_dir>/<clip folder relative to root>.json``::

    {"<key frame file name>": {"<history frame file name>": {
        "key_from_hist": [[...], [...], [...]], "ok": true, "num_matches": 120, "num_inliers": 96, "reason": ""}}}

A clip folder is any folder holding numbered frames ``<n>.jpg`` / ``<n>.png`` (TuSimple
``clips/<date>/<id>/1..20.jpg``, synthetic ``clips/<id>/1..20.jpg``, VIL-100 ``JPEGImages/<video>/00000.jpg``);
a dataset root that is itself a clip folder is cached as ``<cache_dir>/__root__.json``.

The data pipeline's own cache (`PairCache`, ``align: fly``) keeps ORB frame-pair estimates by CONTENT instead: one
file per pair, named by the digest of both frames' pixels (`stamlane.align.identity.frame_digest`: what identifies
a frame, and why the pair cache keys by pixels) with the estimation settings, the OpenCV and numpy versions and
`PAIR_CACHE_VERSION` (`pair_key`), in the user's cache folder (`pair_cache_folder`: ``alignment/`` of
`stamlane.align.user_cache`, never inside the data); entries in the format above (`alignment_to_json`). A frame
rewritten with other pixels has another digest, so a stale entry is never read; every training run, prediction
pass, probe, model and seed on the same frames, wherever they lie, reads the pairs the first one estimated
(`estimate_clip_cached`), and the homographies are the estimated ones bit for bit (JSON keeps a float64 exactly).

Who reads and writes these caches: ``stamlane align`` writes the first (`merge_cache`); the data pipeline's
`stamlane.data.alignment.ClipAligner` is the one owner of every alignment a dataset reads: this module's two
caches, its own memo of clips and pairs, and a clip's alignment kept in the process's frame store.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from stamlane.align.homography import (
    AlignConfig,
    Alignment,
    FramePrep,
    check_plausible,
    estimate_prepared,
)
from stamlane.align.identity import frame_digest
from stamlane.align.user_cache import cache_folder, say_unwritable, writable_folder
from stamlane.align.warp import Strategy, alignments_to_key, clip_estimate
from stamlane.safety.guard import GuardError, is_inside, read_inside, write_atomic

__all__ = [
    "FRAME_SUFFIXES",
    "PAIR_CACHE_NAME",
    "PAIR_CACHE_VERSION",
    "ROOT_CACHE_NAME",
    "PairCache",
    "alignment_from_json",
    "alignment_to_json",
    "cache_file",
    "estimate_clip_cached",
    "find_clip_dirs",
    "list_frames",
    "load_alignment",
    "merge_cache",
    "pair_cache_folder",
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


def alignment_from_json(entry: object) -> Alignment:
    """Inverse of ``alignment_to_json``, for an entry of the form it writes and no other.

    Raises:
        ValueError: ``entry`` is not an object with a finite 3x3 ``key_from_hist`` of numbers, a boolean ``ok``,
            whole non-negative counts and a string ``reason`` (the last three optional): a damaged entry, which
            every reader takes for a missing one.
    """
    if not isinstance(entry, dict):
        raise ValueError(f"an alignment entry is an object, got {type(entry).__name__}")
    rows = entry.get("key_from_hist")
    if not (
        isinstance(rows, list)
        and len(rows) == 3
        and all(isinstance(row, list) and len(row) == 3 for row in rows)
        and all(_is_number(v) for row in rows for v in row)
    ):
        raise ValueError("key_from_hist is not a 3x3 matrix of numbers")
    matrix = np.asarray(rows, np.float64)
    if not np.all(np.isfinite(matrix)):
        raise ValueError("key_from_hist is not finite")
    ok, reason = entry.get("ok"), entry.get("reason", "")
    counts = [entry.get(name, 0) for name in ("num_matches", "num_inliers")]
    if not isinstance(ok, bool) or not isinstance(reason, str):
        raise ValueError("ok is not true or false, or reason is not a string")
    if not all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in counts):
        raise ValueError("num_matches and num_inliers are not whole numbers >= 0")
    return Alignment(matrix, counts[0], counts[1], ok, reason)


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


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
            kept = data.get(key)
            data[key] = {**(kept if isinstance(kept, dict) else {}), **hist}  # a damaged key frame: written anew
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
        the key frame or the history frame is missing from the cache or damaged (`alignment_from_json`), or the
        frames lie in different folders.
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
    hists = _read_cached(str(path), mtime).get(key_path.name)
    entry = hists.get(hist_path.name) if isinstance(hists, dict) else None
    try:
        return None if entry is None else alignment_from_json(entry)
    except ValueError:  # a damaged entry: as a missing one, estimated on the fly
        return None


# ---------------------------------------------------------------------- the content-keyed pair cache (align: fly)
PAIR_CACHE_NAME = "alignment"
"""`PairCache`'s folder in the cache home (`stamlane.align.user_cache.cache_folder`)."""
PAIR_CACHE_VERSION = 1
"""Part of every `pair_key`: raise it when `stamlane.align.homography.estimate_prepared` changes what it returns for
the same frames and settings, so that no entry of the old estimator is read."""
_MAX_ENTRY_BYTES = 1 << 16
"""An entry is a few hundred bytes; a larger file is not one of ours and is not read."""


def pair_key(hist_digest: str, key_digest: str, horizon_row: int, config: AlignConfig) -> str:
    """The name of one pair's entry: a digest of both frames' digests, the (resolved) horizon row, every estimation
    setting, the OpenCV and numpy versions (their ORB, RANSAC and Lucas-Kanade are part of the result) and
    `PAIR_CACHE_VERSION`."""
    import cv2

    what = (PAIR_CACHE_VERSION, cv2.__version__, np.__version__, hist_digest, key_digest, int(horizon_row), config)
    return hashlib.sha256(repr(what).encode()).hexdigest()


def pair_cache_folder() -> Path | None:
    """Where `PairCache` keeps its entries by default: ``alignment/`` in the cache home (``$STAMLANE_CACHE_DIR``,
    else ``$XDG_CACHE_HOME/stamlane``, else ``~/.cache/stamlane``); None where there is no home."""
    return cache_folder(PAIR_CACHE_NAME)


class PairCache:
    """Frame-pair alignments kept by content in the user's cache folder, shared by every process and data set.

    A write goes to a temporary file of the writing process and is renamed over the entry (`write_atomic`): a
    reader sees a whole entry or none, and two processes writing one pair write the same bytes (the estimate is a
    function of the pixels and the settings). A folder that cannot be made or written (a read-only home), or one
    inside the data being read, is not written, said once per process (`stamlane.align.user_cache.CacheWarning`);
    one that exists outside the data is still read (a shared cache on a read-only mount). An entry that cannot be
    read (missing, too large, a link leading out of the folder) or is not what the estimator writes (not JSON, a
    NaN or infinite homography, another shape or type: `alignment_from_json`; an accepted alignment that fails
    `stamlane.align.homography.check_plausible`, a failed one that is not the identity) is a miss: estimated
    again and written over.

    Args:
        folder: the cache folder (None: `pair_cache_folder`).
        inputs: the data being read (a data root, a ``--source`` folder): a folder inside one of them is neither
            read nor written.
    """

    def __init__(self, folder: str | os.PathLike[str] | None = None, inputs: tuple[Path, ...] = ()) -> None:
        chosen = pair_cache_folder() if folder is None else Path(folder)
        self.folder = chosen
        inside = chosen is not None and any(is_inside(chosen, root) for root in inputs)
        self.readable = chosen is not None and not inside
        self.writable = writable_folder(chosen, "the alignment cache", inputs)
        self.hits = 0
        self.misses = 0

    def path(self, key: str) -> Path:
        """The entry file of ``key`` (two-character subfolders keep folders small)."""
        if self.folder is None:
            raise ValueError("this alignment cache has no folder")
        return self.folder / key[:2] / f"{key}.json"

    def get(self, key: str) -> Alignment | None:
        """The entry of ``key`` when it is whole and of the form `alignment_to_json` writes, or None (not counted:
        `lookup` counts)."""
        if not self.readable or self.folder is None:
            return None
        try:
            text = read_inside(self.path(key), self.folder, _MAX_ENTRY_BYTES, "alignment cache entry")
            return alignment_from_json(json.loads(text))
        except (GuardError, json.JSONDecodeError, ValueError):
            return None

    def lookup(self, key: str, shape: tuple[int, int], horizon_row: int, config: AlignConfig) -> Alignment | None:
        """The cached alignment of ``key`` (frames of ``shape`` ``(H, W)``, estimated with ``horizon_row`` and
        ``config``, all three in the key) when it is one the estimator can return, or None; counted in ``hits`` or
        ``misses``."""
        found = self.get(key)
        if found is not None and not _as_estimated(found, shape, horizon_row, config):
            found = None
        self.hits += found is not None
        self.misses += found is None
        return found

    def put(self, key: str, alignment: Alignment) -> None:
        """Store ``alignment`` under ``key`` (atomically, over a damaged entry); a no-op once the folder proved
        unwritable."""
        if not self.writable or self.folder is None:
            return
        path = self.path(key)
        try:
            if not is_inside(path.parent, self.folder):  # a link out of the folder: nothing made or written there
                raise OSError(f"{path.parent} leads outside it (a link?)")
            path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(path, json.dumps(alignment_to_json(alignment)))
        except OSError as err:
            self.writable = False
            say_unwritable("the alignment cache", self.folder, str(err))


def _as_estimated(found: Alignment, shape: tuple[int, int], horizon_row: int, config: AlignConfig) -> bool:
    """Whether ``found`` is what `estimate_prepared` returns: an accepted homography that passes its plausibility
    check, or the identity of a failed estimate."""
    if found.ok:
        return not check_plausible(found.key_from_hist, shape, horizon_row, config)
    return bool(np.array_equal(found.key_from_hist, np.eye(3)))


def estimate_clip_cached(
    frames: list[np.ndarray],
    cache: PairCache | None,
    memo: dict[str, Alignment] | None = None,
    *,
    horizon_row: int | None = None,
    config: AlignConfig | None = None,
    strategy: Strategy = "chain",
) -> list[Alignment]:
    """`stamlane.align.warp.estimate_clip` with every frame pair it estimates looked up first in ``memo`` (this
    process) and ``cache`` (every process; None: none) and stored in both when estimated: the same alignments bit
    for bit, each pair paid once. Frames are prepared (grey levels, features) only when a pair is missing.

    Args:
        frames: ``T`` uint8 images ``(H, W, 3)`` BGR or ``(H, W)``, oldest first, key frame last, one size.
        cache: the shared cache, or None.
        memo: pair key -> alignment, this process's copy (None: none).
        horizon_row, config, strategy: as `estimate_clip`.

    Returns:
        ``T`` alignments, oldest first; the key frame's (last) is the identity with ``ok=True``.
    """
    frames, cfg, row = clip_estimate(frames, horizon_row, config, strategy)
    shape = frames[-1].shape[:2]
    digests = [frame_digest(f) for f in frames]
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
            found = cache.lookup(key, shape, row, cfg)
        if found is None:
            found = estimate_prepared(prep(i), prep(j), cfg)
            if cache is not None:
                cache.put(key, found)
        memo[key] = found
        return replace(found, key_from_hist=found.key_from_hist.copy())  # a caller may change its copy

    alignments = alignments_to_key(len(frames), estimate, shape, row, cfg, strategy)
    alignments.append(Alignment(np.eye(3), 0, 0, True, ""))
    return alignments
