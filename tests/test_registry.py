"""The closed registry (`stamlane.registry`): what a file the user did not write may build.

A checkpoint's hyper_parameters, the run config it carries and a run folder's ``config.yaml`` are data: every name
in them is looked up in a table by its exact string, never imported, and every ``init_args`` value is a plain,
typed value. Each hostile case below ran code, imported a module or escaped as a traceback before the registry.

Nothing here trains: the checkpoints are written by hand, with the weights of a freshly built tiny network.
"""

from __future__ import annotations

import sys
import uuid
from collections.abc import Iterator
from functools import partial
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stamlane.checkpoints import CheckpointError
from stamlane.cli import main
from stamlane.models import STAM, LaneDecoder, VGGEncoder
from stamlane.module import StamLaneModule

REPO = Path(__file__).resolve().parents[1]
torch.set_num_threads(1)
pytestmark = pytest.mark.usefixtures("plain_argv")

NET = {
    "encoder": {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": 0.125, "in_channels": 3}},
    "fusion": {"class_path": "stamlane.models.STAM", "init_args": {"mode": "mixed", "reduction": 4}},
    "decoder": {"class_path": "stamlane.models.LaneDecoder", "init_args": {"embed_dim": 4}},
    "loss": {"class_path": "stamlane.losses.LaneLoss", "init_args": {"delta_v": 0.5}},
    "optimizer": {"class_path": "torch.optim.AdamW", "init_args": {"lr": 0.002, "betas": [0.9, 0.999]}},
    "scheduler": {"class_path": "stamlane.module.PolyLR", "init_args": {"power": 0.9}},
    "postprocess": {"prob_thresh": 0.5, "y_step": 10},
    "num_frames": 2,
    "image_size": [32, 64],
    "crop_top": 0.0,
    "bf16": False,
    "_instantiator": "lightning.pytorch.cli.instantiate_module",
}
"""The hyper_parameters `stamlane fit` stores, for a tiny network (width 1/8, 2 frames at 32x64)."""


@pytest.fixture(scope="module")
def weights() -> dict[str, torch.Tensor]:
    module = StamLaneModule(
        VGGEncoder(width=0.125),
        partial(STAM, mode="mixed", reduction=4),
        partial(LaneDecoder, embed_dim=4),
        num_frames=2,
        image_size=(32, 64),
        bf16=False,
    )
    return module.state_dict()


@pytest.fixture
def canary(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[str, Path]]:
    """A module that, when imported, writes a file: ``(its name, the file)``. Neither may ever appear."""
    name = f"stamlane_canary_{uuid.uuid4().hex[:8]}"
    side = tmp_path / "side-effect"
    folder = tmp_path / "pkgs"
    folder.mkdir()
    (folder / f"{name}.py").write_text(
        f"from pathlib import Path\nPath({str(side)!r}).write_text('imported')\ndef s(*a, **k):\n    return None\n"
    )
    monkeypatch.syspath_prepend(str(folder))
    yield name, side
    assert name not in sys.modules, f"{name} was imported"
    assert not side.exists(), "the canary module ran"


def _save(path: Path, hparams: dict | None, state: dict | None = None, config: str | None = None) -> Path:
    content: dict = {"state_dict": state if state is not None else {}}
    if hparams is not None:
        content["hyper_parameters"] = hparams
    if config is not None:
        content["stamlane_config"] = config
    torch.save(content, path)
    return path


def _one_line(capsys: pytest.CaptureFixture[str], code: int) -> str:
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    lines = [line for line in err.splitlines() if line.startswith("stamlane ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _frames(folder: Path) -> Path:
    folder.mkdir()
    for i in range(1, 3):
        cv2.imwrite(str(folder / f"{i}.png"), np.zeros((36, 64, 3), np.uint8))
    return folder


def _shell(side: Path) -> dict:
    """A 'fusion' whose class_path starts with ``stamlane.`` and reaches ``os.system`` by attributes."""
    return {"class_path": "stamlane.demo.os.system", "init_args": {"command": f"touch {side}"}}


# ------------------------------------------------------------------ hyper_parameters (stream, export)
def test_a_good_checkpoint_still_builds(tmp_path: Path, weights: dict) -> None:
    module = StamLaneModule.from_checkpoint(_save(tmp_path / "ok.ckpt", NET, weights))
    assert isinstance(module.net.encoder, VGGEncoder) and module.num_frames == 2
    assert module.hparams["image_size"] == [32, 64]
    optimizers = module.configure_optimizers()
    optimizer = optimizers["optimizer"] if isinstance(optimizers, dict) else optimizers[0][0]
    assert isinstance(optimizer, torch.optim.AdamW) and optimizer.defaults["lr"] == 0.002


@pytest.mark.parametrize("command", ["stream", "export"])
def test_a_prefix_that_reaches_os_system_runs_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], weights: dict, command: str
) -> None:
    side = tmp_path / "pwned"
    ckpt = _save(tmp_path / "evil.ckpt", {**NET, "fusion": _shell(side)}, weights)
    argv = {
        "stream": ["stream", str(_frames(tmp_path / "frames")), "--ckpt", str(ckpt), "--out", str(tmp_path / "o")],
        "export": ["export", "--ckpt_path", str(ckpt), "--output", str(tmp_path / "m.onnx")],
    }[command]
    err = _one_line(capsys, main(argv))
    assert "'stamlane.demo.os.system'" in err and "fusion" in err and str(ckpt) in err
    assert not side.exists()


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("fusion", {"class_path": "stamlane.cli.importlib.import_module", "init_args": {"name": "{canary}"}}),
        ("encoder", "{canary}"),  # a plain module name where a class goes
        ("optimizer", "{canary}.s"),  # a function named by its dotted path
        ("encoder", {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": "{canary}.s"}}),
        ("loss", {"class_path": "stamlane.losses.LaneLoss", "init_args": {"x": {"class_path": "{canary}.s"}}}),
        ("_instantiator", "{canary}.s"),
    ],
    ids=["import_module", "plain-name", "callable", "typed-arg", "nested", "instantiator"],
)
@pytest.mark.parametrize("command", ["stream", "export"])
def test_hyper_parameters_import_nothing(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    canary: tuple[str, Path],
    weights: dict,
    command: str,
    key: str,
    value: object,
) -> None:
    value = yaml.safe_load(yaml.safe_dump(value).replace("{canary}", canary[0]))
    ckpt = _save(tmp_path / "evil.ckpt", {**NET, key: value}, weights)
    argv = {
        "stream": ["stream", str(_frames(tmp_path / "frames")), "--ckpt", str(ckpt), "--out", str(tmp_path / "o")],
        "export": ["export", "--ckpt_path", str(ckpt), "--output", str(tmp_path / "m.onnx")],
    }[command]
    err = _one_line(capsys, main(argv))
    assert str(ckpt) in err and key in err, err


@pytest.mark.parametrize(
    "hparams",
    [
        {**NET, "fusion": {"class_path": "stamlane.models.SТAM"}},  # a Cyrillic Т
        {**NET, "scheduler": {"class_path": "torch.optim.lr_scheduler.LambdaLR", "init_args": {"lr_lambda": "x.y"}}},
        {**NET, "num_frames": "2"},
        {**NET, "image_size": {"h": 32}},
        {**NET, "postprocess": [1, 2]},
        {**NET, "encoder": {"class_path": "stamlane.models.VGGEncoder", "init_args": {"widht": 0.125}}},
        {k: v for k, v in NET.items() if k != "encoder"},
    ],
    ids=["lookalike", "lambdalr", "str-int", "dict-list", "list-dict", "unknown-arg", "missing-key"],
)
def test_bad_hyper_parameters_are_one_line(tmp_path: Path, weights: dict, hparams: dict) -> None:
    ckpt = _save(tmp_path / "bad.ckpt", hparams, weights)
    with pytest.raises(CheckpointError) as info:
        StamLaneModule.from_checkpoint(ckpt)
    assert str(ckpt) in str(info.value) and "\n" not in str(info.value)


def test_missing_weights_are_one_line(tmp_path: Path, weights: dict) -> None:
    state = dict(list(weights.items())[1:])
    with pytest.raises(CheckpointError, match="does not fit"):
        StamLaneModule.from_checkpoint(_save(tmp_path / "cut.ckpt", NET, state))


# ------------------------------------------------------------------ run configs (predict, validate, test, demo)
def _run_config(fusion: object = None, **sections: object) -> str:
    config: dict = {"model": dict(NET_CONFIG), "data": {"root": "/nonexistent/stamlane-data"}}
    if fusion is not None:
        config["model"]["fusion"] = fusion
    for dotted, value in sections.items():
        section, _, key = dotted.partition("__")
        config.setdefault(section, {})
        if key:
            config[section][key] = value
        else:
            config[section] = value
    return yaml.safe_dump(config)


NET_CONFIG = {k: v for k, v in NET.items() if k not in ("_instantiator", "num_frames", "image_size", "crop_top")}


def _hostile_configs(canary: str, side: Path, tmp_path: Path) -> dict[str, str]:
    enc = tmp_path / "enc.yaml"
    enc.write_text(f"class_path: {canary}.s\n")
    lambda_cb = {"class_path": "lightning.pytorch.callbacks.LambdaCallback", "init_args": {"on_predict_start": ""}}
    lambda_cb["init_args"]["on_predict_start"] = f"{canary}.s"
    return {
        "os-system": _run_config(_shell(side)),
        "import-module": _run_config({"class_path": "stamlane.cli.importlib.import_module", "init_args": {"name": canary}}),
        "lambda-callback": _run_config(trainer__callbacks=[lambda_cb]),
        "abs-subconfig": _run_config(model__encoder=str(enc)),
        "rel-subconfig": _run_config(model__encoder="./enc.yaml"),
        "section-subconfig": _run_config(trainer=str(enc)),
        "lookalike": _run_config({"class_path": "stamlane.models.SТAM"}),
        "lambdalr": _run_config(lr_scheduler={"class_path": "torch.optim.lr_scheduler.LambdaLR", "init_args": {"lr_lambda": f"{canary}.s"}}),
        "profiler": _run_config(trainer__profiler=f"{canary}.s"),
        "wrong-type": _run_config(data__loader=[1, 2]),
        "unknown-key": _run_config(data__lodaer={"batch_size": 1}),
        "yaml-tag": _run_config() + "seed_everything: !!python/name:os.system\n",
        "binary-tag": _run_config() + "source: !!binary aGVsbG8=\n",
    }


CASES = [
    "os-system",
    "import-module",
    "lambda-callback",
    "abs-subconfig",
    "rel-subconfig",
    "section-subconfig",
    "lookalike",
    "lambdalr",
    "profiler",
    "wrong-type",
    "unknown-key",
    "yaml-tag",
    "binary-tag",
]


@pytest.mark.parametrize("case", CASES)
def test_a_checkpoints_run_config_runs_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], canary: tuple[str, Path], monkeypatch: pytest.MonkeyPatch, case: str
) -> None:
    side = tmp_path / "pwned"
    config = _hostile_configs(canary[0], side, tmp_path)[case]
    ckpt = _save(tmp_path / "evil.ckpt", None, config=config)
    monkeypatch.chdir(tmp_path)  # ./enc.yaml resolves here
    err = _one_line(capsys, main(["predict", "--ckpt_path", str(ckpt)]))
    assert str(ckpt) in err, err
    assert not side.exists()


@pytest.mark.parametrize("case", ["os-system", "lambda-callback", "abs-subconfig", "rel-subconfig", "wrong-type"])
def test_a_run_folders_config_runs_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], canary: tuple[str, Path], case: str
) -> None:
    side = tmp_path / "pwned"
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.yaml").write_text(_hostile_configs(canary[0], side, run)[case])
    ckpt = _save(run / "checkpoints" / "last.ckpt", None)
    err = _one_line(capsys, main(["validate", "--ckpt_path", str(ckpt)]))
    assert "config.yaml" in err, err
    assert not side.exists()


@pytest.mark.parametrize("case", ["os-system", "import-module", "lambda-callback", "rel-subconfig"])
def test_the_demo_re_predicts_nothing_hostile(
    tmp_path: Path, canary: tuple[str, Path], monkeypatch: pytest.MonkeyPatch, case: str
) -> None:
    """``stamlane demo --quick`` re-predicts a finished run from its ``run/config.yaml``."""
    from stamlane.experiments.engine import Experiment, ExperimentError

    side = tmp_path / "pwned"
    run = tmp_path / "out" / "stam4-s0" / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.yaml").write_text(_hostile_configs(canary[0], side, run)[case])
    _save(run / "checkpoints" / "last.ckpt", None)
    monkeypatch.chdir(run)
    experiment = Experiment(rows=[], recipe=None, seeds=[0], root=tmp_path / "data", out=tmp_path / "out")  # type: ignore[arg-type]
    with pytest.raises(ExperimentError) as info:
        experiment.predict("stam4-s0", run, "test")
    assert "config.yaml" in str(info.value) and "\n" not in str(info.value)
    assert not side.exists()


def test_a_forged_checkpoint_is_one_line_in_the_demo(tmp_path: Path) -> None:
    """A checkpoint that ``weights_only`` refuses (a pickled object), reached through a run the demo reuses."""
    from stamlane.experiments.engine import Experiment, ExperimentError

    run = tmp_path / "out" / "stam4-s0" / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.yaml").write_text(_run_config())
    torch.save({"state_dict": {}, "x": partial(print)}, run / "checkpoints" / "last.ckpt")
    experiment = Experiment(rows=[], recipe=None, seeds=[0], root=tmp_path / "data", out=tmp_path / "out")  # type: ignore[arg-type]
    with pytest.raises(ExperimentError) as info:
        experiment.predict("stam4-s0", run, "test")
    assert "last.ckpt" in str(info.value) and "\n" not in str(info.value)


def test_a_user_config_with_a_wrong_type_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "c.yaml"
    config.write_text("data:\n  loader: [1, 2]\n")
    err = _one_line(capsys, main(["validate", "--config", str(REPO / "configs" / "demo.yaml"), "--config", str(config)]))
    assert "loader" in err


def test_a_user_config_stays_code(tmp_path: Path, canary: tuple[str, Path]) -> None:
    """``--config`` is the user's own: the registry never checks it (it may name the user's classes)."""
    from stamlane.registry import check_run_config

    text = _run_config({"class_path": "my_package.MyFusion"})
    with pytest.raises(CheckpointError, match="my_package.MyFusion"):
        check_run_config(text, "x.ckpt")  # from a checkpoint: refused
