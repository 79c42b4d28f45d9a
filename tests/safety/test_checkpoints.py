"""stamlane.safety.checkpoints: weights only, only registered classes built (`stamlane.training.registry`), one-line errors for bad
files."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
import torch

from stamlane.safety.checkpoints import CheckpointError, read_checkpoint
from stamlane.training.module import StamLaneModule
from stamlane.training.registry import check_hparams

NET = {
    "encoder": {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": 0.125}},
    "fusion": {"class_path": "stamlane.models.STAM"},
    "decoder": {"class_path": "stamlane.models.LaneDecoder"},
    "optimizer": {"class_path": "torch.optim.AdamW", "init_args": {"lr": 0.002}},
    "scheduler": {"class_path": "stamlane.training.module.PolyLR"},
    "num_frames": 2,
    "image_size": [32, 64],
    "_instantiator": "lightning.pytorch.cli.instantiate_module",
}


def _save(path: Path, hparams: dict, state: dict | None = None) -> Path:
    torch.save({"state_dict": state if state is not None else {}, "hyper_parameters": hparams}, path)
    return path


@pytest.mark.parametrize(
    ("where", "name"),
    [
        ("encoder", "antigravity.Anything"),  # a standard-library module with a side effect on import
        ("optimizer", "os.system"),
        ("fusion", "stamlane..models"),
    ],
)
def test_foreign_classes_are_refused_before_any_import(tmp_path: Path, where: str, name: str) -> None:
    hparams = {**NET, where: {"class_path": name}}
    path = _save(tmp_path / "evil.ckpt", hparams)
    with pytest.raises(CheckpointError, match=f"{where}.class_path names {re.escape(repr(name))}, not in"):
        StamLaneModule.from_checkpoint(path)
    assert "antigravity" not in sys.modules


def test_a_foreign_instantiator_and_nested_names_are_refused(tmp_path: Path) -> None:
    with pytest.raises(CheckpointError, match=r"_instantiator must be .*, got 'builtins\.exec'"):
        check_hparams({**NET, "_instantiator": "builtins.exec"}, "x.ckpt")
    nested = {
        **NET,
        "loss": {"class_path": "stamlane.training.losses.LaneLoss", "init_args": {"x": [{"class_path": "os.rm"}]}},
    }
    with pytest.raises(CheckpointError, match=r"loss\.init_args\.x is not an option of LaneLoss"):
        check_hparams(nested, "x.ckpt")
    inside = {
        **NET,
        "loss": {"class_path": "stamlane.training.losses.LaneLoss", "init_args": {"alpha": {"class_path": "os.rm"}}},
    }
    with pytest.raises(CheckpointError, match=r"alpha\.class_path a class where a plain value goes \('os\.rm'\)"):
        check_hparams(inside, "x.ckpt")
    check_hparams(NET, "x.ckpt")  # stamlane's own classes and torch.optim pass


def test_another_networks_weights_do_not_fit(tmp_path: Path) -> None:
    path = _save(tmp_path / "other.ckpt", NET, {"net.encoder.stages.0.0.weight": torch.zeros(3, 3, 3, 3)})
    with pytest.raises(CheckpointError, match=r"does not fit a stamlane network"):
        StamLaneModule.from_checkpoint(path)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"", "not a readable torch checkpoint"),
        (b"hello\n", "not a readable torch checkpoint"),
        (None, "does not exist"),
    ],
)
def test_unreadable_files(tmp_path: Path, content: bytes | None, match: str) -> None:
    path = tmp_path / "c.ckpt"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(CheckpointError, match=match) as info:
        read_checkpoint(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_truncated_and_weightless_checkpoints(tmp_path: Path) -> None:
    whole = _save(tmp_path / "whole.ckpt", NET)
    cut = tmp_path / "cut.ckpt"
    cut.write_bytes(whole.read_bytes()[: len(whole.read_bytes()) // 2])
    with pytest.raises(CheckpointError, match="not a readable torch checkpoint"):
        read_checkpoint(cut)
    torch.save({"weights": 1}, tmp_path / "w.ckpt")
    with pytest.raises(CheckpointError, match="holds no state_dict"):
        read_checkpoint(tmp_path / "w.ckpt")
