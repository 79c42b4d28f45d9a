"""Transient occluders of the LAST frames of a clip: what only the history can see past (the ``reveal`` splits).

Vehicles, shadows and worn paint hide the same road in every frame of a short span, so a model of four frames
at 20 fps has little to find in its history (docs/results.md). A `KeyOccluder` spoils the key frame alone (and,
with ``frames=2``, the frame before it), while the history frames stay clean: the paint it hides is visible in
every aligned history frame, so perfect use of the history recovers it and the key frame alone cannot.

Kinds (`KEY_OCCLUDERS`, the values of ``SynthConfig.key_occluder``), each drawn once per clip (the same pixels in
every occluded frame):

- ``"spray"``: an opaque textured band over the near road, the full width (spray thrown up by a truck ahead);
  never seen in training in this appearance;
- ``"blobs"``: 3-6 opaque textured ellipses (10-20 % of the width) centred on the mid and near parts of the lane
  marks, one mark after the other (mud or leaves on the lens); never seen in training in this appearance;
- ``"flash"``: the frame overexposed under a bright veil, as the training glare corruption
  (`stamlane.data.corruption`): the in-distribution positive control.

Training sees transient occluders of other appearances only: the CPU recipe's key-frame corruption (the near road
in one flat colour, overexposure; `stamlane.data.corruption`) on clips with the same ego motion
(``train_motion`` clips of `stamlane.synth.dataset.generate_dataset`).

The opaque kinds return a mask (255 where the road is hidden), which the generator adds to the frame's
occluder mask; ``flash`` hides nothing opaquely (its effect on the paint is measured by the paint contrast,
`stamlane.synth.visibility`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stamlane.synth.config import KEY_OCCLUDERS

__all__ = ["KEY_OCCLUDERS", "KeyOccluder"]


def _noise(rng: np.random.Generator, height: int, width: int) -> np.ndarray:
    """Smooth multi-scale noise in [-1, 1], (H, W) float32: the texture of spray and mud."""
    total = np.zeros((height, width), np.float32)
    for cells, weight in ((4, 0.5), (16, 0.3), (64, 0.2)):
        grid = rng.standard_normal((max(2, height * cells // width), cells)).astype(np.float32)
        total += weight * cv2.resize(grid, (width, height), interpolation=cv2.INTER_CUBIC)
    noise: np.ndarray = np.clip(total / 1.5, -1.0, 1.0)
    return noise


@dataclass(frozen=True)
class KeyOccluder:
    """One clip's transient occluder (see the module docstring).

    Attributes:
        kind: one of `KEY_OCCLUDERS`.
        colour: (H, W, 3) uint8 BGR of an opaque occluder; None for ``flash``.
        mask: (H, W) uint8, 255 where the occluder hides the road; None for ``flash``.
        gain, offset, veil: ``flash``: the frame becomes ``frame * gain + offset`` (grey levels) and then
            ``* (1 - veil) + 255 * veil`` with ``veil`` (H, W) float32 in [0, 1].
    """

    kind: str
    colour: np.ndarray | None = None
    mask: np.ndarray | None = None
    gain: float = 1.0
    offset: float = 0.0
    veil: np.ndarray | None = None

    @classmethod
    def sample(
        cls, kind: str, rng: np.random.Generator, size: tuple[int, int], horizon: float, marks: list[np.ndarray]
    ) -> KeyOccluder:
        """Draw one occluder of ``kind`` for frames of ``size`` (H, W).

        Args:
            kind: one of `KEY_OCCLUDERS`.
            rng: the clip's generator (every draw of the occluder comes from it, once per clip).
            size: ``(H, W)`` of the frames.
            horizon: the key frame's horizon row (pixels).
            marks: the key frame's lane marks as (N, 2) pixel points ``(x, y)`` (blobs sit on them).
        """
        if kind not in KEY_OCCLUDERS:
            raise ValueError(f"key occluder must be one of {KEY_OCCLUDERS}, got {kind!r}")
        h, w = size
        ground = max(h - horizon, 1.0)
        if kind == "flash":  # as stamlane.data.corruption's glare, in grey levels
            gain, offset = float(rng.uniform(1.8, 2.6)), float(rng.uniform(0.08, 0.2) * 255)
            cx, cy = rng.uniform(0.2, 0.8) * w, rng.uniform(0.0, 0.5) * h
            yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
            radius = float(rng.uniform(0.3, 0.6) * w)
            veil = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * radius**2)) * float(rng.uniform(0.5, 0.9))
            return cls(kind, gain=gain, offset=offset, veil=veil.astype(np.float32))
        mask = np.zeros((h, w), np.uint8)
        if kind == "spray":
            top = horizon + float(rng.uniform(0.25, 0.5)) * ground
            depth = float(rng.uniform(0.3, 0.5)) * ground
            edge = 0.04 * ground * _noise(rng, 1, w)[0]  # ragged upper and lower edges
            rows = np.arange(h, dtype=np.float32)[:, None]
            mask[(rows >= top + edge[None, :]) & (rows <= top + depth - edge[None, :])] = 255
        else:
            near = [m[m[:, 1] >= horizon + 0.3 * ground] for m in marks if len(m)]  # the marks' mid and near parts
            near = [m for m in near if len(m)]
            for k in range(int(rng.integers(3, 7))):
                if near:  # lane after lane, so that the blobs spread over the marks
                    mark = near[k % len(near)]
                    cx, cy = mark[int(rng.integers(len(mark)))]
                else:
                    cx, cy = rng.uniform(0.2, 0.8) * w, horizon + rng.uniform(0.3, 0.9) * ground
                size = (int(rng.uniform(0.10, 0.20) * w), int(rng.uniform(0.08, 0.16) * h))  # the box's full sides
                cv2.ellipse(mask, ((int(cx), int(cy)), size, float(rng.uniform(0, 180))), 255, -1)
        base = rng.uniform(70, 170, 3) if kind == "spray" else rng.uniform(20, 110, 3)  # grey-brown; dark, any hue
        texture = _noise(rng, h, w)[..., None] * float(rng.uniform(25, 45))
        grain = rng.standard_normal((h, w, 1)).astype(np.float32) * 6
        colour = np.clip(base.astype(np.float32) + texture + grain, 0, 255).astype(np.uint8)
        return cls(kind, colour=colour, mask=mask)

    def apply(self, frame: np.ndarray) -> np.ndarray:
        """The frame with the occluder, BGR uint8 (H, W, 3) -> the same shape (a new array)."""
        if self.kind == "flash":
            assert self.veil is not None
            bright = np.clip(frame.astype(np.float32) * self.gain + self.offset, 0, 255)
            veil = self.veil[..., None]
            flashed: np.ndarray = np.clip(bright * (1 - veil) + 255.0 * veil, 0, 255).astype(np.uint8)
            return flashed
        assert self.colour is not None and self.mask is not None
        return np.where(self.mask[..., None] > 0, self.colour, frame)
