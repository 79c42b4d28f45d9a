"""Make clips: the synthetic road-clip generator (``stamlane synth``), beside ``stamlane.data`` which reads clips.

A flat road (``road``) seen by a pinhole camera (``camera``) that drives along it; box vehicles (``vehicles``)
drive on the road; the ground texture is rendered once per clip and sampled through each frame's exact ground
homography (``render``); the challenging factors' image effects (``effects``); clips and splits in the TuSimple
layout with the true homographies (``generator``). Needs numpy and OpenCV only (no torch, no Lightning).
"""

from __future__ import annotations

from stamlane.synth.generator import (
    FACTORS,
    FORMAT_VERSION,
    SPLITS,
    Factor,
    SynthClip,
    SynthConfig,
    generate_clip,
    generate_dataset,
    key_frames,
    write_clip,
)

__all__ = [
    "FACTORS",
    "FORMAT_VERSION",
    "SPLITS",
    "Factor",
    "SynthClip",
    "SynthConfig",
    "generate_clip",
    "generate_dataset",
    "key_frames",
    "write_clip",
]
