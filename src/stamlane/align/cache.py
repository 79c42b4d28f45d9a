"""The homography cache written by ``stamlane align`` and read by the data pipeline.

Layout: one JSON file per clip folder, ``<cache_dir>/<clip folder relative to root>.json``::

    {"<key frame file name>": {"<history frame file name>": {
        "key_from_hist": [[...], [...], [...]], "ok": true, "num_matches": 120, "num_inliers": 96, "reason": ""}}}

A clip folder is any folder holding numbered frames ``<n>.jpg`` / ``<n>.png`` (TuSimple
``clips/<date>/<id>/1..20.jpg``, synthetic ``clips/<id>/1..20.jpg``, VIL-100 ``JPEGImages/<video>/00000.jpg``);
a dataset root that is itself a clip folder is cached as ``<cache_dir>/__root__.json``.
"""

from __future__ import annotations

import fcntl
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

import numpy as np

from stamlane.align.homography import Alignment
from stamlane.safety.guard import write_atomic

__all__ = [
    "FRAME_SUFFIXES",
    "ROOT_CACHE_NAME",
    "alignment_from_json",
    "alignment_to_json",
    "cache_file",
    "find_clip_dirs",
    "list_frames",
    "load_alignment",
    "merge_cache",
    "read_cache",
    "write_cache",
]

FRAME_SUFFIXES = (".jpg", ".jpeg", ".png")
ROOT_CACHE_NAME = "__root__.json"

CacheDict = dict[str, dict[str, dict]]


def list_frames(clip_dir: str | os.PathLike) -> list[Path]:
    """The numbered frames ``<n>.jpg|.jpeg|.png`` of a folder, in frame-number order (oldest first)."""
    frames = [
        p for p in Path(clip_dir).iterdir() if p.suffix.lower() in FRAME_SUFFIXES and p.stem.isdigit() and p.is_file()
    ]
    return sorted(frames, key=lambda p: (int(p.stem), p.name))


def find_clip_dirs(root: str | os.PathLike, min_frames: int = 2) -> list[Path]:
    """Every folder under ``root`` (``root`` included) holding at least ``min_frames`` numbered frames, sorted."""
    root = Path(root)
    found = []
    for folder, _, files in os.walk(root):
        n = sum(1 for f in files if Path(f).suffix.lower() in FRAME_SUFFIXES and Path(f).stem.isdigit())
        if n >= min_frames:
            found.append(Path(folder))
    return sorted(found)


def cache_file(cache_dir: str | os.PathLike, root: str | os.PathLike, clip_dir: str | os.PathLike) -> Path:
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


def alignment_to_json(alignment: Alignment) -> dict:
    """One cache entry."""
    return {
        "key_from_hist": np.asarray(alignment.key_from_hist, float).tolist(),
        "ok": bool(alignment.ok),
        "num_matches": int(alignment.num_matches),
        "num_inliers": int(alignment.num_inliers),
        "reason": str(alignment.reason),
    }


def alignment_from_json(entry: dict) -> Alignment:
    """Inverse of ``alignment_to_json``."""
    return Alignment(
        np.asarray(entry["key_from_hist"], np.float64).reshape(3, 3),
        int(entry.get("num_matches", 0)),
        int(entry.get("num_inliers", 0)),
        bool(entry.get("ok", False)),
        str(entry.get("reason", "")),
    )


def read_cache(path: str | os.PathLike) -> CacheDict:
    """A clip's cache file, or ``{}`` when it does not exist or cannot be parsed."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError):
        return {}
    return data if isinstance(data, dict) else {}


def write_cache(path: str | os.PathLike, data: CacheDict) -> None:
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


def merge_cache(path: str | os.PathLike, entries: CacheDict) -> CacheDict:
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
    cache_dir: str | os.PathLike, root: str | os.PathLike, key_path: str | os.PathLike, hist_path: str | os.PathLike
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
