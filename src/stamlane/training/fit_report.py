"""``FitReport``: one line per validation while fitting, and the true best score of a run continued with
``--ckpt_path``.

A resumed fit logs and checkpoints into a new version folder, so Lightning's ``ModelCheckpoint`` restores only
the path of the best checkpoint, not its score (it warns "The dirpath has changed"): the resumed run then kept a
worse "best" checkpoint of its own and ``stamlane fit`` closed with "best val/tusimple_f1 nan". `FitReport` reads
the best score and path from the monitoring ``ModelCheckpoint``'s state in the checkpoint resumed from, gives them
back to that callback (a later checkpoint is kept as the best only when it beats them; Lightning never deletes a
file outside the callback's own folder) and keeps the best of both runs for the closing line.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import lightning.pytorch as pl
import torch
from lightning.pytorch.callbacks import ModelCheckpoint

__all__ = ["DEFAULT_MONITOR", "Best", "FitReport", "step_of"]

DEFAULT_MONITOR = "val/tusimple_f1"
"""The score reported when no ``ModelCheckpoint`` monitors one (higher is better)."""


def step_of(path: str) -> int | None:
    """The step in a checkpoint name such as ``best-step=1199.ckpt`` (None when it has none)."""
    match = re.search(r"step=(\d+)", Path(path).name)
    return int(match.group(1)) if match else None


class Best:
    """The best score so far: ``score``, the ``step`` it was reached at and its checkpoint ``path`` ("" if none)."""

    def __init__(self, score: float, step: int | None, path: str = "") -> None:
        self.score, self.step, self.path = score, step, path


def _keeper(trainer: pl.Trainer) -> ModelCheckpoint | None:
    """The first ``ModelCheckpoint`` that monitors a score."""
    return next((cb for cb in trainer.checkpoint_callbacks if isinstance(cb, ModelCheckpoint) and cb.monitor), None)


def _number(value: Any) -> float | None:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


class FitReport(pl.Callback):
    """Print ``stamlane fit: step N  <monitor> X  best Y (step M)`` after every validation of a fit, and keep the
    best of the run and of the run it resumed (`best`; see the module docstring).

    Args:
        verbose: print the line per validation (the best is tracked either way).
    """

    def __init__(self, verbose: bool = True) -> None:
        self.verbose = verbose
        self.best: Best | None = None
        self.resumed: Best | None = None

    def _monitor(self, trainer: pl.Trainer) -> tuple[str, str]:
        keeper = _keeper(trainer)
        return (keeper.monitor, keeper.mode) if keeper is not None and keeper.monitor else (DEFAULT_MONITOR, "max")

    def _better(self, score: float, than: Best | None, mode: str) -> bool:
        return than is None or (score > than.score if mode == "max" else score < than.score)

    def on_load_checkpoint(
        self, trainer: pl.Trainer, pl_module: pl.LightningModule, checkpoint: dict[str, Any]
    ) -> None:
        keeper = _keeper(trainer)
        if keeper is None:
            return
        state = (checkpoint.get("callbacks") or {}).get(keeper.state_key) or {}
        score, path = _number(state.get("best_model_score")), str(state.get("best_model_path") or "")
        if score is None:
            return
        self.resumed = self.best = Best(score, step_of(path) if path else None, path)

    def on_train_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        keeper = _keeper(trainer)
        resumed = self.resumed
        if keeper is None or resumed is None or keeper.best_k_models or not Path(resumed.path).is_file():
            return
        if Path(keeper.dirpath or "").resolve() == Path(resumed.path).resolve().parent:
            return  # the same folder: Lightning restored everything itself
        value = torch.tensor(resumed.score)
        keeper.best_k_models = {resumed.path: value}
        keeper.kth_best_model_path, keeper.kth_value = resumed.path, value
        keeper.best_model_path, keeper.best_model_score = resumed.path, value

    def on_validation_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if trainer.sanity_checking or trainer.state.fn != "fit":
            return
        monitor, mode = self._monitor(trainer)
        score = _number(trainer.callback_metrics.get(monitor))
        if score is None:
            return
        step = trainer.global_step
        if self._better(score, self.best, mode):
            self.best = Best(score, step)
        if self.verbose and trainer.is_global_zero:
            best = self.best
            assert best is not None
            at = f" (step {best.step})" if best.step is not None else ""
            line = f"stamlane fit: step {step}  {monitor} {score:.4f}  best {best.score:.4f}{at}"
            bar = getattr(trainer, "progress_bar_callback", None)  # a line of its own above a progress bar
            if bar is not None:
                bar.print(line)
            else:
                print(line, flush=True)

    def best_checkpoint(self, trainer: pl.Trainer) -> Best | None:
        """The best score of the fit (the run resumed included) with its checkpoint's path, when one was kept."""
        if self.best is None:
            return None
        keeper = _keeper(trainer)
        path = self.best.path or (keeper.best_model_path if keeper is not None else "")
        return Best(self.best.score, self.best.step, path)
