"""``align: fly`` pays each frame pair once: a second dataset on the same frames (a later run, pass, probe, model or
seed) reads the first one's estimates from the user's cache folder and gets the same samples, bit for bit; nothing
is written into the data."""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from stamlane.align.cache import pair_cache_folder
from stamlane.align.homography import ALIGN_PRESETS
from stamlane.align.user_cache import CACHE_ENV
from stamlane.data import TuSimpleClips
from stamlane.data.alignment import ClipAligner
from stamlane.data.options import ClipOptions

CLIP = ClipOptions(num_frames=4, image_size=(40, 128), crop_top=0.4, align="fly")


@pytest.fixture(scope="module", autouse=True)
def cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """This module's own cache home, empty when its first test starts."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(CACHE_ENV, str(tmp_path_factory.mktemp("cache")))
        folder = pair_cache_folder()
        assert folder is not None
        yield folder


@pytest.fixture(scope="module")
def root(tiny_synthetic: Callable[..., Path]) -> Path:
    """Two train clips of 320x180, 8 frames (key frames 8: the whole train split a few windows)."""
    return tiny_synthetic(320, 180, 8, train=2, val=0, test=1, challenging=0, seed=6)


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _samples(ds: TuSimpleClips) -> list[dict]:
    return [ds.load(entry, np.random.default_rng(i)) for i, entry in enumerate(ds.entries)]


def test_a_second_dataset_reads_the_pairs_and_gets_the_same_samples(root: Path, cache: Path) -> None:
    data = _files(root)
    reference = TuSimpleClips(root, "test.json", clip=CLIP)
    options = reference.aligner
    reference.aligner = ClipAligner("fly", root, pair_cache=False)  # as before the cache: estimated here
    expected = _samples(reference)
    assert not list(cache.rglob("*.json"))
    first = TuSimpleClips(root, "test.json", clip=CLIP)
    got = _samples(first)
    assert first.aligner.pair_cache.misses > 0 and len(list(cache.rglob("*.json"))) == first.aligner.pair_cache.misses
    second = TuSimpleClips(root, "test.json", clip=CLIP)
    again = _samples(second)
    assert second.aligner.pair_cache.hits > 0 and second.aligner.pair_cache.misses == 0
    assert options.pair_cache is not None
    for a, b, c in zip(expected, got, again):
        assert torch.equal(a["frames"], b["frames"]) and torch.equal(a["frames"], c["frames"])
        assert a["key_from_hist"].numpy().tobytes() == c["key_from_hist"].numpy().tobytes()
        assert not np.allclose(a["key_from_hist"][0].numpy(), np.eye(3), atol=1e-3)  # aligned, not the identity
    assert _files(root) == data  # the data root as it was: no file added, none changed


def test_a_copy_of_the_data_elsewhere_reads_the_same_entries(root: Path, tmp_path: Path) -> None:
    TuSimpleClips(root, "test.json", clip=CLIP)[0]
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    moved = TuSimpleClips(copy, "test.json", clip=CLIP)
    moved[0]
    assert moved.aligner.pair_cache.hits > 0 and moved.aligner.pair_cache.misses == 0  # keyed by content, not path


def test_the_probes_read_the_pairs_of_the_real_history(root: Path) -> None:
    TuSimpleClips(root, "test.json", clip=CLIP)[0]  # the real history: into the cache
    for source in ("warped_key", "reversed"):
        probe = TuSimpleClips(root, "test.json", clip=CLIP, history_source=source, require_labels=True)
        probe[0]
        assert probe.aligner.pair_cache.misses == 0, source


def test_without_the_cache_nothing_is_written(tmp_path: Path, root: Path) -> None:
    aligner = ClipAligner("fly", tmp_path, pair_cache=False)
    frames = [np.zeros((96, 160, 3), np.uint8) + i for i in range(3)]
    mats, oks = aligner(["1.jpg", "2.jpg", "3.jpg"], frames)
    assert mats.shape == (3, 3, 3) and oks[-1] and aligner.pair_cache is None
    assert not list(tmp_path.iterdir())
    assert ClipAligner("none", tmp_path).pair_cache is None and ClipAligner("true", tmp_path).pair_cache is None


def test_the_fast_preset_is_cached_apart(root: Path) -> None:
    standard = TuSimpleClips(root, "test.json", clip=CLIP)
    expected, _ = standard.aligner(standard.entries[0].frame_paths, standard.read_frames(standard.entries[0]))
    fast = TuSimpleClips(root, "test.json", clip=replace(CLIP, align_preset="fast"))
    assert fast.aligner.config == ALIGN_PRESETS["fast"] != standard.aligner.config
    got, oks = fast.aligner(fast.entries[0].frame_paths, fast.read_frames(fast.entries[0]))
    assert fast.aligner.pair_cache.misses > 0 and all(oks)  # estimated with its settings, not read from standard's
    assert not np.array_equal(got, expected)  # its accuracy: benchmarks/align.py, benchmarks/synth_align.py


def test_an_unknown_preset_is_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match=r"align preset must be one of \('standard', 'fast', 'motion'\), got 'quick'"):
        replace(CLIP, align_preset="quick")
