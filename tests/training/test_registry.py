"""The closed registry (`stamlane.training.registry`): what a file the user did not write may build.

A checkpoint's hyper_parameters, the run config it carries and a run folder's ``config.yaml`` are data: every name
in them is looked up in a table by its exact string, never imported, and every ``init_args`` value is a plain,
typed value. Each hostile case below ran code, imported a module or escaped as a traceback before the registry.

Nothing here trains: the checkpoints are written by hand, with the weights of a freshly built tiny network.
"""

from __future__ import annotations

import sys
import tempfile
import uuid
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from stamlane.cli import main
from stamlane.models import STAM, LaneDecoder, VGGEncoder
from stamlane.safety.checkpoints import CheckpointError
from stamlane.training.module import StamLaneModule
from stamlane.training.registry import safe_config_file

REPO = Path(__file__).resolve().parents[2]
torch.set_num_threads(1)
pytestmark = pytest.mark.usefixtures("plain_argv")

NET = {
    "encoder": {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": 0.125, "in_channels": 3}},
    "fusion": {"class_path": "stamlane.models.STAM", "init_args": {"mode": "mixed", "reduction": 4}},
    "decoder": {"class_path": "stamlane.models.LaneDecoder", "init_args": {"embed_dim": 4}},
    "loss": {"class_path": "stamlane.training.losses.LaneLoss", "init_args": {"delta_v": 0.5}},
    "optimizer": {"class_path": "torch.optim.AdamW", "init_args": {"lr": 0.002, "betas": [0.9, 0.999]}},
    "scheduler": {"class_path": "stamlane.training.module.PolyLR", "init_args": {"power": 0.9}},
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


def _reading(command: str, ckpt: Path, folder: Path) -> list[str]:
    """The arguments of ``stamlane stream`` (on two frames) or ``stamlane export`` reading the checkpoint ``ckpt``,
    their inputs and outputs under ``folder``."""
    if command == "stream":
        return ["stream", str(_frames(folder / "frames")), "--ckpt", str(ckpt), "--out", str(folder / "o")]
    return ["export", "--ckpt_path", str(ckpt), "--output", str(folder / "m.onnx")]


def _shell(side: Path) -> dict:
    """A 'fusion' whose class_path starts with ``stamlane.`` and reaches ``os.system`` by attributes."""
    return {"class_path": "stamlane.experiments.demo.os.system", "init_args": {"command": f"touch {side}"}}


# ------------------------------------------------------------------ hyper_parameters (stream, export)
def test_a_good_checkpoint_still_builds(tmp_path: Path, weights: dict) -> None:
    module = StamLaneModule.from_checkpoint(_save(tmp_path / "ok.ckpt", NET, weights))
    assert isinstance(module.net.encoder, VGGEncoder) and module.num_frames == 2
    assert module.hparams["image_size"] == [32, 64]
    optimizer = module.optimizer_factory(module.parameters())
    assert isinstance(optimizer, torch.optim.AdamW) and optimizer.defaults["lr"] == 0.002


@pytest.mark.parametrize("command", ["stream", "export"])
def test_a_prefix_that_reaches_os_system_runs_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], weights: dict, command: str
) -> None:
    side = tmp_path / "pwned"
    ckpt = _save(tmp_path / "evil.ckpt", {**NET, "fusion": _shell(side)}, weights)
    argv = _reading(command, ckpt, tmp_path)
    err = _one_line(capsys, main(argv))
    assert "'stamlane.experiments.demo.os.system'" in err and "fusion" in err and str(ckpt) in err
    assert not side.exists()


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("fusion", {"class_path": "stamlane.cli.importlib.import_module", "init_args": {"name": "{canary}"}}),
        ("encoder", "{canary}"),  # a plain module name where a class goes
        ("optimizer", "{canary}.s"),  # a function named by its dotted path
        ("encoder", {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": "{canary}.s"}}),
        ("loss", {"class_path": "stamlane.training.losses.LaneLoss", "init_args": {"x": {"class_path": "{canary}.s"}}}),
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
    argv = _reading(command, ckpt, tmp_path)
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


@pytest.mark.parametrize("cut", ["a-weight", "lightning-version"])
def test_a_checkpoint_with_missing_keys_is_one_line(
    tiny_synthetic: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], weights: dict, cut: str
) -> None:
    """``predict --ckpt_path`` with a checkpoint missing a weight or Lightning's version record, and its network's
    hyper-parameters (Lightning's restore raised a RuntimeError / KeyError traceback): one line naming the file (the
    stored model is built from the checkpoint's own record, `stamlane.training.stored.StoredModel`); with ``--config``
    the network of the config is checked against the weights."""
    root = tiny_synthetic(128, 72, 2, train=1, val=1, test=1, challenging=0, seed=5)
    config = _run_config(
        data={
            "root": str(root),
            "clip": {"num_frames": 2, "image_size": [32, 64], "align": "none"},
            "loader": {"batch_size": 1, "num_workers": 0},
        }
    )
    state = dict(list(weights.items())[1:]) if cut == "a-weight" else weights
    ckpt = _save(tmp_path / "cut.ckpt", None, state, config=config)
    if cut == "a-weight":
        content = torch.load(ckpt, weights_only=True)
        torch.save({**content, "pytorch-lightning_version": "2.6.6"}, ckpt)
    out = tmp_path / "predictions"
    err = _one_line(capsys, main(["predict", "--ckpt_path", str(ckpt), f"--predictions.output_dir={out}"]))
    assert str(ckpt) in err and "records no hyper_parameters" in err
    with safe_config_file(config, "run") as path:
        args = ["predict", "--config", str(path), "--ckpt_path", str(ckpt), f"--predictions.output_dir={out}"]
        err = _one_line(capsys, main(args))
    assert str(ckpt) in err and (
        "1 weights missing" in err if cut == "a-weight" else "pytorch-lightning_version" in err
    )


@pytest.mark.parametrize(
    "data",
    [
        {"clip": {"num_frames": "2"}},
        {"clip": [1, 2]},
        {"root": {"class_path": "{canary}.s"}},
        {"loader": "./loader.yaml"},
        {"clip": {"num_frames": 2, "image_size": [32, 64], "stride": {"class_path": "os.system"}}},
    ],
    ids=["str-int", "list", "class", "subconfig", "nested-class"],
)
def test_stream_refuses_bad_data_hyper_parameters(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], canary: tuple[str, Path], weights: dict, data: dict
) -> None:
    data = yaml.safe_load(yaml.safe_dump(data).replace("{canary}", canary[0]))
    ckpt = tmp_path / "c.ckpt"
    torch.save({"state_dict": weights, "hyper_parameters": NET, "datamodule_hyper_parameters": data}, ckpt)
    argv = ["stream", str(_frames(tmp_path / "frames")), "--ckpt", str(ckpt), "--out", str(tmp_path / "o")]
    err = _one_line(capsys, main(argv))
    assert str(ckpt) in err and "datamodule_hyper_parameters" in err, err


def test_aliases_and_shared_references_cannot_expand_without_bound(weights: dict) -> None:
    """A few hundred bytes of YAML aliases (or pickle references) standing for billions of values: refused at once."""
    from stamlane.training.registry import MAX_VALUES, build_module, check_run_config

    lines = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"{b}: &{b} [{', '.join([f'*{a}'] * 10)}]" for a, b in zip("abcdefgh", "bcdefghi")]
    with pytest.raises(CheckpointError, match=f"more than {MAX_VALUES:,} values"):
        check_run_config("\n".join(lines) + "\n", "x.ckpt")
    with pytest.raises(CheckpointError, match="at most 16,777,216 characters"):
        check_run_config("a: " + "x" * (16 << 20), "x.ckpt")
    shared: list = [0] * 10
    for _ in range(8):
        shared = [shared] * 10
    with pytest.raises(CheckpointError, match=f"more than {MAX_VALUES:,} values"):
        build_module({"state_dict": weights, "hyper_parameters": {**NET, "image_size": shared}}, "x.ckpt")


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
        "import-module": _run_config(
            {"class_path": "stamlane.cli.importlib.import_module", "init_args": {"name": canary}}
        ),
        "lambda-callback": _run_config(trainer__callbacks=[lambda_cb]),
        "abs-subconfig": _run_config(model__encoder=str(enc)),
        "rel-subconfig": _run_config(model__encoder="./enc.yaml"),
        "section-subconfig": _run_config(trainer=str(enc)),
        "lookalike": _run_config({"class_path": "stamlane.models.SТAM"}),
        "lambdalr": _run_config(
            lr_scheduler={"class_path": "torch.optim.lr_scheduler.LambdaLR", "init_args": {"lr_lambda": f"{canary}.s"}}
        ),
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
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    canary: tuple[str, Path],
    monkeypatch: pytest.MonkeyPatch,
    case: str,
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
    from stamlane.experiments.runner import Runner
    from stamlane.experiments.store import ExperimentError, RunStore

    side = tmp_path / "pwned"
    run = tmp_path / "out" / "stam4-s0" / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.yaml").write_text(_hostile_configs(canary[0], side, run)[case])
    _save(run / "checkpoints" / "last.ckpt", None)
    monkeypatch.chdir(run)
    runner = Runner(RunStore(tmp_path / "out"), tmp_path / "data")
    with pytest.raises(ExperimentError) as info:
        runner.predict("stam4-s0", run, "test")
    assert "config.yaml" in str(info.value) and "\n" not in str(info.value)
    assert not side.exists()


def test_a_forged_checkpoint_is_one_line_in_the_demo(tmp_path: Path) -> None:
    """A checkpoint that ``weights_only`` refuses (a pickled object), reached through a run the demo reuses."""
    from stamlane.experiments.runner import Runner
    from stamlane.experiments.store import ExperimentError, RunStore

    run = tmp_path / "out" / "stam4-s0" / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.yaml").write_text(_run_config())
    torch.save({"state_dict": {}, "x": partial(print)}, run / "checkpoints" / "last.ckpt")
    runner = Runner(RunStore(tmp_path / "out"), tmp_path / "data")
    with pytest.raises(ExperimentError) as info:
        runner.predict("stam4-s0", run, "test")
    assert "last.ckpt" in str(info.value) and "\n" not in str(info.value)


def test_a_user_config_with_a_wrong_type_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "c.yaml"
    config.write_text("data:\n  loader: [1, 2]\n")
    err = _one_line(
        capsys, main(["validate", "--config", str(REPO / "configs" / "demo.yaml"), "--config", str(config)])
    )
    assert "loader" in err


def test_a_user_config_stays_code(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--config`` is the user's own, like a script: it may name the user's classes. The same text read from a
    checkpoint or a run folder is refused."""
    from stamlane.training.lightning_cli import StamLaneCLI
    from stamlane.training.registry import check_run_config

    name = f"user_fusion_{uuid.uuid4().hex[:8]}"
    (tmp_path / f"{name}.py").write_text(
        "from stamlane.models import SimpleAdd\n\n\nclass Fusion(SimpleAdd):\n    pass\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    user = tmp_path / "mine.yaml"
    user.write_text(f"model:\n  fusion:\n    class_path: {name}.Fusion\n")
    with pytest.raises(SystemExit) as exit_:
        StamLaneCLI(
            args=["fit", "--config", str(REPO / "configs" / "demo.yaml"), "--config", str(user), "--print_config"]
        )
    assert exit_.value.code in (0, None) and f"class_path: {name}.Fusion" in capsys.readouterr().out
    with pytest.raises(CheckpointError, match=rf"model\.fusion\.class_path names '{name}\.Fusion', not in"):
        check_run_config(_run_config({"class_path": f"{name}.Fusion"}), "x.ckpt")


def _shipped() -> list[list[str]]:
    """The ``--config`` lists of the shipped configs: each of configs/, and every 4th paper row on its base (the
    rows differ in the fusion's init_args only)."""
    from stamlane.experiments.table_index import load_tables

    index = load_tables(REPO / "configs" / "paper" / "tables.yaml")
    rows = sorted({r.config for t in index.tables.values() for r in t.rows})
    lists = [[str(c)] for c in sorted((REPO / "configs").glob("*.yaml"))]
    return lists + [[str(c) for c in (index.default_base, *index.layers, row)] for row in rows[::4]]


def test_every_shipped_config_as_fit_stores_it_passes(capsys: pytest.CaptureFixture[str]) -> None:
    """What ``stamlane fit`` writes into its checkpoints and run folders (the config dumped whole) passes."""
    from stamlane.training.lightning_cli import StamLaneCLI
    from stamlane.training.registry import check_run_config

    for configs in _shipped():
        with pytest.raises(SystemExit):
            StamLaneCLI(args=["fit", *(a for c in configs for a in ("--config", c)), "--print_config"])
        check_run_config(capsys.readouterr().out, configs[-1])


# ------------------------------------------------------------------ property: any hostile stored config or hparams
_IDENT = st.text("abcdefghijklmnopqrstuvwxyz_", min_size=1, max_size=6)
_LOOKALIKE = {"a": "а", "e": "е", "o": "о", "c": "с", "p": "р", "S": "Ѕ", "T": "Т", "A": "А", "M": "М"}  # Cyrillic


def _lookalike(name: str, at: int) -> str:
    spots = [i for i, ch in enumerate(name) if ch in _LOOKALIKE]
    i = spots[at % len(spots)] if spots else 0
    return name[:i] + _LOOKALIKE.get(name[i], "\u200b" + name[i]) + name[i + 1 :]


def _names(canary: str, enc: Path) -> st.SearchStrategy[str]:
    from stamlane.training.registry import registry

    known = st.sampled_from(sorted(registry()))
    return st.one_of(
        known,
        known,  # twice: a good share of the examples is accepted, and then parsed
        st.builds(lambda parts: ".".join(["stamlane", *parts, "os", "system"]), st.lists(_IDENT, max_size=2)),
        st.builds(_lookalike, known, st.integers(0, 20)),
        st.sampled_from(
            [
                canary,
                f"{canary}.s",
                "stamlane.cli.importlib.import_module",
                "stamlane.experiments.demo.os.system",
                "lightning.pytorch.callbacks.LambdaCallback",
                "torch.optim.lr_scheduler.LambdaLR",
                "builtins.exec",
                str(enc),
                "./enc.yaml",
                "stamlane.models.STAM.__init__.__globals__",
            ]
        ),
    )


def _hostile_values(names: st.SearchStrategy[str]) -> st.SearchStrategy[object]:
    args = st.sampled_from(["name", "command", "width", "on_predict_start", "lr_lambda", "mode", "lr", "x"])
    leaf = st.one_of(names, st.integers(-2, 3), st.booleans(), st.none(), st.text(max_size=8), st.just([1, 2]))
    good = st.sampled_from(  # values that fit some place: then accepted, and parsed
        [
            {"class_path": "stamlane.models.SimpleAdd"},
            {"class_path": "torch.optim.SGD", "init_args": {"lr": 0.1}},
            "stamlane.training.module.paper_sgd",
            [{"class_path": "lightning.pytorch.callbacks.ModelCheckpoint", "init_args": {"monitor": "val/loss"}}],
            {"class_path": "lightning.pytorch.loggers.CSVLogger", "init_args": {"save_dir": "logs"}},
            "auto",
            {"batch_size": 2},
        ]
    )
    return st.one_of(
        names,
        good,
        names.map(lambda n: {"class_path": n}),
        st.builds(lambda n, a, v: {"class_path": n, "init_args": {a: v}}, names, args, leaf),
        st.builds(lambda v: {"class_path": "stamlane.models.STAM", "init_args": {"mode": v}}, leaf),
        leaf,
    )


_PLACES = [
    ("model", "encoder"),
    ("model", "fusion"),
    ("model", "decoder"),
    ("model", "loss"),
    ("model", "optimizer"),
    ("model", "scheduler"),
    ("model", "postprocess"),
    ("model", "bf16"),
    ("trainer", "callbacks"),
    ("trainer", "logger"),
    ("trainer", "profiler"),
    ("trainer", "strategy"),
    ("trainer", "plugins"),
    ("data", "loader"),
    ("data", "clip"),
    ("optimizer", None),
    ("lr_scheduler", None),
    ("trainer", None),
]
_TAGS = ["!!python/name:{canary}.s", "!!python/object/apply:os.system ['touch {side}']", "!!binary aGk=", "!!set {{a}}"]


def _placed(place: tuple[str, str | None], value: object) -> str:
    """The run config of `_run_config` with ``value`` at ``place`` (one of `_PLACES`: a key of a section, or the
    whole section), as YAML text."""
    config = yaml.safe_load(_run_config())
    section, key = place
    if key is None:
        config[section] = value
    else:
        config.setdefault(section, {})[key] = value
    return yaml.safe_dump(config)


def _refused_in_one_line(err: CheckpointError) -> None:
    """A hostile value refused as it must be: in one line naming the file (``evil.ckpt``)."""
    message = str(err)
    assert "\n" not in message and "evil.ckpt" in message, message
    event("refused")


@settings(max_examples=60, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_any_hostile_stored_config_is_refused_in_one_line_or_fully_registered(
    tmp_path: Path, canary: tuple[str, Path], data: st.DataObject
) -> None:
    """Property: a run config from a checkpoint or a run folder with a hostile value put anywhere a class, a callable
    or an option goes (random ``stamlane.x.os.system`` chains, look-alike letters, callables in init_args, sub-config
    paths, YAML tags, wrong types) is refused in one line naming the file and the key, or accepted only when every
    dotted name in it is an exact registry entry; nothing is imported, no file written."""
    from stamlane.training.registry import check_run_config, registry

    name, side = canary
    enc = tmp_path / "enc.yaml"
    enc.write_text(f"class_path: {name}.s\n")
    place = data.draw(st.sampled_from(_PLACES), label="place")
    value = data.draw(_hostile_values(_names(name, enc)), label="value")
    text = _placed(place, value)
    if data.draw(st.integers(0, 3), label="tagged") == 0:
        tag = data.draw(st.sampled_from(_TAGS), label="tag").format(canary=name, side=side)
        text += f"source: {tag}\n"
    try:
        checked = check_run_config(text, "evil.ckpt")
    except CheckpointError as err:
        _refused_in_one_line(err)
    else:
        event("accepted")
        assert all(c in registry() for c in _class_paths(checked)), checked
        _parse(text)  # what `stamlane predict --ckpt_path` then does with it: jsonargparse resolves every name
    assert name not in sys.modules and not side.exists()


def _class_paths(value: object) -> Iterator[str]:
    if isinstance(value, dict):
        if "class_path" in value:
            yield value["class_path"]
        for item in value.values():
            yield from _class_paths(item)
    elif isinstance(value, list):
        for item in value:
            yield from _class_paths(item)


def _parse(text: str) -> None:
    from jsonargparse import ArgumentError

    from stamlane.training.lightning_cli import StamLaneCLI

    with safe_config_file(text, "evil.ckpt") as path:
        try:
            StamLaneCLI(
                args=["predict", "--config", str(path), "--print_config"], parser_kwargs={"exit_on_error": False}
            )
        except (SystemExit, ArgumentError, ValueError):
            pass


@settings(max_examples=40, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_any_hostile_hyper_parameters_build_nothing_foreign(
    tmp_path: Path, canary: tuple[str, Path], weights: dict, data: st.DataObject
) -> None:
    """Property: hyper_parameters with a hostile value in any option are refused in one line naming the checkpoint
    and the key, or build a network whose every class is a registry entry; nothing is imported."""
    from stamlane.training.registry import build_module, registry

    name, side = canary
    enc = tmp_path / "enc.yaml"
    enc.write_text(f"class_path: {name}.s\n")
    key = data.draw(st.sampled_from([*NET, "extra"]), label="key")
    value = data.draw(_hostile_values(_names(name, enc)), label="value")
    try:
        module = build_module({"state_dict": weights, "hyper_parameters": {**NET, key: value}}, "evil.ckpt")
    except CheckpointError as err:
        _refused_in_one_line(err)
    else:
        event("accepted")
        built = {f"{type(m).__module__}.{type(m).__qualname__}" for m in module.net.modules()}
        own = {n for n in built if n.startswith("stamlane.models.")}
        assert own <= set(registry()) | {n for n in built if "LaneNet" in n or "models." in n}
    assert name not in sys.modules and not side.exists()


@settings(max_examples=8, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
@pytest.mark.parametrize("command", ["predict", "validate", "stream", "export"])
def test_every_command_answers_a_hostile_checkpoint_in_one_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    canary: tuple[str, Path],
    weights: dict,
    command: str,
    data: st.DataObject,
) -> None:
    """Property, per command that reads a checkpoint: whatever hostile value its run config (predict), its run
    folder's config.yaml (validate) or its hyper_parameters (stream, export) hold, the answer is one line and exit
    2 (the data root of the configs does not exist, so an accepted config ends there), and nothing is imported."""
    name, side = canary
    folder = Path(tempfile.mkdtemp(dir=tmp_path))
    enc = folder / "enc.yaml"
    enc.write_text(f"class_path: {name}.s\n")
    value = data.draw(_hostile_values(_names(name, enc)), label="value")
    run = folder / "run"
    (run / "checkpoints").mkdir(parents=True)
    ckpt = run / "checkpoints" / "last.ckpt"
    if command in ("predict", "validate"):
        text = _placed(data.draw(st.sampled_from(_PLACES), label="place"), value)
        if command == "validate":
            (run / "config.yaml").write_text(text)
        _save(ckpt, NET, weights, config=text if command == "predict" else None)
        argv = [command, "--ckpt_path", str(ckpt)]
    else:
        key = data.draw(st.sampled_from(sorted(NET)), label="key")
        _save(ckpt, {**NET, key: value}, weights)
        argv = _reading(command, ckpt, folder) + (["--opset", "17"] if command == "export" else [])
    code = main(argv)
    err = capsys.readouterr().err.strip()
    ours = [line for line in err.splitlines() if line.startswith("stamlane ")]
    assert "Traceback" not in err and (code == 0 or (code == 2 and len(ours) == 1)), err
    assert name not in sys.modules and not side.exists()
