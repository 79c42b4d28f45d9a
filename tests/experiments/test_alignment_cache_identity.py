"""The alignment cache changes no number: a short training run and a prediction pass give the same weights and the
same predictions, bit for bit, with the homographies estimated afresh (as before the cache), estimated into an empty
cache, and read from a full one."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from stamlane.align.cache import PairCache
from stamlane.align.user_cache import CACHE_ENV
from stamlane.experiments.engine import Experiment
from stamlane.experiments.recipes import Recipe, Row
from tests.experiments.test_engine_speed import SHRINK


@pytest.mark.usefixtures("plain_argv")
def test_weights_and_predictions_are_the_same_with_and_without_the_cache(
    tiny_synthetic: Callable[..., Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    root = tiny_synthetic(320, 180, 8, train=3, val=1, test=2, challenging=0, seed=2)
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))  # empty: "cold" estimates into it
    cache = tmp_path / "cache" / "alignment"
    row = Row.paper_row("f4_mixed_cs_features")  # the demo's 4-frame model, aligned on the fly
    recipe = Recipe("paper", steps=4, val_checks=1, val_batches=1)
    results = []
    for name in ("afresh", "cold", "warm"):
        with monkeypatch.context() as patch:
            if name == "afresh":  # every dataset estimates for itself, as before the cache
                patch.setattr(PairCache, "get", lambda self, key: None)
                patch.setattr(PairCache, "put", lambda self, key, alignment: None)
            experiment = Experiment([row], recipe, [0], root, tmp_path / name, extra=SHRINK, max_overlays=0)
            record = experiment.runner.train(row, 0, recipe.training(row), experiment.settings())
            pred = experiment.runner.predict(f"{row.name}-s0", record.run, "test")
        weights = torch.load(record.run / "checkpoints" / "last.ckpt", weights_only=True)["state_dict"]
        lines = (pred / "predictions.json").read_text().splitlines()
        lanes = [{k: v for k, v in json.loads(line).items() if k != "run_time"} for line in lines]  # not timings
        results.append((weights, lanes))
        if name == "afresh":
            assert not list(cache.rglob("*.json"))
    (afresh, afresh_pred), *cached = results
    for weights, pred in cached:
        assert weights.keys() == afresh.keys() and all(torch.equal(weights[k], afresh[k]) for k in afresh)
        assert pred == afresh_pred and len(pred) == 2  # a key frame of each test clip
    assert len(list(cache.rglob("*.json"))) > 0
