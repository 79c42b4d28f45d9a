"""Several processes on the CPU (gloo): scores equal one process's to the last bit on splits of every remainder,
one prediction file, and every launcher Lightning users know (ddp, ddp_spawn, torchrun, two "nodes" by environment
variables) fits, validates, checkpoints and resumes. docs/distributed.md."""

from __future__ import annotations

import csv
import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from stamlane_eval.integrations.distributed import RepeatedImageError, gather_records
from stamlane_eval.integrations.lightning import LaneEvalCallback

from stamlane.cli import main
from stamlane.data import datamodule
from stamlane.training.lightning_cli import StamLaneCLI
from stamlane.training.stored import StoredModel
from stamlane.training.stored_cli import parse
from stamlane.training.stored_predict import prediction_trainer_options
from tests.training.tiny_runs import tiny_args

pytestmark = pytest.mark.usefixtures("plain_argv")

ENV = {**os.environ, "OMP_NUM_THREADS": "1", "OMP_WAIT_POLICY": "PASSIVE", "PYTHONWARNINGS": "ignore"}
TWO = ["--trainer.strategy=ddp", "--trainer.devices=2", "--trainer.accelerator=cpu"]
TIMEOUT = 300


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _run(args: list[str], *, env: dict[str, str] | None = None, launcher: list[str] | None = None) -> str:
    """``stamlane ARGS`` in a process of its own (Lightning's ddp launches the command line again for rank 1)."""
    command = [*(launcher or [sys.executable]), "-m", "stamlane.cli", *args]
    proc = subprocess.run(command, env=env or ENV, capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return proc.stdout


def _logged(folder: Path, prefix: str) -> dict[str, str]:
    """The values logged under ``prefix`` in a run's metrics.csv, as written (strings: compared bit for bit)."""
    rows = list(csv.DictReader(next(folder.rglob("metrics.csv")).open()))
    return {k: v for row in rows for k, v in row.items() if v and k.startswith(prefix)}


def _stored(command: str, root: Path, out: Path, *extra: str) -> list[str]:
    """``COMMAND`` of the shipped single-frame model (its config from the checkpoint; it finds lanes on the tiny set:
    F1 0.6 on val, not 0 as a model of a few steps) on the tiny set, 2 images a batch, scores without timing."""
    return [
        command,
        "--ckpt_path=single-synthetic",
        f"--data.root={root}",
        "--data.loader.batch_size=2",
        "--data.loader.num_workers=0",
        "--model.report_run_time=false",
        f"--trainer.default_root_dir={out}",
        "--trainer.logger=lightning.pytorch.loggers.CSVLogger",
        f"--trainer.logger.save_dir={out}",
        "--trainer.enable_progress_bar=false",
        *extra,
    ]


@pytest.mark.parametrize(("command", "stage", "images"), [("validate", "val", 5), ("test", "test", 7)])
def test_two_processes_score_as_one_bit_for_bit(
    command: str, stage: str, images: int, tiny_set: Path, tmp_path: Path
) -> None:
    """5 and 7 images on 2 processes: Lightning's DistributedSampler would pad them to 6 and 8 (repeats scored)."""
    torch.set_num_threads(1)
    assert len((tiny_set / f"{stage}.json").read_text().splitlines()) == images
    assert main(_stored(command, tiny_set, tmp_path / "one")) == 0  # one process: the stored trainer's, unless asked
    one = _logged(tmp_path / "one", f"{stage}/")
    _run([*_stored(command, tiny_set, tmp_path / "two"), *TWO])
    two = _logged(tmp_path / "two", f"{stage}/")
    assert {f"{stage}/tusimple_f1", f"{stage}/culane_f1@0.5", f"{stage}/loss"} <= one.keys()
    assert 0 < float(one[f"{stage}/tusimple_f1"]) < 1 and 0 < float(one[f"{stage}/culane_f1@0.5"]) < 1
    assert two == one  # every number, as written


def test_two_processes_predict_one_file_in_the_split_order(tiny_set: Path, tmp_path: Path) -> None:
    torch.set_num_threads(1)

    def args(out: Path) -> list[str]:
        written = f"--predictions.output_dir={out / 'predictions'}"
        return [
            a for a in _stored("predict", tiny_set, out, written, "--predictions.overlays=false") if "logger" not in a
        ]

    assert main(args(tmp_path / "one")) == 0
    said = _run([*args(tmp_path / "two"), *TWO])
    assert "wrote 7 tusimple" in said  # every process's count
    files = {run: sorted(p.name for p in (tmp_path / run / "predictions").iterdir()) for run in ("one", "two")}
    assert "predictions.json" in files["two"] and files["two"] == files["one"]  # no .rank<r>.json beside it

    def records(out: Path) -> list[dict]:
        lines = (out / "predictions" / "predictions.json").read_text().splitlines()
        return [{k: v for k, v in json.loads(line).items() if k != "run_time"} for line in lines]

    assert len(records(tmp_path / "one")) == 7
    assert records(tmp_path / "two") == records(tmp_path / "one")  # the same lanes, in the same order


def test_an_image_scored_twice_is_refused() -> None:
    """The guard behind the non-repeating sampler: a padded shard (an image twice) is an error, not a score."""
    with pytest.raises(RepeatedImageError, match="image 3 came twice"):
        gather_records([(3, "a"), (1, "b"), (3, "a")], "val scores")
    assert gather_records([(3, "a"), (1, "b")], "val scores") == [(1, "b"), (3, "a")]
    callback = LaneEvalCallback(culane=False)
    lanes = [[[[0.0, 10.0], [1.0, 20.0]]]] * 2
    step = {"pred_lanes": lanes, "gt_lanes": lanes, "h_samples": [[10, 20]] * 2, "orig_size": [(30, 40)] * 2}
    callback._keep({**step, "image_id": [0, 1]})
    callback._keep({**step, "image_id": [1, 2]})

    class _Module:
        def log(self, name: str, value: float) -> None:
            raise AssertionError("nothing may be logged")

    with pytest.raises(RepeatedImageError, match="image 1 came twice"):
        callback._log(_Module(), "val")


def test_the_evaluation_sampler_shares_without_repeats(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(torch.distributed, "is_initialized", lambda: True)
    monkeypatch.setattr(torch.distributed, "get_world_size", lambda group=None: 2)
    shares = []
    for rank in (0, 1):
        monkeypatch.setattr(torch.distributed, "get_rank", lambda group=None, r=rank: r)
        shares.append(list(datamodule.eval_sampler(list(range(5)), "val")))
    assert shares == [[0, 2, 4], [1, 3]]
    with pytest.raises(datamodule.DataError, match="1 images, fewer than the 2 processes"):
        datamodule.eval_sampler([0], "val")


def test_stored_runs_are_scored_in_one_process_unless_asked(monkeypatch: pytest.MonkeyPatch) -> None:
    """One process is the stored model's default, on values: a command's own trainer options replace it."""
    for name in ("TORCHELASTIC_RUN_ID", "SLURM_NTASKS", "RANK", "GROUP_RANK", "LOCAL_RANK", "LOCAL_WORLD_SIZE"):
        monkeypatch.delenv(name, raising=False)
    stored = {"devices": 8, "num_nodes": 2, "strategy": "ddp", "max_steps": 1500, "precision": "bf16-mixed"}
    one = {"devices": 1, "num_nodes": 1, "strategy": "auto"}
    assert prediction_trainer_options(stored) == {"precision": "bf16-mixed", **one}
    assert prediction_trainer_options(stored, keep=None) == {**stored, **one}
    model = StoredModel.open("single-synthetic")
    for command in ("validate", "test", "predict"):
        config, _ = parse(model, ["--ckpt_path=single-synthetic"], command)
        assert (config.trainer.devices, config.trainer.num_nodes, config.trainer.strategy) == (1, 1, "auto")
        config, _ = parse(model, ["--ckpt_path=single-synthetic", "--trainer.devices=2"], command)
        assert str(config.trainer.devices) == "2"  # as Lightning reads it: a string or an int
    monkeypatch.setenv("SLURM_NTASKS", "4")  # srun started the processes: Lightning takes them from SLURM
    assert prediction_trainer_options(stored) == {"precision": "bf16-mixed", **dict(list(stored.items())[:3])}


# ---------------------------------------------------------------------------------------------------- launchers
def _fit_and_resume(tiny_set: Path, out: Path, launch: list[list[str]], extra: list[str], envs: list[dict]) -> None:
    """Fit 2 steps in this process (last.ckpt), then, started as given, resume it and fit to step 4: training steps,
    a validation of 5 images at step 4 and a checkpoint, all in the launched processes (one launch: the processes'
    start is what costs, 10-15 s each on a 2-core CPU)."""
    torch.set_num_threads(1)
    StamLaneCLI(args=["fit", *tiny_args(tiny_set, out, "--trainer.max_steps=2", "--trainer.limit_val_batches=0")])
    first = next(out.rglob("last.ckpt"))
    args = ["fit", *tiny_args(tiny_set, out, "--trainer.max_steps=4", "--trainer.val_check_interval=2")]
    args += [*extra, f"--ckpt_path={first}"]
    procs = [
        subprocess.Popen(
            [*cmd, "-m", "stamlane.cli", *args], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        for cmd, env in zip(launch, envs, strict=True)
    ]
    for proc in procs:
        _, err = proc.communicate(timeout=TIMEOUT)
        assert proc.returncode == 0, err[-4000:]
    resumed = next(p for p in out.rglob("last.ckpt") if p != first)
    assert torch.load(first, weights_only=True)["global_step"] == 2
    assert torch.load(resumed, weights_only=True)["global_step"] == 4  # 2 steps more, in the launched processes
    assert "val/tusimple_f1" in _logged(resumed.parent.parent, "val/")
    assert not list(out.rglob("*rank*"))  # one set of files: rank 0's


@pytest.mark.parametrize("strategy", ["ddp", "ddp_spawn"])
def test_ddp_and_ddp_spawn_fit_validate_resume(strategy: str, tiny_set: Path, tmp_path: Path) -> None:
    extra = [f"--trainer.strategy={strategy}", "--trainer.devices=2", "--trainer.accelerator=cpu"]
    _fit_and_resume(tiny_set, tmp_path, [[sys.executable]], extra, [ENV])


def test_torchrun_fit_validate_resume(tiny_set: Path, tmp_path: Path) -> None:
    torchrun = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2"]
    _fit_and_resume(tiny_set, tmp_path, [torchrun], TWO, [ENV])


def test_two_nodes_by_environment_variables_fit_validate_resume(tiny_set: Path, tmp_path: Path) -> None:
    """Two "machines" of one process each, as a cluster without SLURM starts them: NODE_RANK, MASTER_ADDR/PORT."""
    port = str(_free_port())
    envs = [{**ENV, "MASTER_ADDR": "127.0.0.1", "MASTER_PORT": port, "NODE_RANK": str(r)} for r in (0, 1)]
    extra = ["--trainer.strategy=ddp", "--trainer.devices=1", "--trainer.num_nodes=2", "--trainer.accelerator=cpu"]
    _fit_and_resume(tiny_set, tmp_path, [[sys.executable]] * 2, extra, envs)
