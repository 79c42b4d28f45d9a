"""Two ``stamlane align`` runs on one cache keep each other's entries (the read-merge-write is locked)."""

from __future__ import annotations

import json
from multiprocessing import get_context
from pathlib import Path

from stamlane.align.cache import merge_cache, read_cache


def _writer(args: tuple[str, int]) -> None:
    path, worker = args
    for i in range(15):
        merge_cache(path, {f"{worker}-{i}.jpg": {"prev.jpg": {"ok": True, "worker": worker}}})


def test_concurrent_writers_lose_nothing(tmp_path: Path) -> None:
    path = tmp_path / "cache" / "clip.json"
    with get_context("spawn").Pool(4) as pool:
        pool.map(_writer, [(str(path), w) for w in range(4)])
    data = read_cache(path)
    assert sorted(data) == sorted(f"{w}-{i}.jpg" for w in range(4) for i in range(15))
    json.loads(path.read_text())  # whole, valid JSON
    assert not [p for p in path.parent.iterdir() if ".tmp" in p.name]  # no temporary name left behind


def test_merge_adds_history_frames_of_a_key_frame(tmp_path: Path) -> None:
    path = tmp_path / "clip.json"
    merge_cache(path, {"20.jpg": {"19.jpg": {"ok": True}}})
    merged = merge_cache(path, {"20.jpg": {"18.jpg": {"ok": False}}, "19.jpg": {"18.jpg": {"ok": True}}})
    assert merged == {"20.jpg": {"19.jpg": {"ok": True}, "18.jpg": {"ok": False}}, "19.jpg": {"18.jpg": {"ok": True}}}
    assert read_cache(path) == merged
