"""`StoredModel`: one checkpoint, one set of settings, whichever route runs it (stream, predict, export, Python)."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
import yaml

from stamlane.align.homography import ALIGN_PRESETS
from stamlane.safety.checkpoints import CheckpointError, read_checkpoint
from stamlane.stream.predictor import StreamingPredictor
from stamlane.training.lightning_cli import CONFIG_KEY
from stamlane.training.stored import ModelSettings, StoredModel, checkpoint_of
from stamlane.weights import shipped_path

torch.set_num_threads(1)

UNUSUAL = {"align": "none", "align_preset": "fast", "horizon_row": 300}
"""Clip options no default has: a route that drops them shows."""


def _variant(tmp_path: Path, clip: dict[str, object]) -> Path:
    """The shipped stam4-synthetic with other data options, in its data hyper-parameters and its config alike."""
    content = read_checkpoint(shipped_path("stam4-synthetic"))
    content["datamodule_hyper_parameters"]["clip"].update(clip)
    config = yaml.safe_load(content[CONFIG_KEY])
    config["data"]["clip"].update(clip)
    content[CONFIG_KEY] = yaml.safe_dump(config)
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    torch.save(content, run / "checkpoints" / "last.ckpt")
    (run / "config.yaml").write_text(content[CONFIG_KEY])
    return run / "checkpoints" / "last.ckpt"


def test_open_reads_the_network_and_its_settings() -> None:
    """The shipped 4-frame model's network, in eval mode, with the stored weights and the data options it trained
    with."""
    model = StoredModel.open("stam4-synthetic")
    assert model.checkpoint == shipped_path("stam4-synthetic") and not model.module.training
    stored = read_checkpoint(shipped_path("stam4-synthetic"))
    assert all(torch.equal(v, stored["state_dict"][k]) for k, v in model.module.state_dict().items())
    clip = stored["datamodule_hyper_parameters"]["clip"]
    settings = model.settings
    assert settings.clip is not None and settings.num_frames == clip["num_frames"] == 4
    assert list(settings.image_size) == list(clip["image_size"]) and settings.aligns
    assert (settings.align_preset, settings.horizon_row, settings.crop_top) == (
        clip.get("align_preset", "standard"),  # written before presets existed: the one preset of then
        clip.get("horizon_row"),
        clip.get("crop_top", 0.0),
    )
    assert settings.postprocess == model.module.postprocess and settings.bf16 is bool(model.module.bf16)
    assert model.config is not None and model.config["data"]["clip"]["num_frames"] == 4


def test_every_route_gets_the_same_settings(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``align: none``, the fast preset and a horizon row reach the predictor of `from_stored`, of ``stamlane
    stream --ckpt`` (a file and a run folder), the data that ``stamlane predict --ckpt_path`` (a split and a
    ``--source``), `Run.predict` (and so the experiment runner's scores) hand to
    ``Trainer.predict``, the data ``validate`` and ``test --ckpt_path`` score, and the .onnx metadata of ``stamlane
    export``."""
    from stamlane.stream.cli import build_parser, load_predictor
    from stamlane.stream.metadata import deployment_metadata
    from stamlane.training import stored_cli
    from stamlane.training.compat import clip_options
    from stamlane.training.runs import open_run

    ckpt = _variant(tmp_path, UNUSUAL)
    model = StoredModel.open(ckpt)
    assert (model.settings.aligns, model.settings.align_preset, model.settings.horizon_row) == (False, "fast", 300)
    predictors = [StreamingPredictor.from_stored(model)]
    for where in (ckpt, ckpt.parent.parent):
        predictors.append(load_predictor(build_parser().parse_args(["v.mp4", "--ckpt", str(where), "--device", "cpu"])))
    for predictor in predictors:
        assert predictor.align is False and predictor.horizon_row == 300
        assert predictor.align_config == ALIGN_PRESETS["fast"] and predictor.transform.crop_top == pytest.approx(
            model.settings.crop_top
        )
    with open_run(ckpt) as run:  # the run's own record of its data
        recorded = clip_options(run.data())
    assert (recorded.align, recorded.align_preset, recorded.horizon_row) == ("none", "fast", 300)
    for command in ("validate", "test"):  # the data module `stamlane validate|test --ckpt_path` score
        _, init = stored_cli.parse(model, ["--ckpt_path", str(ckpt)], command)
        assert init.data.clip == model.settings.clip, command
    for clip in _predicted_clips(ckpt, tmp_path, monkeypatch):
        assert (clip.align, clip.align_preset, clip.horizon_row) == ("none", "fast", 300), clip
        assert (clip.num_frames, list(clip.image_size)) == (model.settings.num_frames, list(model.settings.image_size))
    exported = deployment_metadata(model.module, model.settings.clip, ckpt, 17)["alignment"]
    assert exported["history"] == "unaligned" and exported["source"] == "none"


def test_flags_replace_one_setting_each(tmp_path: Path) -> None:
    """``stream --no-align`` turns an aligned model's alignment off; ``--align-preset`` and ``--horizon-row`` replace
    their setting and nothing else."""
    from stamlane.stream.cli import build_parser, load_predictor

    ckpt = _variant(tmp_path, {"horizon_row": 250})
    base = ["v.mp4", "--ckpt", str(ckpt), "--device", "cpu"]
    default = load_predictor(build_parser().parse_args(base))
    assert default.align is True and default.horizon_row == 250 and default.align_config == ALIGN_PRESETS["standard"]
    off = load_predictor(build_parser().parse_args([*base, "--no-align", "--align-preset", "fast"]))
    assert off.align is False and off.horizon_row == 250 and off.align_config == ALIGN_PRESETS["fast"]
    assert load_predictor(build_parser().parse_args([*base, "--horizon-row", "200"])).horizon_row == 200


def test_a_run_folder_a_name_and_a_file_are_one_checkpoint(tmp_path: Path) -> None:
    ckpt = _variant(tmp_path, {})
    assert checkpoint_of(ckpt.parent.parent) == ckpt and checkpoint_of(ckpt) == ckpt
    assert checkpoint_of("stam4-dashcam") == shipped_path("stam4-dashcam")
    with pytest.raises(CheckpointError, match=r"holds no checkpoints/last\.ckpt"):
        checkpoint_of(tmp_path)
    with pytest.raises(CheckpointError, match="does not exist"):
        StoredModel.open(tmp_path / "missing.ckpt")


def test_settings_of_a_module_without_data_options() -> None:
    """A checkpoint that records no data options: T and the size from the module, the alignment's defaults."""
    module = StoredModel.open("single-synthetic").module
    settings = ModelSettings.of(module, None)
    assert settings.clip is None and settings.num_frames == 1 and settings.aligns
    assert settings.align_preset == "standard" and settings.horizon_row is None
    assert settings.crop_top == pytest.approx(float(module.hparams.get("crop_top") or 0.0))


def _predicted_clips(ckpt: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[object]:
    """The clip options of the data each prediction route hands to ``Trainer.predict`` (`predict_stored`, stopped
    there): ``stamlane predict --ckpt_path`` of a split and of a folder of frames, and `Run.predict` of a split with the real history and with another clip's."""
    import cv2
    import numpy as np

    from stamlane.cli import main
    from stamlane.training import stored_predict
    from stamlane.training.runs import open_run

    handed: list[object] = []

    def stop(model: object, data: object, writer: object, **options: object) -> None:
        handed.append(data)

    monkeypatch.setattr(stored_predict, "predict_stored", stop)
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(1, 3):
        cv2.imwrite(str(frames / f"{i}.png"), np.zeros((72, 128, 3), np.uint8))
    root = tmp_path / "data"
    root.mkdir()
    monkeypatch.chdir(tmp_path)
    for args in (["--data.root", str(root), "--predictions.output_dir=split"], ["--source", str(frames)]):
        assert main(["predict", "--ckpt_path", str(ckpt), *args]) == 0
    with open_run(ckpt) as run:
        for probe in ("real", "other_clip"):
            run.predict("test", probe, tmp_path / f"run-{probe}", root=root)
    assert len(handed) == 4 and type(handed[1]).__name__ == "FramesDataModule"
    return [data.clip for data in handed]  # type: ignore[attr-defined]


def test_every_command_takes_a_run_folder_as_its_checkpoint(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--ckpt_path RUN`` is ``RUN/checkpoints/last.ckpt`` for predict, validate and test (`cli._with_shipped_weights`
    through `checkpoint_of`), each opened once as a stored model; a folder that holds no finished run is one line, exit status 2."""
    from stamlane.cli import main
    from stamlane.training import stored_cli, stored_predict

    ckpt = _variant(tmp_path, {})
    handed: list[object] = []
    monkeypatch.setattr(stored_predict, "predict_stored", lambda model, data, writer, **options: handed.append(model))
    monkeypatch.setattr(stored_cli, "_score", lambda command, model, *rest: handed.append((command, model)))
    root = tmp_path / "data"
    root.mkdir()
    monkeypatch.chdir(tmp_path)
    assert main(["predict", "--ckpt_path", str(ckpt.parent.parent), "--data.root", str(root)]) == 0
    assert isinstance(handed[0], StoredModel) and handed[0].checkpoint == ckpt
    for command in ("validate", "test"):
        assert main([command, f"--ckpt_path={ckpt.parent.parent}", "--data.root", str(root)]) == 0
        said, model = handed[-1]  # type: ignore[misc]
        assert said == command and isinstance(model, StoredModel) and model.checkpoint == ckpt
    capsys.readouterr()
    assert main(["validate", "--ckpt_path", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"stamlane validate: {tmp_path} holds no checkpoints/last.ckpt (not a finished run folder)"
    for empty in (["--ckpt_path="], ["--ckpt_path", ""]):  # no folder ("." would be one): said as typed
        assert main(["test", *empty]) == 2
        assert capsys.readouterr().err.startswith("stamlane test: checkpoint '' does not exist: give the path")
