"""The weights shipped with the package (`stamlane.weights`): the files are the ones the model cards describe,
they load through the closed registry with nothing of the training machine in them, and a shipped model's name
works wherever a checkpoint does; `stamlane.training.release` makes such a file from a run's checkpoint."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import torch
import yaml

from stamlane.cli import main
from stamlane.safety.guard import file_sha256
from stamlane.safety.owner import OWNER_NAME
from stamlane.training.lightning_cli import CONFIG_KEY, START_DIR_KEY
from stamlane.training.module import StamLaneModule
from stamlane.training.release import KEPT, release
from stamlane.training.release import main as release_main
from stamlane.weights import DEFAULT, SHIPPED, resolve, shipped_path

torch.set_num_threads(1)


@pytest.mark.parametrize("model", SHIPPED, ids=lambda m: m.name)
def test_a_shipped_file_is_the_one_its_card_describes_and_builds_from_the_registry(model) -> None:
    path = shipped_path(model.name)
    assert file_sha256(path) == model.sha256  # docs/models.md's numbers are of these bytes
    content = torch.load(path, weights_only=True)
    assert set(content) == {*KEPT, CONFIG_KEY} and START_DIR_KEY not in content
    config = yaml.safe_load(content[CONFIG_KEY])
    assert config["data"]["root"] is None and config["model"]["init_weights"] is None
    assert config["trainer"]["accelerator"] == "auto" and config["trainer"]["logger"] is False
    assert "/work" not in content[CONFIG_KEY] and "outputs/" not in content[CONFIG_KEY]  # nothing of the machine
    module = StamLaneModule.from_checkpoint(path)
    assert module.num_frames == (4 if model.name.startswith("stam4") else 1)
    assert list(module.hparams["image_size"]) == [80, 256]


def test_a_name_means_the_shipped_file_unless_a_file_of_that_name_is_here(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert resolve(DEFAULT) == str(shipped_path(DEFAULT)) and Path(resolve(DEFAULT)).is_file()
    assert resolve("runs/last.ckpt") == "runs/last.ckpt" and resolve("last") == "last"
    (tmp_path / DEFAULT).write_bytes(b"mine")
    assert resolve(DEFAULT) == DEFAULT  # a file of yours always wins
    with pytest.raises(KeyError, match="shipped: stam4-synthetic, single-synthetic, single-dashcam, stam4-dashcam"):
        shipped_path("stam5")


def test_the_help_lists_them_and_a_missing_checkpoint_names_them(capsys) -> None:
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert all(m.name in out for m in SHIPPED) and f"predict --source runs {DEFAULT};" in out
    assert main(["predict", "--ckpt_path", "stam5-synthetic"]) == 2
    assert (
        "or a shipped model's name (stam4-synthetic, single-synthetic, single-dashcam, stam4-dashcam)"
        in capsys.readouterr().err
    )


@pytest.mark.usefixtures("plain_argv")
def test_predict_on_a_folder_with_no_checkpoint_runs_the_default_model(tiny_synthetic, tmp_path, capsys) -> None:
    root = tiny_synthetic(320, 180, 4, train=0, val=0, test=1, challenging=0)
    (clip,) = (root / "clips").iterdir()
    out = tmp_path / "pred"
    assert main(["predict", "--source", str(clip), "--predictions.output_dir", str(out)]) == 0
    said = capsys.readouterr().err
    assert (
        DEFAULT == "stam4-dashcam" and f"running the shipped {DEFAULT} (the 4-frame STAM model for real roads" in said
    )
    assert len(list((out / "lines").rglob("*.lines.txt"))) == 4  # one per frame, each with its own history


@pytest.mark.usefixtures("plain_argv")
def test_predict_on_a_video_with_no_other_argument_keeps_its_folder_clean(
    tiny_synthetic, tmp_path, capsys, monkeypatch
):
    """``stamlane predict --source drive.mp4`` right after the install: the shipped model, the lines, overlays and an
    overlay video in a folder of the model and the video; nothing written beside the video (no decoded frames, no
    config.yaml)."""
    import cv2

    root = tiny_synthetic(320, 180, 5, train=0, val=0, test=1, challenging=0)
    (clip,) = (root / "clips").iterdir()
    monkeypatch.chdir(tmp_path)
    writer = cv2.VideoWriter("drive.mp4", cv2.VideoWriter_fourcc(*"mp4v"), 8, (320, 180))
    for frame in sorted(clip.glob("*.jpg"), key=lambda p: int(p.stem)):
        writer.write(cv2.imread(str(frame)))
    writer.release()
    assert main(["predict", "--source", "drive.mp4"]) == 0
    out = Path("outputs/predict") / DEFAULT / "drive"
    said = capsys.readouterr()
    assert f"running the shipped {DEFAULT}" in said.err and "warning" not in said.err  # one sequence
    assert said.out.endswith(f"wrote 5 culane, 5 overlays, overlay.mp4 (5 frames) under {out}\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drive.mp4", "outputs"]  # nothing beside the input
    video = cv2.VideoCapture(str(out / "overlay.mp4"))
    assert video.get(cv2.CAP_PROP_FRAME_COUNT) == 5 and video.get(cv2.CAP_PROP_FPS) == 8
    assert video.read()[1].shape == (180, 320, 3)
    assert sorted(p.name for p in out.iterdir()) == sorted(["lines", "overlay.mp4", "overlays", OWNER_NAME])


@pytest.mark.usefixtures("plain_argv")
def test_export_of_a_shipped_model_writes_here_not_into_the_package(tmp_path: Path, monkeypatch) -> None:
    pytest.importorskip("onnxruntime")
    monkeypatch.chdir(tmp_path)
    assert main(["export", "--ckpt_path", "single-synthetic"]) == 0
    assert (tmp_path / "single-synthetic.onnx").is_file()
    assert not shipped_path("single-synthetic").with_suffix(".onnx").exists()


def test_release_drops_what_names_the_training_machine_and_keeps_the_weights(tmp_path: Path) -> None:
    shipped = torch.load(shipped_path(DEFAULT), weights_only=True)
    config = yaml.safe_load(shipped[CONFIG_KEY])
    config["data"]["root"] = "data/synthetic-v6"
    config["model"]["init_weights"] = "outputs/demo/pretrain-s0/run/checkpoints/last.ckpt"
    config["trainer"] |= {"accelerator": "cpu", "default_root_dir": "outputs/demo/stam4-s0"}
    run = shipped | {
        CONFIG_KEY: yaml.safe_dump(config),
        START_DIR_KEY: "/home/someone/stamlane",
        "optimizer_states": [{"state": {}, "param_groups": []}],
        "loops": {"fit_loop": {}},
    }
    run["hyper_parameters"] = dict(run["hyper_parameters"]) | {"init_weights": config["model"]["init_weights"]}
    ckpt, out = tmp_path / "last.ckpt", tmp_path / "shipped.ckpt"
    torch.save(run, ckpt)
    released = release(ckpt, out)
    assert set(torch.load(out, weights_only=True)) == set(released) == {*KEPT, CONFIG_KEY}
    cleared = yaml.safe_load(released[CONFIG_KEY])
    assert cleared["data"]["root"] is None and cleared["model"]["init_weights"] is None
    assert cleared["trainer"]["accelerator"] == "auto" and "default_root_dir" not in cleared["trainer"]
    assert released["hyper_parameters"]["init_weights"] is None
    assert all(torch.equal(released["state_dict"][k], shipped["state_dict"][k]) for k in shipped["state_dict"])
    assert os.path.getsize(out) < 1.05 * os.path.getsize(shipped_path(DEFAULT))  # no optimiser state


def test_release_refuses_to_write_over_its_input(tmp_path: Path) -> None:
    ckpt = tmp_path / "last.ckpt"
    ckpt.write_bytes(shipped_path(DEFAULT).read_bytes())
    assert release_main([str(ckpt), str(ckpt)]) == 2


@pytest.mark.usefixtures("plain_argv")
def test_the_default_model_is_a_name_nobody_typed(tiny_synthetic, tmp_path, monkeypatch, capsys) -> None:
    """``predict --source DIR`` without a checkpoint runs the shipped default even where a folder of its name lies
    here (that was "ckpt_path stam4-synthetic is a directory"); the name typed by the user means the folder."""
    root = tiny_synthetic(320, 180, 4, train=0, val=0, test=1, challenging=0)
    (clip,) = (root / "clips").iterdir()
    monkeypatch.chdir(tmp_path)
    (tmp_path / DEFAULT).mkdir()  # a folder of the default model's name, here
    out = tmp_path / "pred"
    assert main(["predict", "--source", str(clip), "--predictions.output_dir", str(out)]) == 0
    assert f"running the shipped {DEFAULT}" in capsys.readouterr().err
    assert len(list((out / "lines").rglob("*.lines.txt"))) == 4
    assert main(["predict", "--source", str(clip), "--ckpt_path", DEFAULT]) == 2  # typed: the folder here wins
    err = capsys.readouterr().err.strip()
    assert err == f"stamlane predict: {DEFAULT} holds no checkpoints/last.ckpt (not a finished run folder)", err
    assert resolve("n" * 300) == "n" * 300  # a name too long for the file system: no file here, no exception
