"""Image-space effects of the challenging factors: a windscreen in front of the camera, glare, night.

Unlike vehicles and shadows these do not live on the road. A ``Windscreen`` is fixed to the CAMERA: dirt and
drops stay at the same pixels in every frame and the wiper sweeps across them, so after ground-plane
alignment a history frame shows the road behind them at other pixels, while an unaligned history frame shows
the occluder again at the same place. ``glare`` changes ONE frame (overexposure, a sun flare or motion blur,
drawn per frame), so the other frames of the clip are clean. ``night`` darkens EVERY frame alike (headlights
light the near road; the far road sinks into sensor noise), so the frames differ only by their noise.

Each effect draws its randomness from the clip's generator only when it is used, so clips without it are
the same as before it existed.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["NightLight", "Windscreen", "glare", "night"]


@dataclass
class Windscreen:
    """Dirt and drops on the windscreen and a sweeping wiper, in image pixels.

    Attributes:
        size: ``(H, W)`` of the frames.
        dirt: ``(cx, cy, rx, ry, angle_deg, opacity)`` of each opaque-ish dirt blob.
        drops: ``(cx, cy, radius)`` of each drop (the scene seen blurred and brightened through it).
        pivot: the wiper's pivot ``(x, y)``, below the image; ``length``: its blade length in pixels.
        sweep: ``(angle0, angle1)`` degrees between which the wiper sweeps (0 = pointing up).
        period: frames per full sweep (there and back); ``phase``: the sweep's phase at frame 0, in [0, 1).
    """

    size: tuple[int, int]
    dirt: list[tuple[float, float, float, float, float, float]]
    drops: list[tuple[float, float, float]]
    pivot: tuple[float, float]
    length: float
    sweep: tuple[float, float]
    period: float
    phase: float

    @classmethod
    def sample(cls, rng: np.random.Generator, width: int, height: int) -> Windscreen:
        """Draw 2-5 dirt blobs on the lower two thirds, 10-30 drops and a wiper sweeping every 12-24 frames."""
        s = width / 640.0
        dirt = [
            (
                float(rng.uniform(0.1, 0.9) * width),
                float(rng.uniform(0.45, 0.95) * height),
                float(rng.uniform(15, 45) * s),
                float(rng.uniform(8, 25) * s),
                float(rng.uniform(0, 180)),
                float(rng.uniform(0.75, 0.95)),
            )
            for _ in range(int(rng.integers(2, 6)))
        ]
        drops = [
            (float(rng.uniform(0, width)), float(rng.uniform(0.3, 1.0) * height), float(rng.uniform(3, 9) * s))
            for _ in range(int(rng.integers(10, 31)))
        ]
        left = rng.random() < 0.5
        pivot = (float((0.15 if left else 0.85) * width), float(height * 1.15))
        sweep = (-75.0, 10.0) if left else (-10.0, 75.0)
        return cls(
            (height, width),
            dirt,
            drops,
            pivot,
            float(1.05 * height),
            sweep,
            float(rng.uniform(12, 24)),
            float(rng.uniform(0, 1)),
        )

    def wiper_angle(self, frame: int) -> float:
        """The wiper's angle (degrees, 0 = up) at frame ``frame``: a smooth back-and-forth sweep."""
        u = 0.5 - 0.5 * np.cos(2 * np.pi * (frame / self.period + self.phase))
        return float(self.sweep[0] + (self.sweep[1] - self.sweep[0]) * u)

    def apply(self, frame: np.ndarray, index: int) -> np.ndarray:
        """Draw the windscreen over ``frame`` (BGR uint8, (H, W, 3)) at frame ``index`` in place.

        Returns:
            the mask of the pixels that hide the road, uint8 (H, W), 255 where dirt or the wiper is (nearly)
            opaque; drops let the road through (blurred) and are not in it.
        """
        h, w = frame.shape[:2]
        if (h, w) != tuple(self.size):
            raise ValueError(f"windscreen made for (H, W) {tuple(self.size)}, got a frame of {(h, w)}")
        hidden = np.zeros((h, w), np.uint8)
        # drops: the scene through a small lens, blurred and brighter
        blurred = cv2.GaussianBlur(frame, (0, 0), 3.0)
        lens = np.zeros((h, w), np.uint8)
        for cx, cy, r in self.drops:
            cv2.circle(lens, (round(cx), round(cy)), max(1, round(r)), 255, -1, lineType=cv2.LINE_AA)
        a = (lens.astype(np.float32) / 255.0)[..., None]
        frame[:] = np.clip(frame * (1 - a) + (blurred * 1.15 + 10) * a, 0, 255).astype(np.uint8)
        # dirt: brownish-grey blobs with soft edges
        alpha = np.zeros((h, w), np.float32)
        for cx, cy, rx, ry, ang, opacity in self.dirt:
            blob = np.zeros((h, w), np.float32)
            cv2.ellipse(blob, ((cx, cy), (2 * rx, 2 * ry), ang), opacity, -1, lineType=cv2.LINE_AA)
            alpha = np.maximum(alpha, cv2.GaussianBlur(blob, (0, 0), max(1.0, 0.25 * ry)))
        # the wiper: a dark blade from the pivot
        theta = np.radians(self.wiper_angle(index))
        tip = (self.pivot[0] + self.length * np.sin(theta), self.pivot[1] - self.length * np.cos(theta))
        blade = np.zeros((h, w), np.float32)
        cv2.line(
            blade,
            (round(self.pivot[0] * 16), round(self.pivot[1] * 16)),
            (round(tip[0] * 16), round(tip[1] * 16)),
            1.0,
            max(3, round(0.025 * w)),
            lineType=cv2.LINE_AA,
            shift=4,
        )
        alpha = np.maximum(alpha, blade)
        colour = np.array([45, 55, 60], np.float32)
        frame[:] = np.clip(frame * (1 - alpha[..., None]) + colour * alpha[..., None], 0, 255).astype(np.uint8)
        hidden[alpha > 0.6] = 255
        return hidden


def glare(frame: np.ndarray, rng: np.random.Generator, horizon: float) -> np.ndarray:
    """One frame spoilt by overexposure, a sun flare near the horizon or motion blur (one of them, drawn).

    Args:
        frame: BGR uint8 (H, W, 3).
        rng: the clip's generator (draws the kind and its strength).
        horizon: the horizon's image row in this frame.

    Returns:
        the new frame (same shape and type).
    """
    h, w = frame.shape[:2]
    kind = int(rng.integers(0, 3))
    if kind == 0:  # overexposure: a gain that clips the bright road and paint together
        return cv2.convertScaleAbs(frame, alpha=float(rng.uniform(1.8, 2.6)), beta=float(rng.uniform(20, 50)))
    if kind == 1:  # a sun flare: a bright veil centred near the horizon, washing out the far paint
        cx, cy = float(rng.uniform(0.2, 0.8) * w), float(horizon + rng.uniform(-0.05, 0.1) * h)
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        radius = float(rng.uniform(0.3, 0.6) * w)
        veil = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * radius**2)) * float(rng.uniform(0.7, 0.95))
        streak = np.exp(-((yy - cy) ** 2) / (2 * (0.02 * h) ** 2)) * 0.6
        a = np.clip(veil + streak, 0, 1)[..., None]
        flared: np.ndarray = np.clip(frame * (1 - a) + 255.0 * a, 0, 255).astype(np.uint8)
        return flared
    # motion blur: a line kernel of 9-21 px in a random direction (camera shake)
    n = int(rng.integers(9, 22)) | 1
    kernel = np.zeros((n, n), np.float32)
    kernel[n // 2, :] = 1.0 / n
    rot = cv2.getRotationMatrix2D((n / 2 - 0.5, n / 2 - 0.5), float(rng.uniform(0, 180)), 1.0)
    kernel = np.asarray(cv2.warpAffine(kernel, rot, (n, n)), dtype=np.float32)  # float32 in, float32 out: no copy
    return cv2.filter2D(frame, -1, kernel / max(float(kernel.sum()), 1e-6))


@dataclass(frozen=True)
class NightLight:
    """How dark a night clip is: ``ambient`` light far away, ``beam`` metres of headlight reach as an image
    row fraction below the horizon, ``noise`` standard deviation of the sensor noise (grey levels)."""

    ambient: float
    beam: float
    noise: float

    @classmethod
    def sample(cls, rng: np.random.Generator) -> NightLight:
        return cls(float(rng.uniform(0.12, 0.25)), float(rng.uniform(0.25, 0.5)), float(rng.uniform(5, 10)))


def night(frame: np.ndarray, rng: np.random.Generator, light: NightLight, horizon: float) -> np.ndarray:
    """The frame at night: dark beyond the headlights' reach, lit near the camera, with sensor noise.

    Args:
        frame: BGR uint8 (H, W, 3), the day-time rendering.
        rng: the clip's generator (draws this frame's noise).
        light: the clip's `NightLight`.
        horizon: the horizon's image row in this frame.
    """
    h, w = frame.shape[:2]
    rows = np.arange(h, dtype=np.float32)
    depth = np.clip((rows - horizon) / max(h - horizon, 1.0), 0, 1)  # 0 at the horizon, 1 at the bottom
    lit = light.ambient + (0.85 - light.ambient) * np.clip(depth / light.beam, 0, 1) ** 2
    cols = np.linspace(-1, 1, w, dtype=np.float32)
    cone = 1.0 - 0.35 * cols**2  # the beams light the middle more than the sides
    gain = lit[:, None] * cone[None, :]
    gain[: int(max(horizon, 0))] = light.ambient * 0.5  # sky
    out = frame.astype(np.float32) * gain[..., None] * np.array([1.0, 0.95, 0.85], np.float32)  # warm bulbs
    out += rng.normal(0.0, light.noise, size=(h, w, 1)).astype(np.float32)
    dark: np.ndarray = np.clip(out, 0, 255).astype(np.uint8)
    return dark
