"""Which processes a command runs in: under a cluster launcher, and the ranks ``ddp_spawn`` starts.

A stored model is scored and predicted in one process unless asked (`stamlane.training.stored_predict.
prediction_trainer_options`: one process is its default, ``--trainer.devices`` and the like replace it), except under
a launcher that starts the processes itself (`launched_by_cluster`). A ``--config`` gives its own trainer: its
processes are the config's.
"""

from __future__ import annotations

import os
from typing import Any

import torch

__all__ = ["launched_by_cluster", "spawned"]


def launched_by_cluster() -> bool:
    """True under a launcher that starts the processes itself: ``torchrun`` (torchelastic) or SLURM's ``srun`` with
    more than one task (Lightning then takes its processes from the launcher, and one device would not match)."""
    if torch.distributed.is_available() and torch.distributed.is_torchelastic_launched():
        return True
    return int(os.environ.get("SLURM_NTASKS", "1") or 1) > 1 and os.environ.get("SLURM_JOB_NAME") not in (
        "bash",
        "interactive",
    )


def spawned(trainer: Any) -> bool:
    """True in the process that started the ranks of ``ddp_spawn`` (``start_method`` spawn, fork, forkserver): it
    trains nothing itself, and its trainer does not hold the ranks' step count nor their checkpoints' paths."""
    from stamlane.training.lightning_compat import start_method

    method = start_method(trainer.strategy)
    return trainer.world_size > 1 and method != "popen" and not torch.distributed.is_initialized()
