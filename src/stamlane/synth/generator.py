"""The generator's names as ``stamlane.synth.generator`` offered them before it was split by job.

Each lives in one module now; this one only gathers them, for code written against the old path:

- `stamlane.synth.layout`: the splits, files, format version and key frames of a set (standard library only);
- `stamlane.synth.config`: `SynthConfig`, the challenging factors and reveal kinds (no OpenCV);
- `stamlane.synth.clip`: `generate_clip`, what draws a clip, and `SynthClip`;
- `stamlane.synth.statistics`: `clip_statistics`, `key_frame_visibility`;
- `stamlane.synth.writer`: `write_clip`; `stamlane.synth.dataset`: `generate_dataset`.

Importing it loads the renderer (OpenCV); ``stamlane.synth.layout`` and ``config`` do not.
"""

from __future__ import annotations

from stamlane.synth.clip import FAR_M, HAZE_PX, SynthClip, generate_clip
from stamlane.synth.config import (
    FACTORS,
    REVEAL,
    REVEAL_MOTION,
    REVEAL_TRAFFIC,
    TRAIN_MOTION,
    Factor,
    SynthConfig,
    challenging_factor,
    clip_kinds,
)
from stamlane.synth.dataset import generate_dataset, write_temporal_labels
from stamlane.synth.layout import (
    DEFAULT_SYNTHETIC_ROOT,
    DEMO_SPLITS,
    EVAL_KEY_STEP,
    FIRST_KEY,
    FORMAT_VERSION,
    KIND_SPLITS,
    REVEAL_FRAMES,
    SPLITS,
    TEMPORAL_CLIPS_PER_FACTOR,
    TEMPORAL_LABELS,
    TRAIN_KEY_STEP,
    VISIBILITY_DIR,
    SplitCounts,
    key_frames,
)
from stamlane.synth.statistics import clip_statistics, key_frame_visibility
from stamlane.synth.writer import write_clip

__all__ = [
    "DEFAULT_SYNTHETIC_ROOT",
    "DEMO_SPLITS",
    "EVAL_KEY_STEP",
    "FACTORS",
    "FAR_M",
    "FIRST_KEY",
    "FORMAT_VERSION",
    "HAZE_PX",
    "KIND_SPLITS",
    "REVEAL",
    "REVEAL_FRAMES",
    "REVEAL_MOTION",
    "REVEAL_TRAFFIC",
    "SPLITS",
    "TEMPORAL_CLIPS_PER_FACTOR",
    "TEMPORAL_LABELS",
    "TRAIN_KEY_STEP",
    "TRAIN_MOTION",
    "VISIBILITY_DIR",
    "Factor",
    "SplitCounts",
    "SynthClip",
    "SynthConfig",
    "challenging_factor",
    "clip_kinds",
    "clip_statistics",
    "generate_clip",
    "generate_dataset",
    "key_frame_visibility",
    "key_frames",
    "write_clip",
    "write_temporal_labels",
]
