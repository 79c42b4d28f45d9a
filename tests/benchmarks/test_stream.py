"""``benchmarks/stream.py``: its fine-tuning of a model runs through the library's training path (feature-space
alignment included), on a tiny synthetic set."""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path

import pytest
import torch

import stamlane.training.module
from stamlane.data.options import ClipOptions
from stamlane.models import STAM, LaneDecoder, VGGEncoder, forward_feature_aligned
from stamlane.predict.postprocess import PostprocessConfig
from stamlane.training.module import StamLaneModule
from tests.benchmarks.scripts import benchmark_module

T, SIZE = 3, (32, 64)
torch.set_num_threads(1)


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("stream") as module:
        yield module


@pytest.fixture(scope="module")
def root(tiny_synthetic: Callable[..., Path]) -> Path:
    """A tiny synthetic set (160x96, 8 frames a clip): 3 train, 1 val, 1 test clip."""
    return tiny_synthetic(160, 96, 8, train=3, val=1, test=1, challenging=0, seed=3)


def test_stream_benchmark_finetunes_through_the_library_path(
    bench, root: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = []
    monkeypatch.setattr(
        stamlane.training.module, "forward_feature_aligned", lambda *a: calls.append(1) or forward_feature_aligned(*a)
    )
    torch.manual_seed(0)
    module = StamLaneModule(
        VGGEncoder(width=0.125),
        functools.partial(STAM, mode="mixed", order="cs", reduction=4, reading="features"),
        LaneDecoder,
        num_frames=T,
        image_size=SIZE,
        postprocess=PostprocessConfig(min_cluster_pixels=5, min_samples=3),
    )
    before = [p.detach().clone() for p in module.parameters()]
    clip = ClipOptions(num_frames=T, image_size=SIZE, stride=2)
    bench.finetune(module, clip, root, ["train.json"], steps=1, feature=True)
    assert calls == [1] and not module.training
    assert any(not torch.equal(a, b) for a, b in zip(before, module.parameters()))
