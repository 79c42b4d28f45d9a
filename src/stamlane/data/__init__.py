"""Read clips: datasets of the benchmark formats, targets, clip-consistent augmentation, the data options in their
groups (``stamlane.data.options``), the DataModule (the synthetic generator that makes the default set is
``stamlane.synth``).

Lightning is imported only by ``stamlane.data.datamodule`` (import ``ClipDataModule`` from there, or
from here: it is loaded on first access), so the tools ``stamlane synth`` and ``stamlane show`` start fast.
"""

from __future__ import annotations

from typing import Any

from stamlane.data.alignment import ALIGN_MODES, WARP_MODES, ClipAligner
from stamlane.data.clips import NET_HOMOGRAPHIES, ClipDataset, ClipEntry
from stamlane.data.collate import collate_clips
from stamlane.data.labels import DataError
from stamlane.data.layouts import ApolloClips, CULaneClips, TuSimpleClips, VIL100Clips
from stamlane.data.options import DEMO_SYNTH, AugmentOptions, ClipOptions, LoaderOptions, SynthOptions
from stamlane.data.targets import draw_lane_targets, left_to_right
from stamlane.data.transforms import ClipParams, ClipTransform, net_homographies

__all__ = [
    "ALIGN_MODES",
    "DEMO_SYNTH",
    "NET_HOMOGRAPHIES",
    "WARP_MODES",
    "ApolloClips",
    "AugmentOptions",
    "CULaneClips",
    "ClipAligner",
    "ClipDataModule",
    "ClipDataset",
    "ClipEntry",
    "ClipOptions",
    "ClipParams",
    "ClipTransform",
    "DataError",
    "LoaderOptions",
    "SynthOptions",
    "TuSimpleClips",
    "VIL100Clips",
    "collate_clips",
    "draw_lane_targets",
    "left_to_right",
    "net_homographies",
]


def __getattr__(name: str) -> Any:
    if name == "ClipDataModule":
        from stamlane.data.datamodule import ClipDataModule

        return ClipDataModule
    raise AttributeError(f"module 'stamlane.data' has no attribute {name!r}")
