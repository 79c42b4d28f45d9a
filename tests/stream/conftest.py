"""Checkpoints as `stamlane fit` writes them, for the export and streaming tests."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
import torch

POSTPROCESS = {"prob_thresh": 0.4, "cluster_thresh": 0.8, "eps": 0.5, "min_samples": 12, "y_step": 5, "extend": True}
"""Decoding settings other than the defaults, so that a test sees they travel."""

HPARAMS = {
    "encoder": {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": 0.125}},
    "fusion": {"class_path": "stamlane.models.STAM", "init_args": {"mode": "mixed", "reduction": 4}},
    "decoder": {"class_path": "stamlane.models.LaneDecoder", "init_args": {"embed_dim": 3}},
    "num_frames": 3,
    "image_size": [64, 128],
    "crop_top": 0.25,
    "postprocess": POSTPROCESS,
    "_instantiator": "lightning.pytorch.cli.instantiate_module",
}
"""A tiny network: T = 3, 64x128 input, the top quarter of each frame cut."""

CLIP = {"num_frames": 3, "image_size": [64, 128], "crop_top": 0.25, "align": "fly", "horizon_row": 40}
"""The data options of its run."""


@pytest.fixture(scope="session")
def save_checkpoint() -> Callable[..., Path]:
    """``save_checkpoint(path, hparams=HPARAMS, clip=CLIP)``: write a checkpoint (untrained weights, seed 0) with
    those hyper-parameters and, unless ``clip`` is None, those data options; returns ``path``."""

    def save(path: Path, hparams: dict = HPARAMS, clip: dict | None = CLIP) -> Path:
        import lightning
        from lightning.pytorch.cli import instantiate_module

        from stamlane.training.module import StamLaneModule

        torch.manual_seed(0)
        module = instantiate_module(StamLaneModule, {k: v for k, v in hparams.items() if k != "_instantiator"})
        content = {
            "state_dict": module.state_dict(),
            "hyper_parameters": dict(hparams),
            "pytorch-lightning_version": lightning.__version__,
        }
        if clip is not None:
            content["datamodule_hyper_parameters"] = {"clip": dict(clip), "loader": {"batch_size": 2}}
        torch.save(content, path)
        return path

    return save
