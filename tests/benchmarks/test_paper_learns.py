"""``benchmarks/paper_learns.py``: the stable layer composes with the paper config and changes only the gradient
clipping; the benchmark's reading of Lightning's log tells a diverging run from one whose loss falls; its quickest
mode trains the stable variant a few steps on a TuSimple-layout set and writes the curve."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import torch

from stamlane.training.lightning_cli import StamLaneCLI
from tests.benchmarks.scripts import REPO, load_script

PAPER, STABLE = REPO / "configs" / "tusimple_stam4.yaml", REPO / "configs" / "common" / "stable_sgd.yaml"
torch.set_num_threads(1)


paper_learns = load_script("paper_learns")
pytestmark = pytest.mark.usefixtures("plain_argv")


def test_the_stable_layer_clips_the_paper_s_sgd_and_changes_nothing_else():
    quiet = ["--trainer.logger=false", "--trainer.enable_checkpointing=false", "--trainer.callbacks=[]"]
    paper = StamLaneCLI(args=["--config", str(PAPER), *quiet], run=False)
    stable = StamLaneCLI(args=["--config", str(PAPER), "--config", str(STABLE), *quiet], run=False)
    assert paper.trainer.gradient_clip_val is None
    assert stable.trainer.gradient_clip_val == 1.0 and stable.trainer.gradient_clip_algorithm == "norm"
    a, b = paper.config.as_dict(), stable.config.as_dict()
    a["trainer"].pop("gradient_clip_val"), a["trainer"].pop("gradient_clip_algorithm")
    b["trainer"].pop("gradient_clip_val"), b["trainer"].pop("gradient_clip_algorithm")
    a.pop("config"), b.pop("config")
    assert a == b  # the same model, optimiser (SGD lr 0.05), schedule and data
    assert b["model"]["optimizer"]["init_args"]["lr"] == 0.05


def _metrics(path: Path, train: list[float], val: dict[int, float]) -> Path:
    """A Lightning CSV log: a train loss per step, a validation loss and F1 after some steps."""
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["epoch", "lr-SGD", "step", "train/loss", "val/loss", "val/tusimple_f1"])
        for step, loss in enumerate(train):
            writer.writerow(["", 0.05, step, "", "", ""])
            writer.writerow([0, "", step, loss, "", ""])
            if step + 1 in val:
                writer.writerow([0, "", step, "", val[step + 1], 0.5])
    return path


def test_a_diverging_run_is_told_from_one_whose_loss_falls(tmp_path: Path):
    falling = paper_learns.curve_rows(
        "a", paper_learns.read_metrics(_metrics(tmp_path / "a.csv", [8, 6, 5, 4, 3], {5: 4.0}))
    )
    assert [r["step"] for r in falling if r["train_loss"] is not None] == [1, 2, 3, 4, 5]
    assert [(r["step"], r["val_loss"], r["val_f1"]) for r in falling if r["val_loss"] is not None] == [(5, 4.0, 0.5)]
    summary = paper_learns.summarise(falling)
    assert not summary["diverged"] and summary["train_loss_first_fifth"] == 8 and summary["train_loss_last_fifth"] == 3
    blown = paper_learns.read_metrics(_metrics(tmp_path / "b.csv", [4, 35, 427, 9, 3211], {}))
    assert paper_learns.summarise(paper_learns.curve_rows("b", blown))["diverged"]
    val_blown = paper_learns.read_metrics(_metrics(tmp_path / "c.csv", [8, 6, 5, 4, 3], {2: 9.8e5}))
    assert paper_learns.summarise(paper_learns.curve_rows("c", val_blown))["diverged"]
    nan = paper_learns.read_metrics(_metrics(tmp_path / "d.csv", [8, float("nan"), 5], {}))
    assert paper_learns.summarise(paper_learns.curve_rows("d", nan))["diverged"]
    # written as JSON: a non-finite loss is null (JSON has no NaN or Infinity), the summary says it diverged
    rows = paper_learns.curve_rows("d", nan)
    record = {"summary": paper_learns.summarise(rows), "rows": rows}
    record = json.loads(json.dumps(paper_learns.finite(record), allow_nan=False))
    assert record["summary"]["diverged"] and [r["train_loss"] for r in record["rows"]] == [8.0, None, 5.0]


def test_the_committed_curve_record_is_strict_json():
    text = (REPO / "docs" / "results" / "paper-learns" / "paper-learns.json").read_text()

    def refuse(name: str) -> None:
        raise ValueError(f"{name} is not JSON")

    assert json.loads(text, parse_constant=refuse)["runs"]


def test_quick_mode_trains_and_writes_the_curve(tmp_path: Path, capsys: pytest.CaptureFixture):
    out = tmp_path / "out"
    argv = ["--quick", "--runs", "stable-quick", "--root", str(tmp_path / "set"), "--out", str(out)]
    assert paper_learns.main(argv) == 0
    rows = list(csv.DictReader((out / "curve.csv").open()))
    assert [int(r["step"]) for r in rows if r["train_loss"]] == [1, 2, 3, 4]
    assert [int(r["step"]) for r in rows if r["val_f1"]] == [2, 4]
    summary = json.loads((out / "paper-learns.json").read_text())
    run = summary["runs"]["stable-quick"]
    assert run["overlays"] == ["configs/common/stable_sgd.yaml"] and run["image_size"] == [64, 128]
    assert "--config=" in run["command"] and not run["diverged"]
    assert (out / "curve.png").stat().st_size > 1000
    assert (tmp_path / "set" / "label_data_0313.json").is_file()  # the set in TuSimple's layout
    assert "stable-quick: 4 steps" in capsys.readouterr().out


def test_bad_arguments_are_one_line_and_status_2(capsys: pytest.CaptureFixture):
    assert paper_learns.main(["--batch", "0"]) == 2
    assert capsys.readouterr().err.count("\n") == 1
