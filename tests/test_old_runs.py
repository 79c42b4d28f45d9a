"""Runs written before the data options were grouped and before the training shell moved into stamlane.training
still work: their ``config.yaml``, the config, model and data hyperparameters inside their checkpoints and their
experiment records are read in today's form by ``stamlane predict|validate``, ``stamlane stream``, ``stamlane
export`` and the experiment engine."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
import torch
import yaml

from stamlane.cli import main
from stamlane.safety.checkpoints import INSTANTIATOR
from stamlane.training.compat import RENAMED_CLASSES, group_config, upgrade_config
from stamlane.training.lightning_cli import CONFIG_KEY

torch.set_num_threads(1)
pytestmark = pytest.mark.usefixtures("plain_argv")

FLAT_CONFIG = Path(__file__).parent / "training" / "flat_demo_config.yaml"
"""A real config of before the groups (``--print_config`` of configs/demo.yaml at 5a179c8)."""
OLD_KEY_CORRUPTION = ["--data.key_corruption=0.5", "--data.key_corruption_kinds=[blank, glare]"]
"""The CPU recipe's stage-2 arguments as the experiment records of before the groups hold them."""


def _old_names(value: object) -> object:
    """``value`` with every class under its name of before the move (``stamlane.module.StamLaneModule``)."""
    old = {new: name for name, new in RENAMED_CLASSES.items()}
    if isinstance(value, dict):
        return {k: _old_names(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_old_names(v) for v in value]
    return old.get(value, value) if isinstance(value, str) else value


def _lanes(path: Path) -> list:
    return [(r["raw_file"], r["lanes"]) for r in map(json.loads, path.read_text().splitlines())]


@pytest.fixture(scope="module")
def tiny_set(tiny_synthetic: Callable[..., Path]) -> Path:
    return tiny_synthetic(256, 144, 4, train=4, val=2, test=2, challenging=0)


@pytest.fixture(scope="module")
def old_run(tiny_set: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run folder as stamlane wrote it before the groups: ``config.yaml``, and the checkpoint's config and data
    hyperparameters, in the flat form (the demo's config shrunk to 2 frames at 64x128, 2 steps)."""
    folder = tmp_path_factory.mktemp("old")
    config = yaml.safe_load(FLAT_CONFIG.read_text())
    data = {"root": str(tiny_set), "num_frames": 2, "image_size": [64, 128], "align": "none"}
    config["data"].update(data, batch_size=2, num_workers=0)
    config["model"]["encoder"]["init_args"]["width"] = 0.125
    config["model"].update(bf16=False, channels_last=False)
    config["trainer"].update(max_steps=2, val_check_interval=2, enable_progress_bar=False, default_root_dir=str(folder))
    config["trainer"]["logger"]["init_args"]["save_dir"] = str(folder)
    config["predictions"]["output_dir"] = str(folder / "predictions")
    flat = folder / "flat.yaml"
    flat.write_text(yaml.safe_dump(config, sort_keys=False))
    assert main(["fit", "--config", str(flat)]) == 0  # an old --config file trains as it is
    run = folder / "stam4" / "version_0"
    ckpt = run / "checkpoints" / "last.ckpt"
    content = torch.load(ckpt, weights_only=True)
    assert "clip" in content["datamodule_hyper_parameters"]  # written today: grouped; made old below
    content[CONFIG_KEY] = flat.read_text()
    content["datamodule_hyper_parameters"] = {**config["data"], "_instantiator": INSTANTIATOR}
    content["hyper_parameters"] = _old_names(content["hyper_parameters"])
    assert content["hyper_parameters"]["loss"]["class_path"] == "stamlane.losses.LaneLoss"
    torch.save(content, ckpt)
    shutil.copy(flat, run / "config.yaml")
    return run


def test_predict_and_validate_read_an_old_checkpoint_and_run_folder(
    old_run: Path, tiny_set: Path, tmp_path: Path
) -> None:
    ckpt = old_run / "checkpoints" / "last.ckpt"
    quiet = ["--trainer.logger=false", "--trainer.callbacks=[]"]
    # the config inside the checkpoint
    assert main(["predict", f"--ckpt_path={ckpt}", *quiet, f"--predictions.output_dir={tmp_path / 'inside'}"]) == 0
    # the run folder's config.yaml beside a checkpoint without one
    lone = old_run / "checkpoints" / "lone.ckpt"
    content = torch.load(ckpt, weights_only=True)
    del content[CONFIG_KEY]
    torch.save(content, lone)
    assert main(["predict", f"--ckpt_path={lone}", *quiet, f"--predictions.output_dir={tmp_path / 'beside'}"]) == 0
    # the same config in today's form: the same lanes
    grouped = tmp_path / "grouped.yaml"
    grouped.write_text(yaml.safe_dump(upgrade_config(yaml.safe_load((old_run / "config.yaml").read_text()))))
    args = ["--config", str(grouped), f"--ckpt_path={ckpt}", *quiet, f"--predictions.output_dir={tmp_path / 'new'}"]
    assert main(["predict", *args]) == 0
    want = _lanes(tmp_path / "new" / "predictions.json")
    assert len(want) == 2
    assert _lanes(tmp_path / "inside" / "predictions.json") == want
    assert _lanes(tmp_path / "beside" / "predictions.json") == want
    # a folder of frames, read as the old run read its clips (2 frames, 64x128)
    out = tmp_path / "folder"
    source = tiny_set / "clips" / "test-0000"
    assert (
        main(["predict", f"--ckpt_path={ckpt}", *quiet, f"--predictions.output_dir={out}", f"--source={source}"]) == 0
    )
    assert len(list((out / "lines").iterdir())) == 4
    assert main(["validate", f"--ckpt_path={ckpt}", *quiet]) == 0


def test_stream_and_export_read_an_old_checkpoint(old_run: Path, tiny_set: Path, tmp_path: Path, capsys) -> None:
    from stamlane.stream.cli import build_parser, load_predictor

    ckpt = old_run / "checkpoints" / "last.ckpt"
    assert "num_frames" in torch.load(ckpt, weights_only=True)["datamodule_hyper_parameters"]  # flat
    predictor = load_predictor(build_parser().parse_args(["frames", "--ckpt", str(ckpt)]))
    assert predictor.num_frames == 2 and predictor.image_size == (64, 128) and predictor.transform.crop_top == 0.4
    frames = tiny_set / "clips" / "test-0000"
    assert main(["stream", str(frames), "--ckpt", str(ckpt), "--out", str(tmp_path / "stream"), "--no-video"]) == 0
    records = (tmp_path / "stream" / "lanes.jsonl").read_text().splitlines()
    # trained with align: none, streamed unaligned as `predict --source` reads it (the stored setting, not a flag)
    assert len(records) == 4 and all(json.loads(r)["aligned"] == [] for r in records)
    assert main(["export", "--ckpt_path", str(ckpt), "--output", str(tmp_path / "model.onnx")]) == 0
    assert "T=2, 128x64" in capsys.readouterr().out


def test_a_checkpoint_of_today_carries_the_grouped_options(old_run: Path, tmp_path: Path) -> None:
    from stamlane.stream.cli import build_parser, load_predictor

    ckpt = old_run / "checkpoints" / "last.ckpt"
    content = torch.load(ckpt, weights_only=True)
    grouped = group_config({"data": content["datamodule_hyper_parameters"]})["data"]
    grouped["clip"]["horizon_row"] = 60
    content["datamodule_hyper_parameters"] = grouped
    new = tmp_path / "new.ckpt"
    torch.save(content, new)
    predictor = load_predictor(build_parser().parse_args(["frames", "--ckpt", str(new)]))
    assert predictor.num_frames == 2 and predictor.horizon_row == 60


def test_the_engine_reuses_and_scores_an_old_run(old_run: Path, tiny_set: Path, tmp_path: Path) -> None:
    """A run folder and record of before the groups, before recipes took stage-1 arguments and before the frames
    were digested: reused as it is, and scored with its ``config.yaml``."""
    from stamlane.experiments.engine import Experiment
    from stamlane.experiments.recipes import RECIPES, Row
    from stamlane.experiments.runner import frames_of

    assert frames_of(old_run) == 2
    said: list[str] = []
    experiment = Experiment(
        [Row("stam4", "4 frames", ("demo.yaml",))],
        RECIPES["cpu"],
        [0],
        tiny_set,
        tmp_path / "exp",
        splits=("test",),
        probes=False,
        temporal=False,
        max_overlays=0,
        log=said.append,
    )
    run = tmp_path / "exp" / "stam4-s0" / "run"
    shutil.copytree(old_run, run)
    settings = experiment.settings()
    assert settings["row_args"] != OLD_KEY_CORRUPTION  # today's names
    old = {k: v for k, v in settings.items() if k != "pretrain_args"}  # recorded before stage 1 took arguments
    record = old | {"row_args": OLD_KEY_CORRUPTION, "seed": 0, "train_minutes": 0.1, "frames": 2}
    record |= {"run": str(run), "last_ckpt": str(run / "checkpoints" / "last.ckpt")}
    (experiment.store.folder("stam4-s0") / "done.json").write_text(json.dumps(record))  # as stamlane wrote it
    stage = experiment.recipe.training(experiment.rows[0])
    reused = experiment.runner.train(experiment.rows[0], 0, stage, settings, label="stage 2")
    assert [line.split(" min  ", 1)[1] for line in said] == ["seed 0, stage 2: 4 frames, done before, reused"]
    assert reused.settings["row_args"] == settings["row_args"] and reused.settings["pretrain_args"] == []
    assert experiment.runner.score("stam4-s0", reused, {"test": ()})  # predicts with the old run's config.yaml
    assert "test" in reused.scores and 0 <= reused.scores["test"]["f1"] <= 1
