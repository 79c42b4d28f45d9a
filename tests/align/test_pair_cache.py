"""The content-keyed frame-pair cache of ``align: fly`` (`stamlane.align.cache.PairCache`): what it returns is what
the estimator returns, bit for bit; it is invalidated by content, shared by processes, lives in the user's cache
folder (never in the data), takes a damaged entry for a miss, and never reads or writes outside its folder."""

from __future__ import annotations

import json
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pytest

from stamlane.align import user_cache
from stamlane.align.cache import (
    PAIR_CACHE_NAME,
    PairCache,
    alignment_to_json,
    estimate_clip_cached,
    pair_cache_folder,
    pair_key,
)
from stamlane.align.homography import AlignConfig, Alignment
from stamlane.align.identity import frame_digest
from stamlane.align.user_cache import CACHE_ENV, cache_home
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
    written = list(tmp_path.rglob("*.json"))
    assert len(written) == 4 and not [p for p in tmp_path.rglob("*") if ".tmp" in p.name]


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
    (entry,) = tmp_path.rglob("*.json")
    entry.write_text('{"key_from_hist": [[1, 2], "no"')
    cache = PairCache(tmp_path)
    _same(estimate_clip_cached(frames[:2], cache), estimate_clip(frames[:2]))
    assert cache.misses == 1
    json.loads(entry.read_text())  # whole again


NAN = float("nan")
DAMAGED = {  # entries that parse as JSON but are not what the estimator writes
    "nan": lambda e: e | {"key_from_hist": [[NAN] * 3] * 3},
    "one nan": lambda e: e | {"key_from_hist": [e["key_from_hist"][0], [NAN, 1.0, 0.0], e["key_from_hist"][2]]},
    "infinite": lambda e: e | {"key_from_hist": [[float("inf"), 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]},
    "2x3": lambda e: e | {"key_from_hist": e["key_from_hist"][:2]},
    "flat": lambda e: e | {"key_from_hist": [v for row in e["key_from_hist"] for v in row]},
    "strings": lambda e: e | {"key_from_hist": [[str(v) for v in row] for row in e["key_from_hist"]]},
    "booleans": lambda e: e | {"key_from_hist": [[True, False, False], [False, True, False], [False, False, True]]},
    "ok a string": lambda e: e | {"ok": "yes"},
    "no ok": lambda e: {k: v for k, v in e.items() if k != "ok"},
    "negative count": lambda e: e | {"num_inliers": -3},
    "reason a list": lambda e: e | {"reason": ["x"]},
    "a list": lambda e: [e],
    "a number": lambda e: 3,
    "implausible": lambda e: e | {"key_from_hist": np.diag([2.0, 2.0, 1.0]).tolist(), "ok": True},
    "singular": lambda e: e | {"key_from_hist": [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], "ok": True},
    "failed, not the identity": lambda e: e | {"key_from_hist": np.diag([1.0, 1.0, 1.01]).tolist(), "ok": False},
}


@pytest.mark.parametrize("damage", DAMAGED, ids=list(DAMAGED))
def test_a_damaged_entry_that_parses_is_a_miss_estimated_again_and_written_over(
    tmp_path: Path, frames: list[np.ndarray], damage: str
) -> None:
    truth = estimate_clip(frames[:2])
    assert truth[0].ok  # the entry holds a real homography: its damage is a change
    estimate_clip_cached(frames[:2], PairCache(tmp_path))
    (entry,) = tmp_path.rglob("*.json")
    whole = json.loads(entry.read_text())
    assert whole == alignment_to_json(truth[0])
    entry.write_text(json.dumps(DAMAGED[damage](whole)))  # NaN written as JSON's NaN, which json.loads reads
    cache = PairCache(tmp_path)
    _same(estimate_clip_cached(frames[:2], cache), truth)  # the lanes do not change
    assert (cache.hits, cache.misses) == (0, 1)
    assert json.loads(entry.read_text()) == whole  # rewritten as estimated
    again = PairCache(tmp_path)
    _same(estimate_clip_cached(frames[:2], again), truth)
    assert (again.hits, again.misses) == (1, 0)


def test_a_failed_estimate_is_cached_as_the_identity_and_read_back(tmp_path: Path) -> None:
    flat = [np.full((96, 160, 3), 90, np.uint8)] * 2  # textureless: no features, the identity with ok=False
    truth = estimate_clip(flat)
    assert not truth[0].ok
    estimate_clip_cached(flat, PairCache(tmp_path))
    cache = PairCache(tmp_path)
    _same(estimate_clip_cached(flat, cache), truth)
    assert (cache.hits, cache.misses) == (1, 0)  # a failed entry is an entry, not damage


def _said(caplog: pytest.LogCaptureFixture) -> str:
    """The one line said about the cache (and there was one)."""
    (line,) = [r.getMessage() for r in caplog.records if r.name == "stamlane.cache"]
    return line


def test_nothing_is_read_or_written_through_a_link_out_of_the_cache_folder(
    tmp_path: Path, frames: list[np.ndarray], caplog: pytest.LogCaptureFixture
) -> None:
    outside, folder = tmp_path / "outside", tmp_path / "cache"
    estimate_clip_cached(frames[:2], PairCache(outside))
    (entry,) = outside.rglob("*.json")
    poisoned = json.loads(entry.read_text()) | {"key_from_hist": np.diag([1.01, 1.0, 1.0]).tolist()}
    assert not _plausible_fails(poisoned)  # a plausible homography: only the link check keeps it out
    entry.write_text(json.dumps(poisoned))
    folder.mkdir()
    (folder / entry.parent.name).symlink_to(entry.parent)
    cache = PairCache(folder)
    result = estimate_clip_cached(frames[:2], cache)
    assert "leads outside it (a link?)" in _said(caplog)
    _same(result, estimate_clip(frames[:2]))  # the poisoned entry outside was not read
    assert cache.hits == 0 and not cache.writable
    assert json.loads(entry.read_text()) == poisoned  # nor written over


def _plausible_fails(entry: dict) -> str:
    from stamlane.align.homography import check_plausible

    return check_plausible(np.asarray(entry["key_from_hist"]), (180, 320), 81)


def test_the_cache_lives_in_the_cache_home(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "named"))
    assert pair_cache_folder() == tmp_path / "named" / PAIR_CACHE_NAME
    assert PairCache().folder == tmp_path / "named" / PAIR_CACHE_NAME
    monkeypatch.delenv(CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_home() == tmp_path / "xdg" / "stamlane"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/xdg")  # ignored, as the XDG specification says
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_home() == tmp_path / "home" / ".cache" / "stamlane"
    assert cache_home({CACHE_ENV: "~/elsewhere"}) == tmp_path / "home" / "elsewhere"


def test_a_cache_inside_the_data_is_neither_read_nor_written(
    tmp_path: Path, frames: list[np.ndarray], caplog: pytest.LogCaptureFixture
) -> None:
    data = tmp_path / "data"
    estimate_clip_cached(frames[:2], PairCache(data / "cache"))  # an entry there, from before
    before = sorted(p.read_bytes() for p in data.rglob("*.json"))
    cache = PairCache(data / "cache", inputs=(data,))
    assert f"lies inside the data {data}, which is never written" in _said(caplog)
    _same(estimate_clip_cached(frames[:2], cache), estimate_clip(frames[:2]))
    assert (cache.hits, cache.misses, cache.writable) == (0, 1, False)
    assert sorted(p.read_bytes() for p in data.rglob("*.json")) == before


def test_an_unwritable_cache_is_said_once_and_read_where_it_exists(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, frames: list[np.ndarray], caplog: pytest.LogCaptureFixture
) -> None:
    estimate_clip_cached(frames[:3], PairCache(tmp_path / "shared"))  # filled by someone who can write it
    monkeypatch.setattr(user_cache.os, "access", lambda *args: False)  # as a read-only mount (tests run as root)
    caches = [PairCache(tmp_path / "shared") for _ in range(3)]
    assert _said(caplog).startswith(f"stamlane: the alignment cache {tmp_path / 'shared'} is not written (it is not")
    _same(estimate_clip_cached(frames[:4], caches[0]), estimate_clip(frames[:4]))
    assert (caches[0].hits, caches[0].misses) == (2, 1)  # the two pairs it holds read, the new one estimated
    assert len(list((tmp_path / "shared").rglob("*.json"))) == 2  # and not written


def test_a_cache_that_cannot_be_made_is_said_once_and_nothing_fails(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, frames: list[np.ndarray], caplog: pytest.LogCaptureFixture
) -> None:
    (tmp_path / "file").write_text("a file where the home would be")
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "file" / "home"))
    for _ in range(2):
        cache = PairCache()
        _same(estimate_clip_cached(frames[:2], cache), estimate_clip(frames[:2]))
    assert "is not written (it cannot be made: Not a directory)" in _said(caplog) and cache.misses == 1


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
    files = list(tmp_path.rglob("*"))
    assert not [p for p in files if ".tmp" in p.name]
    for path in (p for p in files if p.is_file()):
        json.loads(path.read_text())  # every entry whole
