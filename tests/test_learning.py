"""Learning itself: a tiny network overfits two synthetic clips, and ``last.ckpt`` is the final model.

These fail when learning breaks (a loss, target, optimiser or decoding bug that still leaves every loss
finite), and when the checkpoint that the demo, ``stamlane predict`` and the docs use is not the weights
training ended with.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from lightning.pytorch import Trainer, seed_everything
from lightning.pytorch.callbacks import ModelCheckpoint
from stamlane_eval.integrations.lightning import LaneEvalCallback

from stamlane.training.final_checkpoint import FinalCheckpoint
from tests.overfit import overfit, tiny_data, tiny_module

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def two_clips(tiny_synthetic) -> Path:
    """Two 4-frame training clips at 256x144 (their key frames are also the validation set)."""
    return tiny_synthetic(256, 144, 4, train=2, val=0, test=0, challenging=0, seed=5)


@pytest.mark.parametrize("num_frames", [1, 2])
def test_a_tiny_network_overfits_two_clips(two_clips: Path, tmp_path: Path, num_frames: int) -> None:
    found = overfit(
        tiny_module(num_frames),
        tiny_data(two_clips, num_frames),
        STEPS,
        tmp_path,
        [LaneEvalCallback(tusimple=True, culane=False)],
    )
    f1 = found["val/tusimple_f1"]
    assert f1 >= 0.9, f"{num_frames}-frame model reached TuSimple F1 {f1:.3f} on its own training clips"


def test_last_checkpoint_holds_the_final_weights(two_clips: Path, tmp_path: Path) -> None:
    """A 7-step run with 4-step periodic checkpoints: Lightning alone leaves last.ckpt at step 4."""
    seed_everything(0)
    module = tiny_module(1)
    periodic = ModelCheckpoint(dirpath=tmp_path / "ckpt", every_n_train_steps=4, save_last=True)
    trainer = Trainer(
        max_steps=7,
        limit_val_batches=0,
        logger=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        callbacks=[periodic, FinalCheckpoint()],
        default_root_dir=tmp_path,
    )
    trainer.fit(module, datamodule=tiny_data(two_clips, 1))
    last = tmp_path / "ckpt" / "last.ckpt"
    assert periodic.last_model_path == str(last)
    assert not [p for p in (tmp_path / "ckpt").iterdir() if ".tmp" in p.name]  # written beside, then renamed
    ckpt = torch.load(last, map_location="cpu", weights_only=True)
    assert ckpt["global_step"] == 7
    final = module.state_dict()
    assert ckpt["state_dict"].keys() == final.keys()
    for name, value in final.items():
        torch.testing.assert_close(ckpt["state_dict"][name], value, rtol=0, atol=0, msg=name)


def test_the_cli_adds_the_final_checkpoint() -> None:
    from stamlane.training.lightning_cli import StamLaneCLI

    cli = StamLaneCLI(args=["--config", str(Path(__file__).parents[1] / "configs" / "demo.yaml")], run=False)
    assert any(isinstance(cb, FinalCheckpoint) for cb in cli.trainer.callbacks)


STEPS = 150
"""Steps of the overfitting runs: both models reach F1 1.0 (about 10 s each on one core); with the learning rate
set to 0 they stay at 0."""
