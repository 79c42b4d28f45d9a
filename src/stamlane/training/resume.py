"""Exact resume: a run continued with ``--ckpt_path`` draws the same batches as the uninterrupted run.

Lightning restores weights, optimizer, scheduler and loop counters, but not what decides the data: the
global random states (the shuffling sampler and the per-clip augmentation draw from torch's global
generator; DataLoader workers are seeded from it) and, after a mid-epoch checkpoint, the position inside
the epoch (a plain DataLoader restarts from its first batch). `ExactResume` saves, in every checkpoint,
the random states as they were when the epoch's data iterator was created (before any draw of that
epoch) and, on resume, restores them before the iterator is re-created and then skips the batches the
interrupted run had already trained on (they are loaded again, so skipping costs data-loading time).
Everything it stores is tensors and plain values (the checkpoint stays loadable with ``weights_only``).
"""

from __future__ import annotations

import random
from typing import Any

import lightning.pytorch as pl
import numpy as np
import torch

from stamlane.training.lightning_compat import fit_data_fetcher

__all__ = ["ExactResume", "get_rng_states", "set_rng_states"]


def get_rng_states() -> dict[str, Any]:
    """Global random states of torch, numpy and ``random``, as tensors and plain values."""
    legacy = np.random.get_state()  # noqa: NPY002 (the global state is the point)
    assert isinstance(legacy, tuple)  # legacy=True (the default): the 5-tuple, never the dict
    kind, keys, pos, has_gauss, cached = legacy
    version, state, gauss = random.getstate()
    return {
        "torch": torch.get_rng_state(),
        "numpy": [str(kind), torch.from_numpy(keys.astype(np.int64)), int(pos), int(has_gauss), float(cached)],
        "python": [int(version), list(state), gauss],
    }


def set_rng_states(states: dict[str, Any]) -> None:
    """Restore what `get_rng_states` returned."""
    torch.set_rng_state(states["torch"])
    kind, keys, pos, has_gauss, cached = states["numpy"]
    np.random.set_state((kind, keys.numpy().astype(np.uint32), pos, has_gauss, cached))  # noqa: NPY002
    version, state, gauss = states["python"]
    random.setstate((version, tuple(state), gauss))


class ExactResume(pl.Callback):
    """Make ``--ckpt_path`` resume draw the same data as an uninterrupted run (see the module docstring).

    The random states after each training batch are restored after validation, so validation never
    shifts the training draws (the interrupted run validated where the resumed one may not). Works with map-style
    datasets (the DataLoader has a length, so Lightning does not prefetch) and with step-triggered
    checkpoints (``ModelCheckpoint(every_n_train_steps=...)``, mid-epoch or at an epoch's last batch);
    Lightning's own epoch-end checkpoints (``save_on_train_epoch_end``) resume into a shortened epoch.
    """

    def __init__(self) -> None:
        self._epoch_states: dict[str, Any] | None = None
        self._batches_in_epoch = 0
        self._epoch_length: int | None = None
        self._skip = 0
        self._after_batch: dict[str, Any] | None = None
        self._resumed = False

    @property
    def state_key(self) -> str:
        return "ExactResume"

    def on_fit_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        # the first epoch's iterator is created after this hook (FitLoop.setup_data); later epochs' right
        # after on_train_epoch_start
        if self._epoch_states is None:
            self._epoch_states = get_rng_states()

    def on_train_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self._epoch_length = _finite(trainer.num_training_batches)
        skip, self._skip = self._skip, 0
        resumed, self._resumed = self._resumed, False
        fetcher = fit_data_fetcher(trainer)  # created by FitLoop.setup_data, nothing fetched yet
        if not resumed or fetcher is None or fetcher.iterator is None:
            return
        for _ in range(skip):  # the batches the interrupted run had trained on in this epoch
            next(fetcher.iterator)
        # Lightning may draw (e.g. re-creating a validation iterator) before the next fetch; undo that then
        fetcher.iterator = _RestoreOnFirstNext(fetcher.iterator, get_rng_states())

    def on_train_epoch_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self._batches_in_epoch = 0
        self._epoch_length = _finite(trainer.num_training_batches)
        if trainer.current_epoch > 0:
            self._epoch_states = get_rng_states()

    def on_train_batch_end(self, trainer: pl.Trainer, *args: Any) -> None:
        self._batches_in_epoch += 1  # runs before ModelCheckpoint's hook (Lightning orders those last)
        self._after_batch = get_rng_states()  # what training goes on from, whether validation runs or not

    def on_validation_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        # validation (its DataLoader iterator draws a seed) must not shift the training draws
        if trainer.state.fn == "fit" and not trainer.sanity_checking and self._after_batch is not None:
            set_rng_states(self._after_batch)

    def state_dict(self) -> dict[str, Any]:
        return {
            "epoch_rng_states": self._epoch_states,
            "rng_states": self._after_batch if self._after_batch is not None else get_rng_states(),
            "batches_in_epoch": self._batches_in_epoch,
            "epoch_length": self._epoch_length,
        }

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        done, length = state_dict.get("batches_in_epoch", 0), state_dict.get("epoch_length")
        self._resumed = True
        if length is not None and done >= length:  # saved after the epoch's last batch: go on from there
            set_rng_states(state_dict["rng_states"])
            return
        if state_dict.get("epoch_rng_states") is not None:  # mid-epoch: replay the epoch's draws
            set_rng_states(state_dict["epoch_rng_states"])
            self._epoch_states = state_dict["epoch_rng_states"]
            self._batches_in_epoch = self._skip = int(done)


class _RestoreOnFirstNext:
    """Wraps an iterator; sets the random states once, right before the first item is drawn."""

    def __init__(self, iterator: Any, states: dict[str, Any]) -> None:
        self.iterator = iterator
        self.states: dict[str, Any] | None = states

    def __iter__(self) -> _RestoreOnFirstNext:
        return self

    def __next__(self) -> Any:
        if self.states is not None:
            set_rng_states(self.states)
            self.states = None
        return next(self.iterator)


def _finite(value: float | int) -> int | None:
    return int(value) if value != float("inf") else None
