"""Two ``stamlane align`` runs on one cache keep each other's entries (the read-merge-write is locked); a damaged
entry is read as a missing one and estimated again by a rerun."""

from __future__ import annotations

import json
from multiprocessing import get_context
from pathlib import Path

import cv2
import numpy as np

from stamlane.align.cache import cache_file, load_alignment, merge_cache, read_cache, write_cache
from stamlane.align.cli import AlignJob, process_clip
from stamlane.synth import SynthConfig
from stamlane.synth.clip import generate_clip

NAN = float("nan")


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


def test_a_damaged_entry_reads_as_missing(tmp_path: Path) -> None:
    """``align: cache`` then estimates the pair on the fly (`stamlane.data.alignment.ClipAligner`)."""
    root, cache = tmp_path / "data", tmp_path / "cache"
    (root / "clip").mkdir(parents=True)
    good = {"key_from_hist": np.eye(3).tolist(), "ok": True, "num_matches": 9, "num_inliers": 8, "reason": ""}
    write_cache(
        cache / "clip.json",
        {
            "3.jpg": {"2.jpg": good, "1.jpg": good | {"key_from_hist": [[NAN] * 3] * 3}},
            "2.jpg": {"1.jpg": good | {"ok": "yes"}},
            "1.jpg": [1, 2],
        },
    )
    found = load_alignment(cache, root, "clip/3.jpg", "clip/2.jpg")
    assert found is not None and found.ok and found.num_inliers == 8
    assert load_alignment(cache, root, "clip/3.jpg", "clip/1.jpg") is None
    assert load_alignment(cache, root, "clip/2.jpg", "clip/1.jpg") is None
    assert load_alignment(cache, root, "clip/1.jpg", "clip/0.jpg") is None
    merged = merge_cache(cache / "clip.json", {"1.jpg": {"0.jpg": good}})  # a damaged key frame: replaced
    assert merged["1.jpg"] == {"0.jpg": good} and merged["3.jpg"]["2.jpg"] == good


def test_a_rerun_of_stamlane_align_estimates_a_damaged_entry_again(tmp_path: Path) -> None:
    root, cache = tmp_path / "data", tmp_path / "cache"
    clip = root / "clip"
    clip.mkdir(parents=True)
    frames = generate_clip(SynthConfig(width=320, height=180, num_frames=3), np.random.default_rng([0, 0, 1])).frames
    for i, frame in enumerate(frames, 1):
        cv2.imwrite(str(clip / f"{i}.png"), frame)
    job = AlignJob(root, cache, num_frames=3)
    assert process_clip(clip, job).status == "done"
    path = cache_file(cache, root, clip)
    whole = read_cache(path)
    assert process_clip(clip, job).status == "skipped"  # covered
    write_cache(
        path, {"3.png": whole["3.png"] | {"2.png": whole["3.png"]["2.png"] | {"key_from_hist": [[NAN] * 3] * 3}}}
    )
    assert process_clip(clip, job).status == "done"  # estimated again
    assert read_cache(path) == whole
