"""The runner under every experiment and benchmark: one run trained from a recipe stage and reused, one run scored on
a split with its probes, and what decides that a split is predicted again (its labels, its frames, the rules)."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from stamlane.experiments.recipes import Recipe, Row
from stamlane.experiments.runner import Runner, frame_files_digest
from stamlane.experiments.store import RunStore
from stamlane.training.runs import RunRecord
from tests.experiments.tiny_experiments import SHRINK

torch.set_num_threads(1)
pytestmark = pytest.mark.usefixtures("plain_argv")
ROW = Row.paper_row("f2_mixed_cs_features")


@pytest.fixture
def trained(tiny_synthetic: Callable[..., Path], tmp_path: Path) -> tuple[Runner, RunRecord, list[str]]:
    """A two-frame run of two steps on a tiny set of its own (its frames are changed by the tests), and the
    progress lines said."""
    root = tiny_synthetic(128, 72, 4, train=2, val=1, test=2, challenging=0)
    said: list[str] = []
    runner = Runner(RunStore(tmp_path / "out"), root, extra=SHRINK, progress=False, max_overlays=0, say=said.append)
    recipe = Recipe("paper", steps=2)
    record = runner.train(ROW, 0, recipe.training(ROW), {"data": str(root)} | recipe.settings())
    return runner, record, said


def _predicted(said: list[str]) -> list[str]:
    return [line.split(": predicting ", 1)[1] for line in said if ": predicting " in line]


def test_a_run_is_trained_once_and_scored_once(trained: tuple[Runner, RunRecord, list[str]]) -> None:
    runner, record, said = trained
    name = runner.store.run_name(ROW.name, 0)
    assert said == [f"seed 0, training: {ROW.label}, 2 steps"]
    assert record.run == runner.store.run_dir(name) and record.frames == 2
    assert runner.train(
        ROW, 0, Recipe("paper", steps=2).training(ROW), {k: record.setting(k) for k in ("data", "steps")}
    )
    assert said[-1] == f"seed 0, training: {ROW.label}, done before, reused"
    assert runner.score(name, record, {"test": ("key",)})
    assert _predicted(said) == ["test", "test@key"]
    assert (runner.store.pred_dir(name, "test", "key") / "per_image.jsonl").is_file()
    per_image, clips = runner.scored(name, record, "test@key")
    assert clips == ["clips/test-0000", "clips/test-0001"] and per_image["tusimple_f1"].shape == (2, 2)
    assert not runner.score(name, record, {"test": ("key",)})  # current: nothing predicted, nothing scored
    assert _predicted(said) == ["test", "test@key"]


def test_a_frame_written_again_under_the_same_labels_is_predicted_again(
    trained: tuple[Runner, RunRecord, list[str]],
) -> None:
    """A generator that moves pixels and leaves the labels as they were: the split's predictions are stale."""
    runner, record, said = trained
    name = runner.store.run_name(ROW.name, 0)
    runner.score(name, record, {"test": ("key",), "val": ()})
    labels = (runner.root / "test.json").read_bytes()
    frame = runner.root / "clips" / "test-0001" / "2.jpg"  # a history frame of a key frame of the test split
    frame.write_bytes(frame.read_bytes())  # the same bytes, written again: a new modification time
    assert (runner.root / "test.json").read_bytes() == labels
    said.clear()
    assert runner.score(name, record, {"test": ("key",), "val": ()})
    assert said[0] == f"{name}: the test frames changed, predicting them again"
    assert _predicted(said) == ["test", "test@key"]  # val's frames are as they were: not predicted again
    assert record.frame_files["test"] == frame_files_digest(runner.root, "test")
    other = runner.root / "clips" / "train-0000" / "2.jpg"  # a frame of no scored split
    os.utime(other, ns=(0, 0))
    said.clear()
    assert not runner.score(name, record, {"test": ("key",), "val": ()}) and said == []


def test_a_record_of_before_the_frames_were_digested_keeps_its_predictions(
    trained: tuple[Runner, RunRecord, list[str]],
) -> None:
    """A record ``done.json`` written by the version before (the labels' digest, no ``frame_files``): its
    predictions stand for the frames found at its next scoring, and a frame changed after that is seen."""
    runner, record, said = trained
    name = runner.store.run_name(ROW.name, 0)
    runner.score(name, record, {"test": ()})
    runner.store.mark(name, record)
    done = runner.store.folder(name) / "done.json"
    old = json.loads(done.read_text())
    del old["frame_files"], old["pretrain_args"]
    done.write_text(json.dumps(old, indent=2))
    again = runner.store.finished(name, {"data": old["data"], "pretrain_args": []})
    assert again is not None and again.frame_files == {}
    said.clear()
    assert not runner.score(name, again, {"test": ()}) and said == []  # not predicted again
    assert again.frame_files["test"] == frame_files_digest(runner.root, "test")
    os.utime(runner.root / "clips" / "test-0000" / "4.jpg", ns=(1, 1))
    assert runner.score(name, again, {"test": ()}) and _predicted(said) == ["test"]


def test_recipes_hold_options_as_data_and_record_the_flags_of_before() -> None:
    """A store of before (its records hold the row arguments as the flags a YAML printer wrote) is reused: its flags
    read as the same options, written as JSON today."""
    from stamlane.experiments.recipes import KEY_CORRUPTION, RECIPES
    from stamlane.experiments.store import upgrade_record
    from stamlane.training.runs import flags_of

    assert KEY_CORRUPTION == {
        "data.augment.key_corruption": 0.5,
        "data.augment.key_corruption_kinds": ["blank", "glare"],
    }
    today = ["--data.augment.key_corruption=0.5", '--data.augment.key_corruption_kinds=["blank", "glare"]']
    assert RECIPES["cpu"].settings()["row_args"] == flags_of(KEY_CORRUPTION) == today
    before = ["--data.augment.key_corruption=0.5", "--data.augment.key_corruption_kinds=[blank, glare]"]
    assert upgrade_record({"row_args": before, "extra": ["--x=[a, b]"]}) == {
        "row_args": today,
        "pretrain_args": [],
        "extra": ["--x=[a, b]"],  # the user's arguments, as typed
    }
    assert flags_of({"a": True, "b": None, "c": Path("d e"), "f": [Path("g")], "h": "[i, j]"}) == [
        "--a=true",
        "--b=null",
        "--c=d e",
        '--f=["g"]',
        "--h=[i, j]",
    ]
