"""Reading checkpoints safely: weights only, only known classes, one-line errors.

A checkpoint is data, and data must not run code. ``torch.load(weights_only=True)`` never unpickles code, but
Lightning's ``load_from_checkpoint`` then BUILDS the network from the hyperparameters stored in the file:
their ``class_path`` entries (and ``_instantiator``) name Python objects that get imported and called. A
crafted checkpoint could name any module. `check_classes` checks every name against `ALLOWED_CLASSES`
(stamlane's own classes and torch's optimisers and schedulers) before anything is built:
`stamlane.module.StamLaneModule.from_checkpoint` does it (this module imports nothing of stamlane's).

Every problem — a missing, empty, truncated or text file, a file without weights, a foreign class, another
network's weights — is a `CheckpointError` (a ``ValueError``) naming the file and the problem in one line;
the command-line tools print it and exit with status 2.
"""

from __future__ import annotations

import pickle
import re
import struct
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import torch

__all__ = [
    "ALLOWED_CLASSES",
    "CONFIG_ALLOWED_CLASSES",
    "INSTANTIATOR",
    "CheckpointError",
    "check_classes",
    "check_config",
    "read_checkpoint",
]

ALLOWED_CLASSES = ("stamlane.", "torch.optim.")
"""Prefixes of the ``class_path`` names a checkpoint may ask to build (``torch.optim.lr_scheduler`` included)."""
CONFIG_ALLOWED_CLASSES = (*ALLOWED_CLASSES, "lightning.pytorch.callbacks.", "lightning.pytorch.loggers.")
"""What a run's config found in a checkpoint or a results folder may name: the network's classes and Lightning's
callbacks and loggers (what ``stamlane fit`` configs use). A config the USER gives with ``--config`` is code,
like a script, and may name any class of the user's; one read from a file the user only points at is data."""
_DOTTED = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)+")
INSTANTIATOR = "lightning.pytorch.cli.instantiate_module"
"""The only ``_instantiator`` accepted: what LightningCLI writes into the checkpoints of ``stamlane fit``."""


_UNREADABLE = (
    RuntimeError,
    EOFError,
    OSError,
    pickle.UnpicklingError,
    zipfile.BadZipFile,
    ValueError,
    KeyError,
    IndexError,
    TypeError,
    AttributeError,
    struct.error,
)
"""What ``torch.load`` raises on bytes that are no checkpoint (empty, text, truncated, a legacy pickle gone wrong)."""


class CheckpointError(ValueError):
    """A checkpoint that cannot be used; the message names the file and the problem, in one line."""


def read_checkpoint(path: str | Path) -> dict[str, Any]:
    """The checkpoint's content, loaded with ``weights_only=True``.

    Raises:
        CheckpointError: missing, unreadable, not a torch checkpoint (empty, truncated, text), not a dict, or
            without a ``state_dict``.
    """
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist")
    try:
        content = torch.load(path, map_location="cpu", weights_only=True)
    except _UNREADABLE as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise CheckpointError(
            f"checkpoint {path} is not a readable torch checkpoint (empty, truncated or another kind of file): "
            f"{first[:200]}"
        ) from None
    if not isinstance(content, dict) or not isinstance(content.get("state_dict"), dict):
        raise CheckpointError(f"checkpoint {path} holds no state_dict (not a Lightning checkpoint of stamlane)")
    return content


def _class_paths(value: Any) -> Iterator[str]:
    if isinstance(value, dict):
        if isinstance(value.get("class_path"), str):
            yield value["class_path"]
        for item in value.values():
            yield from _class_paths(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _class_paths(item)


def check_classes(hparams: dict[str, Any], source: str | Path) -> None:
    """Refuse hyperparameters that would import anything but `ALLOWED_CLASSES` (and `INSTANTIATOR`).

    Raises:
        CheckpointError: naming the first foreign name.
    """
    instantiator = hparams.get("_instantiator")
    if instantiator is not None and instantiator != INSTANTIATOR:
        raise CheckpointError(f"checkpoint {source} asks for instantiator {instantiator!r}; only {INSTANTIATOR!r}")
    for name in _class_paths(hparams):
        if not name.startswith(ALLOWED_CLASSES) or ".." in name:
            raise CheckpointError(
                f"checkpoint {source} asks to build {name!r}; only stamlane's classes and torch.optim may be built"
            )


_IMPORT_KEYS = frozenset(
    {"encoder", "fusion", "decoder", "loss", "optimizer", "scheduler", "callbacks", "logger", "plugins", "profiler"}
)
"""Config keys whose string values jsonargparse imports (a class or a callable named by its dotted path)."""


def _import_names(value: Any) -> Iterator[str]:
    """Every name in a config that jsonargparse would import: ``class_path`` values, and dotted strings given
    where a class or a callable is expected (``optimizer: torch.optim.SGD``, ``callbacks: [pkg.Callback]``)."""
    if isinstance(value, dict):
        for key, item in value.items():
            names = item if isinstance(item, list) else [item]
            if key == "class_path" or key in _IMPORT_KEYS:
                yield from (n for n in names if isinstance(n, str) and _DOTTED.fullmatch(n))
            yield from _import_names(item)
    elif isinstance(value, list):
        for item in value:
            yield from _import_names(item)


def check_config(text: str, source: str | Path) -> None:
    """Refuse a run config, read from a checkpoint or a results folder, that would import anything but
    `CONFIG_ALLOWED_CLASSES`: every ``class_path``, and every dotted name where a class or a callable is expected
    (``optimizer: os.system`` would be imported as a callable), is checked before the config is parsed.

    Raises:
        CheckpointError: not YAML, or naming the first foreign name.
    """
    import yaml

    try:
        config = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise CheckpointError(f"the config of {source} is not YAML: {str(err).splitlines()[0]}") from None
    for name in _import_names(config):
        if not name.startswith(CONFIG_ALLOWED_CLASSES) or ".." in name:
            raise CheckpointError(
                f"the config of {source} names {name!r}; a config read from a checkpoint or a run folder may name "
                f"only stamlane's classes, torch.optim and Lightning's callbacks and loggers (give your own config "
                f"with --config to use other classes)"
            )
