"""The poly schedule of a resumed run follows the ``max_steps`` of the run that resumes (not the checkpoint's)."""

from __future__ import annotations

from pathlib import Path

import lightning.pytorch as pl
import pytest
import torch

from stamlane.training.lightning_cli import StamLaneCLI
from stamlane.training.module import PolyLR
from tests.training.tiny_runs import tiny_args

pytestmark = pytest.mark.usefixtures("plain_argv")


class _Rates(pl.Callback):
    """The learning rates each optimizer step is taken with, by step (1-based)."""

    def __init__(self) -> None:
        self.rates: dict[int, list[float]] = {}

    def on_train_batch_start(self, trainer: pl.Trainer, *args: object) -> None:
        self.rates[trainer.global_step + 1] = [g["lr"] for g in trainer.optimizers[0].param_groups]


def _fit(args: list[str]) -> dict[int, list[float]]:
    rates = _Rates()
    StamLaneCLI(args=["fit", *args], trainer_defaults={"callbacks": [rates]})
    return rates.rates


def test_resume_with_more_steps_follows_the_longer_schedule(tiny_set: Path, tmp_path: Path) -> None:
    torch.set_num_threads(1)
    no_val = ["--trainer.limit_val_batches=0"]
    straight = _fit(tiny_args(tiny_set, tmp_path / "nine", "--trainer.max_steps=9", *no_val))
    _fit(tiny_args(tiny_set, tmp_path / "six", "--trainer.max_steps=6", *no_val))
    last = next((tmp_path / "six").rglob("last.ckpt"))
    assert torch.load(last, weights_only=True)["global_step"] == 6
    resumed = _fit(tiny_args(tiny_set, tmp_path / "six", "--trainer.max_steps=9", f"--ckpt_path={last}", *no_val))
    assert sorted(resumed) == [7, 8, 9]
    for step in (7, 8, 9):
        assert resumed[step] == straight[step], step  # exact: the same formula at the same step
    assert all(rate > 0 for step in (7, 8, 9) for rate in resumed[step])  # was 0.0: the 6-step schedule's end


def test_poly_lr_keeps_its_own_length_on_load() -> None:
    params = [torch.nn.Parameter(torch.zeros(1))]
    short = PolyLR(torch.optim.SGD(params, lr=1.0), total_steps=4)
    for _ in range(4):
        short.optimizer.step()
        short.step()
    assert short.optimizer.param_groups[0]["lr"] == 0.0
    longer = PolyLR(torch.optim.SGD(params, lr=1.0), total_steps=8)
    longer.optimizer.load_state_dict(short.optimizer.state_dict())  # Lightning restores the optimizer first
    longer.load_state_dict(short.state_dict())
    assert longer.total_steps == 8 and longer.last_epoch == 4
    assert longer.optimizer.param_groups[0]["lr"] == pytest.approx((1 - 4 / 8) ** 0.9, abs=0)
