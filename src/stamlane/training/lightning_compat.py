"""The places where stamlane reaches into Lightning's private parts, kept in this one module.

Each has no public equivalent; ``tests/training/test_lightning_compat.py`` fails when Lightning changes one of them, and
``pyproject.toml`` caps lightning below 3.

- `fit_data_fetcher`: exact resume (``stamlane.training.resume``) skips the batches an interrupted epoch had trained on
  by advancing the fit loop's data fetcher; no hook hands out the epoch's iterator before its first batch.
- `drop_hyperparameters`: a module built in Python from ``nn.Module`` objects must not store them (a
  ``weights_only`` checkpoint cannot hold them), while under LightningCLI the same arguments are stored as
  plain config; ``save_hyperparameters(ignore=...)`` cannot tell the two apart before the values are known.
- `plain_hyperparameters`: the same for dataclass values (a DataModule's option groups made in Python), stored as
  the plain dicts LightningCLI stores for them.
- `keep_command_line_hparams`: LightningCLI's ``_parse_ckpt_path`` re-applies a checkpoint's saved model
  hyperparameters OVER ``--config`` / ``--model.*``; `stamlane.training.lightning_cli.StamLaneCLI` replaces it with this
  no-op, so that the command line stays in charge (``--model.postprocess.*`` at predict time).
- `subcommand_parser`: the parser of one LightningCLI subcommand, whose ``dump`` writes a run's config as
  ``stamlane fit`` would read it back (the config that travels inside every checkpoint).
- `start_method`: how a DDP strategy starts its processes (the script run again per rank, or a multiprocessing
  start method): `stamlane.training.launch.spawned` tells the process that only started the ranks of
  ``ddp_spawn`` from one that trains.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, is_dataclass
from typing import Any

__all__ = [
    "CKPT_HPARAMS_METHOD",
    "drop_hyperparameters",
    "fit_data_fetcher",
    "keep_command_line_hparams",
    "plain_hyperparameters",
    "start_method",
    "subcommand_parser",
]

CKPT_HPARAMS_METHOD = "_parse_ckpt_path"
"""LightningCLI's method that merges a checkpoint's hyperparameters into the parsed config."""


def fit_data_fetcher(trainer: Any) -> Any:
    """The fit loop's data fetcher (created by ``FitLoop.setup_data``; None before), whose ``iterator`` is the
    epoch's batch iterator."""
    return trainer.fit_loop._data_fetcher


def drop_hyperparameters(module: Any, keys: Iterable[str]) -> None:
    """Remove ``keys`` from what ``module.save_hyperparameters()`` stored (current and initial copies)."""
    for key in list(keys):
        del module._hparams[key]
        module._hparams_initial.pop(key, None)


def plain_hyperparameters(module: Any) -> None:
    """Store every dataclass value of what ``module.save_hyperparameters()`` stored as a dict (current and initial
    copies): a ``weights_only`` checkpoint cannot hold a dataclass, and the loggers write plain values."""
    for hparams in (module._hparams, getattr(module, "_hparams_initial", {})):
        for key, value in hparams.items():
            if is_dataclass(value) and not isinstance(value, type):
                hparams[key] = asdict(value)


def keep_command_line_hparams(cli: Any) -> None:
    """Replacement of LightningCLI's ``_parse_ckpt_path``: the config built from ``--config`` and the command
    line is used as it is (``stamlane predict|validate|test --ckpt_path X`` without ``--config`` do not come here:
    they open the checkpoint as a stored model, `stamlane.training.stored_cli`)."""


def subcommand_parser(cli: Any, subcommand: str) -> Any:
    """The jsonargparse parser of ``subcommand`` of a LightningCLI (``cli._parser``)."""
    return cli._parser(subcommand)


def start_method(strategy: Any) -> str:
    """How ``strategy`` starts its processes: ``"popen"`` (the script run again for each rank, DDP's default) or a
    multiprocessing start method (``"spawn"``, ``"fork"``, ``"forkserver"``: ``ddp_spawn`` and its kin); a strategy
    of one process, which records none, ``"popen"``."""
    return str(getattr(strategy, "_start_method", "popen"))
