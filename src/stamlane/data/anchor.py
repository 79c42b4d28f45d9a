"""Labelled synthetic clips that hold a model to what it learnt while it adapts to unlabelled real video.

`stamlane adapt` (`stamlane.training.adapt`) fine-tunes a model on pseudo-labels of a user's video; every batch also
holds clips of the generator with their exact labels, so that the model does not forget the road it was trained
on (the issue's bound: the synthetic test split must not drop by more than 2 points). `anchor_clips` writes a small
set of the world the shipped dashcam models were trained on (``dashcam3``, lanes labelled by TuSimple's convention,
``label_lanes="adjacent"``) and reads it as the model reads its clips.
"""

from __future__ import annotations

from pathlib import Path

from stamlane.data.layouts import TuSimpleClips
from stamlane.data.options import ClipOptions
from stamlane.synth.config import SynthConfig
from stamlane.synth.dataset import generate_dataset
from stamlane.synth.layout import SplitCounts

__all__ = ["ANCHOR_WORLD", "anchor_clips", "read_anchor"]

ANCHOR_WORLD = SynthConfig(world="dashcam3", label_lanes="adjacent")
"""The generator's settings of the anchor clips: the shipped dashcam models' training world (docs/models.md)."""


def anchor_clips(root: str | Path, clip: ClipOptions, clips: int, seed: int = 0) -> TuSimpleClips:
    """Write ``clips`` train clips of `ANCHOR_WORLD` into ``root`` and read them with ``clip``'s options.

    Args:
        root: an empty (or missing) folder, written here.
        clip: the model's clip options (its frames, size, crop and alignment).
        clips: train clips to write (13 labelled key frames each).
        seed: the set's master seed (clip ``i`` depends only on it and ``i``).

    Returns:
        the clips' labelled key frames, read as the model's training read its clips (no augmentation).
    """
    if clips < 1:
        raise ValueError(f"anchor clips must be >= 1, got {clips}")
    generate_dataset(root, SplitCounts(train=clips), seed=seed, config=ANCHOR_WORLD, progress=False, visibility=False)
    return read_anchor(root, clip)


def read_anchor(root: str | Path, clip: ClipOptions, labels: str = "train.json") -> TuSimpleClips:
    """An existing synthetic set's labelled key frames (``root/labels``), read with ``clip``'s options."""
    return TuSimpleClips(root, labels, clip=clip)
