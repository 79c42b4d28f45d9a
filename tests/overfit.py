"""A tiny network overfitting a few synthetic clips in seconds: what the learning tests share."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path

import torch
from lightning.pytorch import Callback, Trainer, seed_everything

from stamlane.data.datamodule import ClipDataModule
from stamlane.data.options import AugmentOptions, ClipOptions, LoaderOptions
from stamlane.models import STAM, LaneDecoder, VGGEncoder
from stamlane.predict.postprocess import PostprocessConfig
from stamlane.training.module import PolyLR, StamLaneModule

SIZE = (64, 128)  # network input (H, W)
NO_AUGMENTATION = AugmentOptions(crop_scale=(1.0, 1.0), flip_prob=0.0, brightness=0.0, contrast=0.0, saturation=0.0)


def tiny_module(num_frames: int, postprocess: PostprocessConfig | None = None) -> StamLaneModule:
    """Width 1/8, mixed C-S STAM in the history-carrying reading, AdamW 5e-3, fp32; initialised from seed 0."""
    seed_everything(0)
    return StamLaneModule(
        VGGEncoder(width=0.125),
        functools.partial(STAM, mode="mixed", order="cs", reduction=4, reading="features"),
        LaneDecoder,
        optimizer=functools.partial(torch.optim.AdamW, lr=5e-3, weight_decay=1e-4),
        scheduler=PolyLR,
        postprocess=postprocess or PostprocessConfig(min_cluster_pixels=10, min_samples=10),
        num_frames=num_frames,
        image_size=SIZE,
        bf16=False,
        report_run_time=False,
    )


def tiny_data(root: Path, num_frames: int) -> ClipDataModule:
    """The set's train clips, exactly aligned, without augmentation; their key frames are the validation set."""
    return ClipDataModule(
        root=str(root),
        clip=ClipOptions(num_frames=num_frames, image_size=SIZE, align="true"),
        augment=NO_AUGMENTATION,
        loader=LoaderOptions(batch_size=2),
        val_labels=["train.json"],
    )


def overfit(
    module: StamLaneModule, data: ClipDataModule, steps: int, root_dir: Path, callbacks: Sequence[Callback]
) -> dict[str, float]:
    """Train ``steps`` steps in one thread, validate once at the end; the logged metrics."""
    trainer = Trainer(
        max_steps=steps,
        val_check_interval=steps,
        check_val_every_n_epoch=None,
        num_sanity_val_steps=0,
        logger=False,
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        callbacks=list(callbacks),
        default_root_dir=root_dir,
    )
    threads = torch.get_num_threads()
    # one thread, whatever ran before in this process (`stamlane demo` in-process sets two): the sums' order, and so
    # the weights after a few hundred steps of AdamW, depend on it, and the tests' thresholds were set on one
    torch.set_num_threads(1)
    try:
        trainer.fit(module, datamodule=data)
    finally:
        torch.set_num_threads(threads)
    return {k: float(v) for k, v in trainer.callback_metrics.items()}
