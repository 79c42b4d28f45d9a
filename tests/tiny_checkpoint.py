"""A tiny checkpoint as `stamlane fit` writes it, for the tests of the commands that read one (the contract, the
fuzzing): what a command checks in its record before it builds anything."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import torch

TINY_HPARAMS = {
    "encoder": {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": 0.125}},
    "fusion": {"class_path": "stamlane.models.STAM", "init_args": {"mode": "mixed", "reduction": 4}},
    "decoder": {"class_path": "stamlane.models.LaneDecoder", "init_args": {"embed_dim": 4}},
    "num_frames": 2,
    "image_size": [32, 64],
    "_instantiator": "lightning.pytorch.cli.instantiate_module",
}
"""The hyper-parameters of the network: width 1/8, STAM, 2 frames at 32x64."""


def save_tiny_checkpoint(path: Path, num_frames: int = 2, image_size: Sequence[int] = (32, 64)) -> Path:
    """Write the `TINY_HPARAMS` network (untrained weights, seed 0) to ``path`` with a record (hyper-parameters and
    data options) of ``num_frames`` frames of ``image_size`` ``(H, W)``; returns ``path``."""
    import lightning
    from lightning.pytorch.cli import instantiate_module

    from stamlane.training.module import StamLaneModule

    torch.manual_seed(0)
    module = instantiate_module(StamLaneModule, {k: v for k, v in TINY_HPARAMS.items() if k != "_instantiator"})
    record = {"num_frames": num_frames, "image_size": list(image_size)}
    torch.save(
        {
            "state_dict": module.state_dict(),
            "hyper_parameters": TINY_HPARAMS | record,
            "datamodule_hyper_parameters": record,
            "pytorch-lightning_version": lightning.__version__,
        },
        path,
    )
    return path
