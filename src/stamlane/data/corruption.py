"""Training-time corruption of the KEY frame alone, history intact: a reason for the fusion to read the history.

On clean clips the key frame alone shows every lane, so nothing in training rewards a multi-frame network for
looking at its history frames, and it learns not to (a network trained that way scores the same with its
history replaced by copies of the key frame). `KeyFrameCorruption` spoils part of the key frame of some training
clips while the (aligned) history frames keep the paint, and the targets stay those of the undamaged frame, as
labels run through vehicles and glare on real benchmarks: where the key frame lost the paint, only the history
can tell where the lane is.

Kinds, one drawn per corrupted clip:

- ``"drop"``: 1-3 rectangles (20-50 % of the width, 25-70 % of the height) replaced by the frame's mean colour;
- ``"glare"``: the frame overexposed (gain 1.8-2.6 plus an offset, clipped) under a bright veil, as the
  challenging split's glare factor;
- ``"occluder"``: 2-5 opaque dark ellipses (10-30 % of the width), as vehicles or windscreen dirt;
- ``"blank"``: every row below a random 20-60 % of the height replaced by the frame's mean colour (the near road,
  where every lane is: the key frame alone cannot be solved there).

A single-frame network trained on the same data sees the same corruption (it is then plain augmentation), so
models compared at equal data stay comparable.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["CORRUPTIONS", "DEFAULT_KINDS", "KeyFrameCorruption"]

CORRUPTIONS = ("drop", "glare", "occluder", "blank")
DEFAULT_KINDS = ("drop", "glare", "occluder")


@dataclass(frozen=True)
class KeyFrameCorruption:
    """Corrupt the key frame of a clip with probability ``prob``.

    Args:
        prob: chance that a clip's key frame is corrupted, in [0, 1].
        kinds: the kinds drawn from (`CORRUPTIONS`), uniformly; default `DEFAULT_KINDS`.
    """

    prob: float = 0.5
    kinds: tuple[str, ...] = DEFAULT_KINDS

    def __post_init__(self) -> None:
        if not 0.0 <= self.prob <= 1.0:
            raise ValueError(f"key corruption prob must be in [0, 1], got {self.prob}")
        unknown = [k for k in self.kinds if k not in CORRUPTIONS]
        if unknown or not self.kinds:
            raise ValueError(f"key corruption kinds must be some of {CORRUPTIONS}, got {self.kinds}")

    def __call__(self, clip: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Corrupt the key frame in place (or not).

        Args:
            clip: (T, 3, H, W) float32 RGB in [0, 1], key frame last (the network input).
            rng: the sample's random generator.

        Returns:
            ``clip`` (the same array).
        """
        if clip.ndim != 4 or clip.shape[1] != 3:
            raise ValueError(f"expected a clip of shape (T, 3, H, W), got {clip.shape}")
        if self.prob == 0 or rng.random() >= self.prob:
            return clip
        kind = self.kinds[int(rng.integers(len(self.kinds)))]
        key = np.ascontiguousarray(clip[-1].transpose(1, 2, 0))  # (H, W, 3)
        h, w = key.shape[:2]
        if kind == "drop":
            mean = key.reshape(-1, 3).mean(axis=0)
            for _ in range(int(rng.integers(1, 4))):
                rw, rh = int(rng.uniform(0.2, 0.5) * w), int(rng.uniform(0.25, 0.7) * h)
                x0, y0 = int(rng.integers(0, w - rw + 1)), int(rng.integers(0, h - rh + 1))
                key[y0 : y0 + rh, x0 : x0 + rw] = mean
        elif kind == "blank":
            key[int(rng.uniform(0.2, 0.6) * h) :] = key.reshape(-1, 3).mean(axis=0)
        elif kind == "glare":
            key = key * float(rng.uniform(1.8, 2.6)) + float(rng.uniform(0.08, 0.2))
            cx, cy = rng.uniform(0.2, 0.8) * w, rng.uniform(0.0, 0.5) * h
            yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
            radius = float(rng.uniform(0.3, 0.6) * w)
            veil = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * radius**2)) * float(rng.uniform(0.5, 0.9))
            key = key * (1 - veil[..., None]) + veil[..., None]
        else:
            for _ in range(int(rng.integers(2, 6))):
                axes = (int(rng.uniform(0.05, 0.15) * w), int(rng.uniform(0.05, 0.2) * h))
                centre = (int(rng.integers(0, w)), int(rng.integers(h // 4, h)))
                colour = tuple(float(c) for c in rng.uniform(0.05, 0.35, 3))
                cv2.ellipse(key, (centre, axes, float(rng.uniform(0, 180))), colour, -1)
        clip[-1] = np.clip(key, 0.0, 1.0).transpose(2, 0, 1)
        return clip
