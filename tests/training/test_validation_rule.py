"""Every shipped config chooses its best checkpoint by a number the machine cannot change: validation scores
without lane.py's 200 ms rule (the test stage keeps it and logs how many images it hit)."""

from __future__ import annotations

from pathlib import Path

import pytest
from lightning.pytorch.callbacks import ModelCheckpoint
from stamlane_eval.integrations.lightning import LaneEvalCallback

from stamlane.training.lightning_cli import StamLaneCLI

REPO = Path(__file__).resolve().parents[2]
CONFIGS = sorted((REPO / "configs").glob("*.yaml"))
TIMED = ("val/tusimple_late",)  # counts of images over 200 ms: the machine's


@pytest.mark.usefixtures("plain_argv")
@pytest.mark.parametrize("config", CONFIGS, ids=[c.stem for c in CONFIGS])
def test_the_best_checkpoint_does_not_depend_on_the_machine(config: Path) -> None:
    cli = StamLaneCLI(args=["--config", str(config), "--model.encoder.width=0.0625"], run=False)
    scorer = next(cb for cb in cli.trainer.callbacks if isinstance(cb, LaneEvalCallback))
    monitors = [cb.monitor for cb in cli.trainer.callbacks if isinstance(cb, ModelCheckpoint) and cb.monitor]
    assert monitors, "no best checkpoint chosen"
    for monitor in monitors:
        assert monitor.startswith("val/") and monitor not in TIMED, monitor
    if scorer.use_tusimple:  # the 200 ms rule in the test stage only (as the benchmark), never in validation
        assert scorer.tusimple_time_limit == "test", (config.name, scorer.tusimple_time_limit)
