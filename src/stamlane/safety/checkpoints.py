"""Reading checkpoints safely: weights only, only known classes, one-line errors.

A checkpoint is data, and data must not run code. ``torch.load(weights_only=True)`` never unpickles code, but
Lightning's ``load_from_checkpoint`` then BUILDS the network from the hyperparameters stored in the file:
their ``class_path`` entries (and ``_instantiator``) name Python objects that get imported and called. A
crafted checkpoint could name any module. So the network is never built that way: `stamlane.training.registry` looks
every name up in a closed table, by exact name, and builds from it (this module imports nothing of stamlane's).

Every problem — a missing, empty, truncated or text file, a file without weights, a foreign class, another
network's weights — is a `CheckpointError` (a ``ValueError``) naming the file and the problem in one line;
the command-line tools print it and exit with status 2.
"""

from __future__ import annotations

import pickle
import struct
import zipfile
from pathlib import Path
from typing import Any

import torch

__all__ = ["INSTANTIATOR", "CheckpointError", "read_checkpoint"]

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
        raise CheckpointError(
            f"checkpoint {path} does not exist: give the path of a trained run's checkpoint (RUN/checkpoints/last.ckpt)"
        )
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
