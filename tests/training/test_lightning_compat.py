"""The private Lightning parts stamlane uses (``stamlane.training.lightning_compat``) are still there and still behave as
relied on: these tests fail when a Lightning release changes them."""

from __future__ import annotations

import inspect
import io

import lightning.pytorch as pl
import torch
from lightning.pytorch.cli import LightningCLI
from lightning.pytorch.demos.boring_classes import BoringModel

from stamlane.models import STAM, LaneDecoder, VGGEncoder
from stamlane.training.lightning_cli import StamLaneCLI
from stamlane.training.lightning_compat import (
    CKPT_HPARAMS_METHOD,
    drop_hyperparameters,
    fit_data_fetcher,
    keep_command_line_hparams,
    start_method,
)
from stamlane.training.module import StamLaneModule


def test_lightning_cli_still_merges_checkpoint_hparams_in_the_method_we_replace() -> None:
    assert f"self.{CKPT_HPARAMS_METHOD}()" in inspect.getsource(LightningCLI.__init__)
    merged = inspect.getsource(getattr(LightningCLI, CKPT_HPARAMS_METHOD))
    assert "hyper_parameters" in merged and "parse_object" in merged  # what would override the command line
    assert getattr(StamLaneCLI, CKPT_HPARAMS_METHOD) is keep_command_line_hparams


def test_the_fit_loop_data_fetcher_holds_the_epoch_iterator(tmp_path) -> None:
    seen = []

    class Look(pl.Callback):
        def on_train_epoch_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
            seen.append(fit_data_fetcher(trainer))

    trainer = pl.Trainer(
        max_steps=2,
        limit_val_batches=0,
        logger=False,
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        callbacks=[Look()],
        default_root_dir=tmp_path,
    )
    trainer.fit(BoringModel())
    assert seen and seen[0] is not None and hasattr(seen[0], "iterator")


def test_hyperparameters_of_built_objects_can_be_dropped() -> None:
    module = StamLaneModule(VGGEncoder(width=0.125), STAM, LaneDecoder, num_frames=2)
    assert "encoder" not in module.hparams and "encoder" not in module.hparams_initial  # an nn.Module: dropped
    assert module.hparams["num_frames"] == 2
    drop_hyperparameters(module, ["num_frames"])
    assert "num_frames" not in module.hparams and "num_frames" not in module.hparams_initial
    buffer = io.BytesIO()
    torch.save({"hyper_parameters": dict(module.hparams)}, buffer)
    buffer.seek(0)
    assert torch.load(buffer, weights_only=True)["hyper_parameters"] == dict(module.hparams)  # plain values only


def test_a_subcommand_has_a_parser_that_dumps_its_config(tmp_path) -> None:
    """`subcommand_parser` reaches LightningCLI's ``_parser``: the config that travels in a checkpoint is the parser's
    dump."""
    from stamlane.training.lightning_compat import subcommand_parser

    runs = []

    class Counting(LightningCLI):
        def before_validate(self) -> None:
            runs.append("validate")

    common = ["--trainer.logger=false", "--trainer.enable_progress_bar=false", "--trainer.limit_val_batches=1"]
    cli = Counting(BoringModel, args=["validate", f"--trainer.default_root_dir={tmp_path}", *common])
    assert runs == ["validate"]
    dumped = subcommand_parser(cli, "validate").dump(cli.config["validate"], skip_none=False)
    assert "limit_val_batches: 1" in dumped and "default_root_dir" in dumped


def test_a_strategy_says_how_it_starts_its_processes() -> None:
    """DDP's ``_start_method``: ``popen`` by default, the multiprocessing method of ``ddp_spawn``; a one-process
    strategy records none."""
    from lightning.pytorch.strategies import DDPStrategy, SingleDeviceStrategy

    assert start_method(DDPStrategy()) == "popen"
    assert start_method(DDPStrategy(start_method="spawn")) == "spawn"
    assert start_method(SingleDeviceStrategy(torch.device("cpu"))) == "popen"
    assert not hasattr(SingleDeviceStrategy(torch.device("cpu")), "_start_method")  # the default is ours, not read
