"""The Trainer of the tests that fit a module in-process: on the CPU, writing and printing nothing of its own."""

from __future__ import annotations

from lightning.pytorch import Trainer


def cpu_trainer(**options: object) -> Trainer:
    """A `Trainer` on the CPU without logger, checkpoints, progress bar, model summary or sanity validation;
    ``options`` add to or override these (``max_steps=2``, ``limit_val_batches=0``)."""
    quiet: dict[str, object] = {
        "accelerator": "cpu",
        "logger": False,
        "enable_checkpointing": False,
        "enable_progress_bar": False,
        "enable_model_summary": False,
        "num_sanity_val_steps": 0,
    }
    return Trainer(**(quiet | options))
