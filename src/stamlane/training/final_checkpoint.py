"""``FinalCheckpoint``: ``last.ckpt`` holds the weights training ENDED with.

Lightning's ``ModelCheckpoint(save_last=True, every_n_train_steps=N)`` writes ``last.ckpt`` only when
one of its N-step saves fires, so a run of 1200 steps with N = 250 leaves ``last.ckpt`` at step 1000:
the demo then scored weights 200 steps old. This callback rewrites ``last.ckpt`` when ``fit`` ends
(every rank calls ``trainer.save_checkpoint``; rank 0 writes it under a temporary name and renames it:
`stamlane.safety.guard.atomic_path`), in the folder of the first
``ModelCheckpoint`` that keeps a last checkpoint, and points that callback's ``last_model_path`` at it,
so ``--ckpt_path last`` and everything that reads ``last.ckpt`` see the final model.
"""

from __future__ import annotations

from pathlib import Path

import lightning.pytorch as pl
from lightning.pytorch.callbacks import ModelCheckpoint

from stamlane.safety.guard import atomic_path

__all__ = ["FinalCheckpoint"]


class FinalCheckpoint(pl.Callback):
    """Write ``<dirpath>/last.ckpt`` at the end of ``fit`` (see the module docstring)."""

    def on_train_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        keeper = next(
            (cb for cb in trainer.checkpoint_callbacks if isinstance(cb, ModelCheckpoint) and cb.save_last),
            None,
        )
        if keeper is None or keeper.dirpath is None or trainer.sanity_checking:
            return
        path = Path(keeper.dirpath) / f"{keeper.CHECKPOINT_NAME_LAST}{keeper.FILE_EXTENSION}"
        with atomic_path(path) as tmp:  # renamed when written: a kill mid-write leaves the previous last.ckpt whole
            trainer.save_checkpoint(str(tmp))  # only rank 0 writes; the other ranks' names stay empty
        trainer.strategy.barrier("final_checkpoint")
        keeper.last_model_path = str(path)
