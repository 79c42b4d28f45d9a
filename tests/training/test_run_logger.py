"""Where a run's logs go is decided on the values parsed, not on which flags were typed (`RunLogger`,
`StamLaneCLI._logs_outside_run`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from stamlane.training.lightning_cli import StamLaneCLI
from stamlane.training.run_logger import RunLogger
from stamlane.training.runs import run_cli
from stamlane.training.stored_cli import scoring_name
from tests.training.tiny_runs import REPO

DEMO = str(REPO / "configs" / "demo.yaml")


class _Parsed(Exception):
    """The config a command parsed to (raised before anything is built)."""


class _ParseOnly(StamLaneCLI):
    def before_instantiate_classes(self) -> None:  # LightningCLI's public hook, after every rule of parsing
        raise _Parsed(self.config)


def _parsed(args: list[str]) -> object:
    """The config ``stamlane ARGS`` parses to, the subcommand first."""
    with pytest.raises(_Parsed) as parsed:
        run_cli(args, cli=_ParseOnly)
    return parsed.value.args[0]


def _trainer(args: list[str]) -> object:
    """The trainer ``stamlane fit ARGS`` would train with (nothing run)."""
    return run_cli(args, run=False).trainer


def test_a_run_logger_without_a_folder_writes_under_the_trainer_root(tmp_path: Path) -> None:
    assert RunLogger().save_dir == "."
    root = tmp_path / "root"
    by_flag = _trainer(["--config", DEMO, f"--trainer.default_root_dir={root}"])
    assert Path(by_flag.logger.log_dir) == root / "stam4" / "version_0"
    config = tmp_path / "root.yaml"  # the same value from a file: the same folder
    config.write_text(f"trainer:\n  default_root_dir: {root}\n")
    by_file = _trainer(["--config", DEMO, "--config", str(config)])
    assert by_file.logger.log_dir == by_flag.logger.log_dir
    given = _trainer(["--config", DEMO, f"--trainer.default_root_dir={root}", f"--trainer.logger.save_dir={tmp_path}"])
    assert Path(given.logger.log_dir) == tmp_path / "stam4" / "version_0"  # a save_dir given is kept
    assert Path(_trainer(["--config", DEMO]).logger.save_dir) == Path("outputs/demo")  # the configs' root


@pytest.mark.parametrize("command", ["validate", "test"])
def test_scores_log_beside_the_run_whichever_name_is_given(command: str, tmp_path: Path) -> None:
    assert scoring_name("stam4", command) == f"stam4-{command}"
    assert scoring_name(None, command) == f"lightning_logs-{command}"
    assert scoring_name(f"stam4-{command}", command) == f"stam4-{command}"  # not extended twice
    for extra, name in (([], "stam4"), (["--trainer.logger.name=mine"], "mine")):
        config = _parsed([command, "--config", DEMO, f"--trainer.default_root_dir={tmp_path}", *extra])
        assert config[command].trainer.logger.init_args.name == f"{name}-{command}"
        assert config[command].trainer.logger.init_args.save_dir == str(tmp_path)
    assert _parsed(["predict", "--config", DEMO]).predict.trainer.logger is False  # predict logs no metric


@pytest.mark.parametrize(
    ("save_dir", "says"),
    [
        ({"class_path": "os.system"}, "trainer.logger"),  # a class where a folder goes
        ([1, 2], "trainer.logger"),  # not a folder
        ("dir\x00name", "trainer.logger.init_args.save_dir"),  # a folder no file system names
    ],
)
def test_a_run_logger_in_a_stored_config_is_checked_like_any_value(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], save_dir: object, says: str
) -> None:
    """A checkpoint's config may name `RunLogger` (the registry has it), with plain values only: anything else is
    one line, exit status 2, before anything is built or written."""
    import torch
    import yaml

    from stamlane.cli import main
    from stamlane.training.lightning_cli import CONFIG_KEY

    content = torch.load(REPO / "src/stamlane/weights/single-synthetic.ckpt", map_location="cpu", weights_only=True)
    stored = yaml.safe_load(content[CONFIG_KEY])
    logger = {"class_path": "stamlane.training.run_logger.RunLogger", "init_args": {"name": "x"}}
    stored["trainer"]["logger"] = logger
    content[CONFIG_KEY] = yaml.safe_dump(stored)
    torch.save(content, tmp_path / "ok.ckpt")
    assert StoredModel_opens(tmp_path / "ok.ckpt")
    logger["init_args"]["save_dir"] = save_dir
    content[CONFIG_KEY] = yaml.safe_dump(stored)
    torch.save(content, tmp_path / "bad.ckpt")
    assert main(["validate", "--ckpt_path", str(tmp_path / "bad.ckpt")]) == 2
    err = capsys.readouterr().err.strip()
    ours = [line for line in err.splitlines() if line.startswith("stamlane")]
    assert len(ours) == 1 and says in ours[0] and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.ckpt", "ok.ckpt"]  # nothing written


def StoredModel_opens(ckpt: Path) -> bool:
    """Whether ``ckpt`` opens as a stored model whose logger is a `RunLogger`."""
    from stamlane.training.stored import StoredModel

    return StoredModel.open(ckpt).section("trainer")["logger"]["class_path"].endswith("RunLogger")
