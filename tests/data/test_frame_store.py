"""The frame store (`stamlane.data.frame_store`) changes no number: an evaluation sample read through it, the first
time (decoded, aligned, resized and kept), from a store filled by another dataset (nothing decoded) and from a
store filled by `ClipDataset.materialise`'s threads, is the sample read without it, bit for bit; a frame written
again is read again; the store keeps to its budget; a short training run and a prediction pass give the same final
weights and the same lanes with and without it."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import torch

from stamlane.data.clips import ClipDataset
from stamlane.data.datamodule import ClipDataModule
from stamlane.data.frame_store import FRAME_STORE, FrameStore
from stamlane.data.layouts import make_clips
from stamlane.data.options import ClipOptions, LoaderOptions
from stamlane.types import NET_HOMOGRAPHIES


@pytest.fixture(scope="module")
def clip_root(tiny_synthetic: Callable[..., Path]) -> Path:
    return tiny_synthetic(320, 180, 8, train=0, val=0, test=3, challenging=0, seed=4)


def _dataset(root: Path, store: FrameStore | None, **options: Any) -> ClipDataset:
    history_source = options.pop("history_source", "real")
    clip = ClipOptions(**{"num_frames": 3, "image_size": (48, 96), "crop_top": 0.3, "align": "fly", **options})
    dataset = make_clips("tusimple", root, ["test.json"], clip=clip, history_source=history_source)
    dataset.frame_store = store
    return dataset


def _assert_same(a: dict[str, Any], b: dict[str, Any]) -> None:
    assert a.keys() == b.keys()
    for key in ("frames", "binary", "instance", "key_from_hist", NET_HOMOGRAPHIES):
        if key in a:
            assert a[key].dtype == b[key].dtype and torch.equal(a[key], b[key]), key
    assert a["meta"] == b["meta"]
    assert len(a["lanes"]) == len(b["lanes"]) and all(np.array_equal(x, y) for x, y in zip(a["lanes"], b["lanes"]))


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"history_source": "key"},
        {"history_source": "reversed"},
        {"history_source": "other_clip"},
        {"warp": "feature"},
        {"align": "none"},
        {"num_frames": 1},
    ],
    ids=["real", "key", "reversed", "other_clip", "feature", "unaligned", "single"],
)
def test_stored_samples_are_the_samples(clip_root: Path, options: dict[str, Any]) -> None:
    plain = _dataset(clip_root, None, **options)
    assert not plain.stores_frames and len(plain) >= 3
    store = FrameStore(64 << 20)
    first = _dataset(clip_root, store, **options)
    assert first.stores_frames
    samples = [plain[i] for i in range(len(plain))]
    for i, sample in enumerate(samples):
        _assert_same(first[i], sample)  # made and kept
    kept, misses = len(store), store.misses
    assert kept > 0 and store.used <= store.budget
    again = _dataset(clip_root, store, **options)  # a new dataset (a later pass): everything from the store
    decoded: list[str] = []
    again.read_frames = lambda entry: decoded.append(entry.raw_file)  # type: ignore[method-assign]
    for i, sample in enumerate(samples):
        _assert_same(again[i], sample)
    assert decoded == [] and len(store) == kept and store.misses == misses
    filled = FrameStore(64 << 20)
    threaded = _dataset(clip_root, filled, **options)
    assert threaded.materialise(threads=2) == len(samples)
    later = _dataset(clip_root, filled, **options)
    later.read_frames = lambda entry: decoded.append(entry.raw_file)  # type: ignore[method-assign]
    for i, sample in enumerate(samples):
        _assert_same(later[i], sample)
    assert decoded == []


def test_training_samples_and_synthesised_history_are_not_stored(clip_root: Path) -> None:
    assert not _dataset(clip_root, FrameStore(1 << 20), history_source="warped_key").stores_frames
    from stamlane.data.options import AugmentOptions

    clip = ClipOptions(num_frames=3, image_size=(48, 96), align="fly")
    train = make_clips("tusimple", clip_root, ["test.json"], clip=clip, transform=AugmentOptions().transform(clip))
    train.frame_store = FrameStore(1 << 20)
    assert not train.stores_frames and train.materialise(2) == 0 and len(train.frame_store) == 0


def test_a_frame_written_again_is_read_again(clip_root: Path, tmp_path: Path) -> None:
    root = tmp_path / "set"
    shutil.copytree(clip_root, root)
    store = FrameStore(64 << 20)
    before = _dataset(root, store)[0]
    key = root / before["meta"]["frame_paths"][-1]
    image = cv2.imread(str(key))
    cv2.imwrite(str(key), 255 - image)  # same size, other pixels
    after = _dataset(root, store)[0]
    _assert_same(after, _dataset(root, None)[0])
    assert not torch.equal(after["frames"][-1], before["frames"][-1])


def test_the_store_keeps_to_its_budget() -> None:
    store = FrameStore(3000)
    for k in range(5):
        store.put(k, np.zeros(1000, np.uint8))
        assert store.used <= 3000
    assert store.get(0) is None and store.get(4) is not None and len(store) == 3
    store.get(2)  # just used: stays
    store.put(5, np.zeros(1000, np.uint8))
    assert 2 in store and 3 not in store
    store.put("big", np.zeros(4000, np.uint8))  # larger than the budget: not kept, nothing evicted for it
    assert "big" not in store and len(store) == 3
    store.reserve(1000)
    assert store.budget == 3000  # a smaller budget never shrinks it


def test_the_datamodule_materialises_what_fits(clip_root: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    monkeypatch.setattr(ClipDataset, "materialise", lambda self, threads=1: calls.append(len(self)) or len(self))
    clip = ClipOptions(num_frames=3, image_size=(48, 96), align="fly")
    for memory_mb, stored in ((64, True), (0, False)):
        data = ClipDataModule(
            str(clip_root), clip=clip, loader=LoaderOptions(1, 0, memory_mb), predict_labels=["test.json"]
        )
        data.predict_dataloader()
        assert (data.datasets["predict"].frame_store is FRAME_STORE) == stored
    assert len(calls) == 1
    with pytest.raises(ValueError, match="memory_mb"):
        LoaderOptions(memory_mb=-1)


@pytest.mark.usefixtures("plain_argv")
def test_weights_and_predictions_are_the_same_with_and_without_the_store(
    tiny_synthetic: Callable[..., Path], tmp_path: Path
) -> None:
    from stamlane.experiments.engine import Experiment
    from stamlane.experiments.recipes import Recipe, Row
    from tests.experiments.test_engine_speed import SHRINK

    root = tiny_synthetic(320, 180, 8, train=3, val=1, test=2, challenging=0, seed=2)
    row = Row.paper_row("f4_mixed_cs_features")  # the demo's 4-frame model, aligned on the fly
    recipe = Recipe("paper", steps=4, val_checks=2, val_batches=1)
    results = []
    for name, memory in (("without", "0"), ("with", "64"), ("again", "64")):
        if name != "again":  # "again" finds the store as "with"'s run and passes left it
            FRAME_STORE.clear()
        extra = (*SHRINK, "--data.loader.num_workers=1", f"--data.loader.memory_mb={memory}")
        experiment = Experiment([row], recipe, [0], root, tmp_path / name, extra=extra, max_overlays=0)
        record = experiment.runner.train(row, 0, recipe.training(row), experiment.settings())
        preds = []
        for source in ("real", "key", "real"):  # the second real pass reads what the first kept
            pred = experiment.runner.predict(f"{row.name}-s0", record.run, "test", source)
            lines = (pred / "predictions.json").read_text().splitlines()
            preds.append([{k: v for k, v in json.loads(line).items() if k != "run_time"} for line in lines])
        weights = torch.load(record.last_ckpt, weights_only=True)["state_dict"]
        results.append((weights, preds))
    (plain, plain_preds), *stored = results
    for weights, preds in stored:
        assert weights.keys() == plain.keys() and all(torch.equal(weights[k], plain[k]) for k in plain)
        assert preds == plain_preds and len(preds[0]) == 2
    assert len(FRAME_STORE) > 0
