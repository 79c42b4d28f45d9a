"""``FitReport``: a line per validation, the best of a run and of the run it resumed."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest
import torch
from lightning.pytorch.callbacks import ModelCheckpoint

from stamlane.training.fit_report import FitReport, step_of


def _trainer(keeper: ModelCheckpoint, step: int, score: float | None) -> SimpleNamespace:
    metrics = {} if score is None else {"val/tusimple_f1": torch.tensor(score)}
    return SimpleNamespace(
        checkpoint_callbacks=[keeper],
        sanity_checking=False,
        state=SimpleNamespace(fn="fit"),
        callback_metrics=metrics,
        global_step=step,
        is_global_zero=True,
    )


def test_a_resumed_run_goes_on_from_the_best_of_the_run_it_resumed(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    old = tmp_path / "version_0" / "checkpoints" / "best-step=200.ckpt"
    old.parent.mkdir(parents=True)
    old.write_bytes(b"x")
    keeper = ModelCheckpoint(dirpath=tmp_path / "version_1" / "checkpoints", monitor="val/tusimple_f1", mode="max")
    state = {"best_model_score": torch.tensor(0.32), "best_model_path": str(old)}
    report = FitReport()
    report.on_load_checkpoint(_trainer(keeper, 300, None), None, {"callbacks": {keeper.state_key: state}})
    report.on_train_start(_trainer(keeper, 300, None), None)
    # the checkpoint callback compares new scores with the resumed best (Lightning drops it in a new folder)
    assert keeper.best_model_path == str(old) and float(keeper.best_model_score) == pytest.approx(0.32)
    assert keeper.best_k_models == {str(old): pytest.approx(torch.tensor(0.32))}

    report.on_validation_end(_trainer(keeper, 400, 0.25), None)
    assert capsys.readouterr().out == "stamlane fit: step 400  val/tusimple_f1 0.2500  best 0.3200 (step 200)\n"
    best = report.best_checkpoint(_trainer(keeper, 400, None))
    assert best is not None and (best.score, best.step, best.path) == (pytest.approx(0.32), 200, str(old))

    report.on_validation_end(_trainer(keeper, 500, 0.5), None)
    assert "best 0.5000 (step 500)" in capsys.readouterr().out


def test_no_score_no_line_and_a_missing_best_file_is_not_handed_over(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    keeper = ModelCheckpoint(dirpath=tmp_path / "v1", monitor="val/tusimple_f1", mode="max")
    report = FitReport()
    state = {"best_model_score": torch.tensor(0.3), "best_model_path": str(tmp_path / "gone" / "best-step=9.ckpt")}
    report.on_load_checkpoint(_trainer(keeper, 10, None), None, {"callbacks": {keeper.state_key: state}})
    report.on_train_start(_trainer(keeper, 10, None), None)
    assert keeper.best_k_models == {}  # a file that is gone is not a best to keep; the score is still reported
    report.on_validation_end(_trainer(keeper, 12, None), None)
    assert capsys.readouterr().out == ""
    best = report.best_checkpoint(_trainer(keeper, 12, None))
    assert best is not None and best.step == 9 and best.score == pytest.approx(0.3)
    assert step_of("best-step=1199.ckpt") == 1199 and step_of("last.ckpt") is None
