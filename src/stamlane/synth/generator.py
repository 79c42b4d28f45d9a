"""The generator's names as ``stamlane.synth.generator`` offered them before it was split by job.

Each lives in one module now; this one only offers every name of those modules (their ``__all__``), for code
written against the old path:

- `stamlane.synth.layout`: the splits, files, format version and key frames of a set (standard library only);
- `stamlane.synth.config`: `SynthConfig`, the challenging factors and reveal kinds (no OpenCV);
- `stamlane.synth.clip`: `generate_clip`, what draws a clip, and `SynthClip`;
- `stamlane.synth.statistics`: `clip_statistics`, `key_frame_visibility`;
- `stamlane.synth.writer`: `write_clip`; `stamlane.synth.dataset`: `generate_dataset`.

Importing it loads the renderer (OpenCV); ``stamlane.synth.layout`` and ``config`` do not.
"""

from __future__ import annotations

from types import ModuleType

from stamlane.synth import clip, config, dataset, layout, statistics, writer

_HOMES: tuple[ModuleType, ...] = (layout, config, clip, statistics, writer, dataset)
"""The modules the old path's names live in (each name in one of them)."""

__all__ = sorted(name for home in _HOMES for name in home.__all__)


def __getattr__(name: str) -> object:
    for home in _HOMES:
        if name in home.__all__:
            return getattr(home, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
