"""The content-keyed frame-pair cache of ``align: fly`` (`stamlane.align.cache.PairCache`): what it returns is what
the estimator returns, bit for bit; it is invalidated by content, shared by processes, and never reads or writes
outside the data root."""

from __future__ import annotations

import json
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pytest

from stamlane.align.cache import PAIR_CACHE_DIR, PairCache, estimate_clip_cached, frame_digest, pair_key
from stamlane.align.homography import AlignConfig, Alignment
from stamlane.align.warp import estimate_clip
from stamlane.synth import SynthConfig
from stamlane.synth.clip import generate_clip

CLIP_CONFIG = SynthConfig(width=320, height=180, num_frames=5)


@pytest.fixture(scope="module")
def frames() -> list[np.ndarray]:
    """Five frames of a synthetic road clip (320x180), oldest first."""
    return list(generate_clip(CLIP_CONFIG, np.random.default_rng([0, 0, 1])).frames)


def _same(a: list[Alignment], b: list[Alignment]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x.key_from_hist.tobytes() == y.key_from_hist.tobytes()  # bit for bit, not close
        assert (x.ok, x.reason, x.num_matches, x.num_inliers, x.extrapolated) == (
            y.ok,
            y.reason,
            y.num_matches,
            y.num_inliers,
            y.extrapolated,
        )


@pytest.mark.parametrize("strategy", ["chain", "direct"])
def test_a_cached_homography_is_the_estimated_one_bit_for_bit(
    tmp_path: Path, frames: list[np.ndarray], strategy: str
) -> None:
    truth = estimate_clip(frames, strategy=strategy)
    assert sum(a.ok for a in truth[:-1]) >= 3  # a clip that aligns: the entries hold real homographies
    cache = PairCache(tmp_path)
    _same(estimate_clip_cached(frames, cache, strategy=strategy), truth)  # estimated, written
    assert cache.misses == 4 and cache.hits == 0
    again = PairCache(tmp_path)  # another process, or a later run: reads every pair
    _same(estimate_clip_cached(frames, again, strategy=strategy), truth)
    assert again.hits == 4 and again.misses == 0
    written = list((tmp_path / PAIR_CACHE_DIR).rglob("*.json"))
    assert len(written) == 4 and not [p for p in (tmp_path / PAIR_CACHE_DIR).rglob("*") if ".tmp" in p.name]


def test_windows_of_one_clip_share_their_pairs(tmp_path: Path, frames: list[np.ndarray]) -> None:
    cache, memo = PairCache(tmp_path), {}
    estimate_clip_cached(frames[:4], cache, memo)
    estimate_clip_cached(frames[1:], cache, memo)  # pairs 1-2 and 2-3 are the first window's
    assert cache.misses == 4  # 0-1, 1-2, 2-3, 3-4: each estimated once
    _same(estimate_clip_cached(frames[1:], PairCache(tmp_path)), estimate_clip(frames[1:]))


def test_other_pixels_or_other_settings_are_other_entries(tmp_path: Path, frames: list[np.ndarray]) -> None:
    cache = PairCache(tmp_path)
    estimate_clip_cached(frames[:3], cache)
    changed = [f.copy() for f in frames[:3]]
    changed[1][100, 100, 0] ^= 1  # one bit of one pixel
    assert frame_digest(changed[1]) != frame_digest(frames[1])
    fresh = PairCache(tmp_path)
    _same(estimate_clip_cached(changed, fresh), estimate_clip(changed))
    assert fresh.hits == 0 and fresh.misses == 2  # both pairs touch the changed frame
    digests = [frame_digest(f) for f in frames[:2]]
    keys = {
        pair_key(*digests, 81, AlignConfig()),
        pair_key(*digests, 80, AlignConfig()),
        pair_key(*digests, 81, AlignConfig(max_models=1)),
        pair_key(*reversed(digests), 81, AlignConfig()),
    }
    assert len(keys) == 4
    assert frame_digest(frames[0][:, :, 0]) != frame_digest(frames[0][:, :, :1])  # the shape is in the digest


def test_a_damaged_entry_is_estimated_again_and_replaced(tmp_path: Path, frames: list[np.ndarray]) -> None:
    estimate_clip_cached(frames[:2], PairCache(tmp_path))
    (entry,) = (tmp_path / PAIR_CACHE_DIR).rglob("*.json")
    entry.write_text('{"key_from_hist": [[1, 2], "no"')
    cache = PairCache(tmp_path)
    _same(estimate_clip_cached(frames[:2], cache), estimate_clip(frames[:2]))
    assert cache.misses == 1
    json.loads(entry.read_text())  # whole again


def test_nothing_is_read_or_written_through_a_link_out_of_the_data_root(
    tmp_path: Path, frames: list[np.ndarray]
) -> None:
    outside, root = tmp_path / "outside", tmp_path / "root"
    estimate_clip_cached(frames[:2], PairCache(outside))
    (entry,) = (outside / PAIR_CACHE_DIR).rglob("*.json")
    poisoned = json.loads(entry.read_text()) | {"key_from_hist": np.diag([2.0, 2.0, 1.0]).tolist()}
    entry.write_text(json.dumps(poisoned))
    root.mkdir()
    (root / ".stamlane-cache").symlink_to(outside / ".stamlane-cache")
    cache = PairCache(root)
    with pytest.warns(UserWarning, match="cannot be written"):
        result = estimate_clip_cached(frames[:2], cache)
    _same(result, estimate_clip(frames[:2]))  # the poisoned entry outside was not read
    assert cache.hits == 0 and not cache.writable
    assert json.loads(entry.read_text()) == poisoned  # nor written over


def _estimate_in_process(args: tuple[str, int]) -> list[list[float]]:
    root, offset = args
    clip = list(generate_clip(CLIP_CONFIG, np.random.default_rng([0, 0, 1])).frames)
    out = []
    for _ in range(3):
        cache = PairCache(root)
        out.append([a.key_from_hist.tolist() for a in estimate_clip_cached(clip[offset:], cache)])
    return out


def test_several_processes_writing_one_cache_agree(tmp_path: Path, frames: list[np.ndarray]) -> None:
    with get_context("spawn").Pool(2) as pool:
        results = pool.map(_estimate_in_process, [(str(tmp_path), 0), (str(tmp_path), 0), (str(tmp_path), 1)])
    truth = [a.key_from_hist.tolist() for a in estimate_clip(frames)]
    for runs in results[:2]:
        assert all(run == truth for run in runs)
    assert all(run == [a.key_from_hist.tolist() for a in estimate_clip(frames[1:])] for run in results[2])
    files = list((tmp_path / PAIR_CACHE_DIR).rglob("*"))
    assert not [p for p in files if ".tmp" in p.name]
    for path in (p for p in files if p.is_file()):
        json.loads(path.read_text())  # every entry whole
