"""Every class a stored run may name is registered where it is defined (`stamlane.types.nameable`).

The closed registry (`stamlane.training.registry`) reads its table from those registrations: a run trained with a
class the docs tell users to add (``HistoryUseMonitor``) opens from its own checkpoint with ``validate`` and
``predict``; nothing outside the registrations may be named.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from stamlane.cli import main
from stamlane.training.registry import registry
from tests.training.tiny_runs import tiny_args

REPO = Path(__file__).resolve().parents[2]
torch.set_num_threads(1)
pytestmark = pytest.mark.usefixtures("plain_argv")

MONITOR = "stamlane.training.history_use_monitor.HistoryUseMonitor"


def test_a_run_with_the_history_monitor_opens_from_its_checkpoint(
    tiny_synthetic: Callable[..., Path], tmp_path: Path
) -> None:
    root = tiny_synthetic(256, 144, 2, train=2, val=2, test=2, challenging=0)
    run = tmp_path / "run"
    assert main(["fit", *tiny_args(root, run, "--trainer.max_steps=2", f"--trainer.callbacks+={MONITOR}")]) == 0
    last = next(run.rglob("last.ckpt"))
    assert main(["test", f"--ckpt_path={last}", f"--data.root={root}", "--trainer.logger", "false"]) == 0
    assert not (run / "config.yaml").exists()  # no logger, no log folder: no config.yaml in the trainer's root
    out = tmp_path / "predictions"
    assert main(["predict", f"--ckpt_path={last}", f"--data.root={root}", f"--predictions.output_dir={out}"]) == 0
    assert any(out.rglob("*.json"))


def _named_classes() -> set[str]:
    """Every dotted stamlane/torch/lightning class name written in a shipped config, a doc, a benchmark or a recipe."""
    texts = [
        *(REPO / "configs").rglob("*.yaml"),
        *(REPO / "docs").rglob("*.md"),
        REPO / "README.md",
        *(REPO / "benchmarks").glob("*.py"),
        *(REPO / "src" / "stamlane" / "experiments").glob("*.py"),
    ]
    pattern = re.compile(r"(?:class_path: |callbacks\+?=|class_path=)((?:stamlane|torch|lightning)(?:\.\w+)+)")
    return {name for path in texts for name in pattern.findall(path.read_text(encoding="utf-8"))}


def test_every_class_the_project_names_is_registered() -> None:
    named = _named_classes()
    assert MONITOR in named and "stamlane.models.STAM" in named  # the scan sees both kinds of place
    assert sorted(named - set(registry())) == []


def test_registered_names_are_exact() -> None:
    table = registry()
    from stamlane.models import STAM
    from stamlane.training.history_use_monitor import HistoryUseMonitor

    assert table["stamlane.models.STAM"] is STAM  # the package's public name
    assert table["stamlane.models.stam.STAM"] is STAM  # the defining module's name
    assert table[MONITOR] is HistoryUseMonitor
    assert "stamlane.training.history_use_monitor.key_copied" not in table  # a function nobody registered
    assert "stamlane.training.module.StamLaneModule" not in table  # the module is built by the CLI, never named
