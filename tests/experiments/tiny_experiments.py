"""The tiny runs of the experiment tests: the overrides that shrink a recipe's runs to seconds."""

from __future__ import annotations

SHRINK = (
    "--data.clip.image_size=[32, 64]",
    "--data.loader.batch_size=2",
    "--data.loader.num_workers=0",
    "--data.clip.align=true",
    "--model.encoder.width=0.125",
    "--model.channels_last=false",
)
"""Overrides of every run of an experiment test: 32x64 clips aligned before training, width 1/8, 2 clips a batch."""
