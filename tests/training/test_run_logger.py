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
