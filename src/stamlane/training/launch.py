"""How many processes ``stamlane validate|test|predict`` runs: one, unless asked.

A checkpoint carries the trainer of the run that wrote it (``--ckpt_path`` alone reads the run's config from it):
a run trained on 8 GPUs would be validated on 8 again, with Lightning's warning to use one device. Scores are the
same either way (each image is scored once, in the split's order: docs/distributed.md), but one process is what a
score or a prediction of a stored model needs; several are asked for on the command line (``--trainer.devices``,
``--trainer.strategy``, ``--trainer.num_nodes``) or by launching under ``torchrun`` or SLURM's ``srun``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import torch

__all__ = ["PROCESS_FLAGS", "launched_by_cluster", "one_process_unless_asked", "spawned"]

PROCESS_FLAGS = ("--trainer.devices", "--trainer.strategy", "--trainer.num_nodes")
"""Command-line options that ask ``validate``, ``test`` or ``predict`` for the trainer's processes as given."""
_EVALUATING = ("validate", "test", "predict")


def launched_by_cluster() -> bool:
    """True under a launcher that starts the processes itself: ``torchrun`` (torchelastic) or SLURM's ``srun`` with
    more than one task (Lightning then takes its processes from the launcher, and one device would not match)."""
    if torch.distributed.is_available() and torch.distributed.is_torchelastic_launched():
        return True
    return int(os.environ.get("SLURM_NTASKS", "1") or 1) > 1 and os.environ.get("SLURM_JOB_NAME") not in (
        "bash",
        "interactive",
    )


def one_process_unless_asked(subcommand: str | None, trainer: Any, given: Sequence[str]) -> bool:
    """Set the trainer section of ``validate``, ``test`` or ``predict`` to one process (``devices: 1``, ``num_nodes:
    1``, ``strategy: auto``) unless the command line names one of `PROCESS_FLAGS` or a cluster launcher started it.

    Args:
        subcommand: the LightningCLI subcommand.
        trainer: the parsed ``trainer`` section (a jsonargparse Namespace), changed in place.
        given: the command-line arguments.

    Returns:
        whether the section was changed.
    """
    if subcommand not in _EVALUATING or trainer is None:
        return False
    flags = {arg.split("=", 1)[0] for arg in given if arg.startswith("--")}
    if flags & set(PROCESS_FLAGS) or launched_by_cluster():
        return False
    trainer["devices"], trainer["num_nodes"], trainer["strategy"] = 1, 1, "auto"
    return True


def spawned(trainer: Any) -> bool:
    """True in the process that started the ranks of ``ddp_spawn`` (``start_method`` spawn, fork, forkserver): it
    trains nothing itself, and its trainer does not hold the ranks' step count nor their checkpoints' paths."""
    from stamlane.training.lightning_compat import start_method

    method = start_method(trainer.strategy)
    return trainer.world_size > 1 and method != "popen" and not torch.distributed.is_initialized()
