"""`RunLogger`: the CSV logger of stamlane's configs, its folder the trainer's ``default_root_dir`` unless given.

Lightning's own loggers need a ``save_dir``; Lightning's default logger (``trainer.logger: true``) writes under the
trainer's ``default_root_dir``. A `RunLogger` without a ``save_dir`` does the same, so that one value says where a
run goes: ``stamlane fit --config configs/demo.yaml --trainer.default_root_dir DIR`` writes the logs, the config and
the checkpoints under ``DIR/stam4/version_N``, and a ``--trainer.logger.save_dir`` given is kept as given. The CLI
sets it (`stamlane.training.lightning_cli.StamLaneCLI`), on the parsed values, before the trainer is made.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from lightning.pytorch.loggers import CSVLogger

from stamlane.types import nameable

__all__ = ["RunLogger", "each_logger", "logs_under_root"]


@nameable
class RunLogger(CSVLogger):
    """`lightning.pytorch.loggers.CSVLogger` whose ``save_dir`` may be left out (None): the trainer's
    ``default_root_dir`` (`logs_under_root`), the working folder when the logger is made on its own."""

    def __init__(
        self,
        save_dir: str | Path | None = None,
        name: str | None = "lightning_logs",
        version: int | str | None = None,
        prefix: str = "",
        flush_logs_every_n_steps: int = 100,
    ) -> None:
        root = "." if save_dir is None else save_dir
        super().__init__(root, name, version, prefix, flush_logs_every_n_steps)


def each_logger(logger: Any) -> list[Any]:
    """The entries of a ``trainer.logger`` option: a list of loggers as it is, one logger as a list of one; a
    boolean or None (Lightning's default logger, or none) holds no entry to change."""
    if isinstance(logger, list):
        return logger
    return [] if logger is None or isinstance(logger, bool) else [logger]


def logs_under_root(trainer: Mapping[str, Any] | None) -> None:
    """Give each `RunLogger` of a parsed ``trainer`` section (a jsonargparse Namespace, changed in place) without a
    ``save_dir`` the section's ``default_root_dir`` (``.`` without one, Lightning's working folder)."""
    if trainer is None:
        return
    for one in each_logger(trainer.get("logger")):
        init = getattr(one, "init_args", None)
        if str(getattr(one, "class_path", "")).endswith(f".{RunLogger.__name__}") and init is not None:
            if init.get("save_dir") is None:
                init["save_dir"] = str(trainer.get("default_root_dir") or ".")
