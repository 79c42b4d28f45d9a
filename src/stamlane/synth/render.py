"""Sampling the ground of a synthetic frame like a camera does: filtered far away, sharp near the car.

A single ``cv2.warpPerspective`` of the top-down road texture point-samples it: far away one image row
spans metres of road and the asphalt aliases into noise that changes from frame to frame, while near the
camera one texel of the texture covers several pixels and the road looks blurry. Both are unlike a camera
and both hurt feature matching (the paper's pre-alignment). ``GroundRenderer`` fixes both:

* **along-road prefiltering** (an anisotropic mip map, a "rip map"): the texture is also kept averaged over
  2, 4, 8 ... texels along the road (its rows), and each image row is sampled from the level that matches
  how much road it spans (blending two levels); across the road the footprint stays below ~2 texels
  within 60 m, so the lateral resolution (lane marks) is kept;
* **asphalt grain**: a ground-anchored, high-resolution grain texture (1.6 cm texels, two octaves) modulates
  the brightness where one pixel covers only a few centimetres of road (the nearest ~15 m), faded out
  before it would alias.

Both only change how the ground's brightness is sampled, never where the ground is: every frame's
``image_from_ground`` homography stays exact.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["GrainLayer", "GroundRenderer"]

GRAIN_PPM = 64.0
"""Texels per metre of the grain texture (1.6 cm)."""
GRAIN_TILE = (1024, 1024)
"""Grain texture size ``(H, W)`` in texels (16 m by 16 m); it repeats, turned by a random angle."""


class GrainLayer:
    """Ground-anchored asphalt grain: two octaves (fine aggregate, coarser mottling) of brightness modulation.

    Args:
        rng: random generator (the layer is a deterministic function of its state).
        strength: relative brightness amplitude (standard deviation of the fine octave).
    """

    def __init__(self, rng: np.random.Generator, strength: float = 0.12) -> None:
        h, w = GRAIN_TILE
        fine: np.ndarray = cv2.GaussianBlur(rng.standard_normal((h, w), dtype=np.float32), (0, 0), 0.7)
        stones = rng.random((h, w), dtype=np.float32)
        fine += np.where(stones < 0.02, 2.5, 0.0).astype(np.float32) - np.where(stones > 0.985, 2.5, 0.0).astype(
            np.float32
        )
        fine *= strength / max(float(fine.std()), 1e-6)
        coarse: np.ndarray = cv2.GaussianBlur(rng.standard_normal((h, w), dtype=np.float32), (0, 0), 3.0)
        coarse *= strength / max(float(coarse.std()), 1e-6)
        self.tile = cv2.merge([fine, coarse])
        angle = float(rng.uniform(0, 2 * np.pi))
        c, s = np.cos(angle) * GRAIN_PPM, np.sin(angle) * GRAIN_PPM
        self.tile_from_ground = np.array(
            [[c, -s, float(rng.uniform(0, w))], [s, c, float(rng.uniform(0, h))], [0, 0, 1]]
        )

    def weights(self, footprint_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-row weights of the fine and coarse octaves for a ground footprint per pixel (metres)."""
        fine = np.clip((0.045 - footprint_m) / (0.045 - 0.02), 0.0, 1.0)
        coarse = np.clip((0.16 - footprint_m) / (0.16 - 0.06), 0.0, 1.0)
        return fine.astype(np.float32), coarse.astype(np.float32)


class GroundRenderer:
    """Renders frames of a top-down ground texture with along-road prefiltering and optional grain.

    Args:
        texture: BGR uint8 ``(h, w, 3)`` top-down texture; rows run along the road.
        tex_from_ground: ``(3, 3)`` affine map ground ``(X, Z, 1)`` metres -> texture pixels.
        grain: asphalt grain layer, or None.
        levels: number of along-road averaging levels (level ``k`` averages ``2**k`` texture rows).
    """

    def __init__(
        self, texture: np.ndarray, tex_from_ground: np.ndarray, grain: GrainLayer | None = None, levels: int = 7
    ) -> None:
        self.levels = [texture]
        for _ in range(1, levels):
            prev = self.levels[-1]
            if prev.shape[0] < 4:
                break
            self.levels.append(cv2.resize(prev, (prev.shape[1], prev.shape[0] // 2), interpolation=cv2.INTER_AREA))
        self.tex_from_ground = np.asarray(tex_from_ground, np.float64)
        self.grain = grain

    def _level_from_tex(self, k: int) -> np.ndarray:
        """Level ``k`` pixels from level-0 texture pixels (pixel centres at integers)."""
        if k == 0:
            return np.eye(3)
        sy = self.levels[k].shape[0] / self.levels[0].shape[0]
        return np.array([[1.0, 0, 0], [0, sy, 0.5 * sy - 0.5], [0, 0, 1.0]])

    def render(
        self, image_from_ground: np.ndarray, size: tuple[int, int], first_row: int, border: tuple[float, ...]
    ) -> np.ndarray:
        """One frame of the ground.

        Args:
            image_from_ground: ``(3, 3)`` homography ground ``(X, Z, 1)`` metres -> image pixels.
            size: ``(H, W)`` of the frame.
            first_row: first image row below the horizon (rows above are left at ``border``).
            border: BGR colour where there is no texture (beyond its ends).

        Returns:
            BGR uint8 ``(H, W, 3)``.
        """
        height, width = size
        out = np.empty((height, width, 3), np.float32)
        out[:] = np.asarray(border, np.float32)
        first_row = int(np.clip(first_row, 0, height))
        if first_row >= height:
            return out.astype(np.uint8)
        img_from_tex = image_from_ground @ np.linalg.inv(self.tex_from_ground)
        tex_from_img = np.linalg.inv(img_from_tex)
        rows = np.arange(first_row, height, dtype=np.float64)
        cx = (width - 1) / 2.0

        def tex_at(u: np.ndarray | float, v: np.ndarray) -> np.ndarray:
            p = np.stack([np.broadcast_to(u, v.shape), v, np.ones_like(v)], axis=1) @ tex_from_img.T
            uv: np.ndarray = p[:, :2] / p[:, 2:3]
            return uv

        here = tex_at(cx, rows)
        along = np.abs(tex_at(cx, rows + 1.0)[:, 1] - here[:, 1])  # texture rows spanned by one image row
        across = np.linalg.norm(tex_at(cx + 1.0, rows) - here, axis=1)
        level = np.clip(np.log2(np.maximum(along, 1.0)), 0.0, len(self.levels) - 1.0)
        level[~np.isfinite(level)] = len(self.levels) - 1.0
        acc = np.zeros((height - first_row, width, 3), np.float32)
        last = len(self.levels) - 1
        for k in range(len(self.levels)):
            # triangle weights over the (fractional) level; they sum to 1 in every row
            weight = np.clip(1.0 - np.abs(level - k), 0.0, 1.0)
            if k == 0:
                weight[level <= 0] = 1.0
            if k == last:
                weight[level >= last] = 1.0
            band = np.flatnonzero(weight > 0)
            if len(band) == 0:
                continue
            r0, r1 = int(band[0]), int(band[-1]) + 1
            shift = np.array([[1.0, 0, 0], [0, 1.0, -(first_row + r0)], [0, 0, 1.0]])
            warp = shift @ img_from_tex @ np.linalg.inv(self._level_from_tex(k))
            part = cv2.warpPerspective(
                self.levels[k],
                warp,
                (width, r1 - r0),
                flags=cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=border,
            )
            acc[r0:r1] += part.astype(np.float32) * weight[r0:r1, None, None].astype(np.float32)
        if self.grain is not None:
            footprint = np.maximum(along, across) / float(self.tex_from_ground[0, 0])  # metres per pixel
            fine_w, coarse_w = self.grain.weights(footprint)
            band = np.flatnonzero((fine_w > 0) | (coarse_w > 0))
            if len(band):
                r0, r1 = int(band[0]), int(band[-1]) + 1
                shift = np.array([[1.0, 0, 0], [0, 1.0, -(first_row + r0)], [0, 0, 1.0]])
                warp = shift @ image_from_ground @ np.linalg.inv(self.grain.tile_from_ground)
                g = cv2.warpPerspective(
                    self.grain.tile, warp, (width, r1 - r0), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP
                )
                mod = 1.0 + g[..., 0] * fine_w[r0:r1, None] + g[..., 1] * coarse_w[r0:r1, None]
                acc[r0:r1] *= mod[..., None]
        out[first_row:] = acc
        return np.clip(out, 0, 255).astype(np.uint8)
