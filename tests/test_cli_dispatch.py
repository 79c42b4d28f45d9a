"""The ``stamlane`` dispatcher: tools, LightningCLI commands, ``predict --stream``."""

from __future__ import annotations

import pytest

from stamlane import cli


def test_usage_and_unknown_command(capsys):
    assert cli.main([]) == 2
    assert "usage: stamlane" in capsys.readouterr().err
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    for command in (*cli.LIGHTNING_COMMANDS, *cli.TOOLS):  # every command listed with its line
        assert f"  {command} " in out and cli.SUMMARIES[command] in out
    assert set(cli.SUMMARIES) == {*cli.LIGHTNING_COMMANDS, *cli.TOOLS}
    assert cli.main(["nonsense"]) == 2
    assert "unknown command 'nonsense'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("rest", "expected"),
    [
        (["--stream", "drive.mp4", "--ckpt", "a.ckpt"], ["drive.mp4", "--ckpt", "a.ckpt"]),
        (["--ckpt", "a.ckpt", "--stream=drive.mp4", "--no-video"], ["drive.mp4", "--ckpt", "a.ckpt", "--no-video"]),
    ],
)
def test_predict_stream_arguments(rest, expected):
    assert cli._stream_args(rest) == expected


def test_predict_stream_runs_the_stream_tool(tmp_path, capsys):
    missing = tmp_path / "missing.mp4"
    assert cli.main(["predict", "--stream", str(missing), "--config", "configs/demo.yaml"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("stamlane stream") and "missing.mp4" in err[0], err


def test_versions_come_from_the_package_metadata(capsys):
    from importlib.metadata import version

    from stamlane_eval import cli as eval_cli

    assert cli.main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"stamlane {version('stamlane')}"
    assert eval_cli.main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"stamlane-eval {version('stamlane-eval')}"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["predict"], "stamlane predict: give --ckpt_path CKPT (a trained run's checkpoint"),
        (["validate", "--trainer.devices=1"], "stamlane validate: give --ckpt_path CKPT"),
        (["fit"], "stamlane fit: give --config CONFIG"),
        (["predict", "--ckpt_path", "nowhere/last.ckpt"], "checkpoint nowhere/last.ckpt does not exist: give the path"),
        (["fit", "--config=nowhere.yaml"], "stamlane fit: config nowhere.yaml does not exist"),
    ],
)
def test_what_is_missing_is_said_before_torch_is_imported(argv, message):
    """A missing file or argument is answered before torch and Lightning are imported (what makes it fast; the time
    itself is not asserted: a shared machine's load would make that test flaky)."""
    import subprocess
    import sys

    code = (
        "import sys; from stamlane.cli import main; rc = main(sys.argv[1:]);"
        "assert 'torch' not in sys.modules and 'lightning' not in sys.modules; sys.exit(rc)"
    )
    proc = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and message in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_help_is_not_taken_for_a_missing_argument():
    assert cli._missing_input("predict", ["--help"]) is None
    assert cli._missing_input("validate", ["--config", "configs/demo.yaml"]) is None
    assert cli._missing_input("predict", ["-c", "configs/demo.yaml"]) is None  # LightningCLI's short --config
    assert "config nowhere.yaml does not exist" in cli._missing_input("predict", ["-c", "nowhere.yaml"])
    assert cli._missing_input("fit", ["--ckpt_path=last", "--config", "configs/demo.yaml"]) is None


def test_a_relative_data_root_is_found_from_the_start_folder_then_the_run_folder(tmp_path, monkeypatch):
    """`stamlane.training.runs.Run.data_root`: what ``validate|test|predict --ckpt_path`` give the run as its root."""
    from pathlib import Path

    from stamlane.data.labels import DataError
    from stamlane.training.runs import Run

    def run(root, ckpt, start=None):
        return Run(Path(ckpt), {"data": {"root": root}}, Path(ckpt), "", start)

    start, elsewhere = tmp_path / "start", tmp_path / "elsewhere"
    (start / "data" / "set").mkdir(parents=True)
    elsewhere.mkdir()
    ckpt = start / "runs" / "stam4" / "version_0" / "checkpoints" / "last.ckpt"
    monkeypatch.chdir(elsewhere)
    found = start / "data" / "set"
    assert run("data/set", ckpt, str(start)).data_root() == found  # the recorded start folder
    assert run("data/set", ckpt).data_root() == found  # an ancestor of the run folder
    assert run(str(tmp_path), ckpt).data_root() is None  # absolute: as it is
    far = tmp_path / "far" / "last.ckpt"
    with pytest.raises(DataError, match=r"data root data/set .* give --data.root DIR$"):
        run("data/set", far).data_root()
    assert run(None, far).data_root() is None  # the default synthetic set: made
    monkeypatch.chdir(start)
    assert run("data/set", far).data_root() is None  # here, as before
