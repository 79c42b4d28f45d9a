"""Make clips: the synthetic road-clip generator (``stamlane synth``), beside ``stamlane.data`` which reads clips.

One module per job:

- ``layout``: what a set looks like on disk (splits, files, format version, key frames); the standard library only;
- ``config``: `SynthConfig`, the challenging factors (`FACTORS`) and the reveal kinds; no OpenCV;
- ``clip``: `generate_clip` draws a clip: a flat road (``road``) seen by a pinhole camera (`stamlane.align.camera`)
  that drives along it, box vehicles (``vehicles``), the ground texture rendered once per clip and sampled through
  each frame's exact ground homography (``render``), the challenging factors' image effects (``effects``) and the
  reveal splits' transient occluders (``transient``);
- ``worlds``: every world (`WORLDS`), each a choice of a variant of each scene part (the standard library only);
  ``parts``: every variant of every part and the one order they draw in; ``dashcam``, ``scenery`` and ``bodies``: the
  variants of the dashcam worlds (the camera spread, marking standards, surfaces, barriers and rails, skies, sensor
  effects; the sun and its shadows, curbs, poles, surface repairs, verges, vehicles with bodies);
- ``visibility`` and ``statistics``: where the paint of a labelled point is visible, what a clip offers the history;
- ``writer``: `write_clip` stores a clip; ``dataset``: `generate_dataset` writes a whole set; ``cli``:
  ``stamlane synth``.

Needs numpy and OpenCV only (no torch, no Lightning). The names below are imported from their modules on first
use, so that ``import stamlane.synth.layout`` (what ``stamlane.data`` and ``stamlane.experiments`` read a set by)
loads neither numpy nor the renderer. ``stamlane.synth.generator`` gathers every name the generator module had
before the split.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from stamlane.synth.clip import SynthClip, generate_clip
    from stamlane.synth.config import FACTORS, Factor, SynthConfig
    from stamlane.synth.dataset import generate_dataset
    from stamlane.synth.layout import FORMAT_VERSION, SPLITS, SplitCounts, key_frames
    from stamlane.synth.writer import write_clip

__all__ = [
    "FACTORS",
    "FORMAT_VERSION",
    "SPLITS",
    "Factor",
    "SplitCounts",
    "SynthClip",
    "SynthConfig",
    "generate_clip",
    "generate_dataset",
    "key_frames",
    "write_clip",
]

_HOMES = {
    "FACTORS": "stamlane.synth.config",
    "FORMAT_VERSION": "stamlane.synth.layout",
    "SPLITS": "stamlane.synth.layout",
    "Factor": "stamlane.synth.config",
    "SplitCounts": "stamlane.synth.layout",
    "SynthClip": "stamlane.synth.clip",
    "SynthConfig": "stamlane.synth.config",
    "generate_clip": "stamlane.synth.clip",
    "generate_dataset": "stamlane.synth.dataset",
    "key_frames": "stamlane.synth.layout",
    "write_clip": "stamlane.synth.writer",
}
"""The module each exported name lives in, imported when the name is first asked for."""


def __getattr__(name: str) -> object:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
