"""Weights shipped with stamlane: trained models a user can run right after the install, loaded by name.

``stamlane predict --ckpt_path stam4-synthetic --source my.mp4`` (and ``validate``, ``test``, ``export
--ckpt_path``, ``stream --ckpt``) takes a name of `SHIPPED` where it takes a checkpoint file; ``stamlane predict
--source VIDEO`` with neither ``--ckpt_path`` nor ``--config`` runs `DEFAULT`. The files are ordinary stamlane
checkpoints without optimiser state (`stamlane.training.release`), read like any other: through the closed
registry, with ``weights_only=True``. What they were trained on and what they score: docs/models.md.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

__all__ = ["DEFAULT", "SHIPPED", "ShippedModel", "resolve", "shipped_path"]


@dataclass(frozen=True)
class ShippedModel:
    """A model shipped with the package.

    Attributes:
        name: what ``--ckpt_path`` takes.
        file: its file in this package.
        sha256: the file's SHA-256 (checked by the tests: the card's numbers are those of these bytes).
        summary: one line for ``stamlane --help``.
    """

    name: str
    file: str
    sha256: str
    summary: str


SHIPPED = (
    ShippedModel(
        "stam4-synthetic",
        "stam4-synthetic.ckpt",
        "51c2eda055a392a6fe289ff2a8e0560d4b70473d2ff836b1fb4894275a847a64",
        "the demo's 4-frame pre-aligned STAM model (synthetic clips, seed 0, float32)",
    ),
    ShippedModel(
        "single-synthetic",
        "single-synthetic.ckpt",
        "0ce20c1eac25ddbae25770e70a0233700fe5dd0528037d0932a5c06152be89f0",
        "the demo's single-frame baseline (the same recipe, seed 0, float32)",
    ),
    ShippedModel(
        "single-dashcam",
        "single-dashcam.ckpt",
        "43802b415ec40200970cdef757a76d04db15bcc7d7d3fb7fbe89aa7067ff75bd",
        "single-synthetic fine-tuned for real roads (dashcam3 world, TuSimple's labels and rows; seed 0, bfloat16)",
    ),
    ShippedModel(
        "stam4-dashcam",
        "stam4-dashcam.ckpt",
        "703c7db6a89220029b80e9cff1706ab90291f373ea1f3355493d175de65d8273",
        "the 4-frame STAM model for real roads: single-dashcam's STAM trained on 4-frame clips of its data, the rest "
        "nearly frozen (seed 0, bfloat16)",
    ),
)
"""The models shipped, in the order ``stamlane --help`` lists them (docs/models.md has their cards)."""
DEFAULT = "stam4-dashcam"
"""What ``stamlane predict --source VIDEO`` runs when given no checkpoint and no config: a user's own video is a real
road, and the 4-frame model fine-tuned for real roads draws its lines where the synthetic-only models draw extra,
crossing ones (docs/models.md)."""


def shipped_path(name: str) -> Path:
    """The file of the shipped model ``name``.

    Raises:
        KeyError: ``name`` is not a shipped model (the message lists them).
    """
    for model in SHIPPED:
        if model.name == name:
            return Path(str(files(__name__) / model.file))
    raise KeyError(f"no shipped model {name!r}; shipped: {', '.join(m.name for m in SHIPPED)}")


def resolve(value: str) -> str:
    """What ``--ckpt_path VALUE`` means: a shipped model's file where ``VALUE`` is one's name and no file or folder
    of that name exists here (a file of yours always wins), else ``VALUE`` unchanged. Never raises: a name too long
    for the file system is no file here (``os.path.exists``, not ``Path.exists``, which raises on Python 3.11)."""
    if any(value == m.name for m in SHIPPED) and not os.path.exists(value):
        return str(shipped_path(value))
    return value
