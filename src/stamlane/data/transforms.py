"""Clip-consistent augmentation and resizing to the network size.

One random draw per clip (crop/scale, horizontal flip, colour jitter) is applied to every frame and to
the key frame's lanes alike. Geometry is one 3x3 matrix ``net_from_orig`` (original pixels -> network
pixels, pixel centres at integers): crop and scale ``x_net = (x - x0 + 0.5) * W_net / w_crop - 0.5``,
then the flip ``x_net -> W_net - 1 - x_net``. Each frame is warped ONCE with
``net_from_orig @ key_from_hist[t]``: the pre-alignment (in original pixels) and the resize are composed,
so a history frame is interpolated a single time. Lanes map with the same matrix, and back with its
inverse, so network-pixel predictions return to original pixels without drift.

For feature-space alignment (``warp="feature"`` data, streaming) the frames are resized with the identity
instead and the homographies go to the network with the frames, in network pixels (`net_homographies`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["ClipParams", "ClipTransform", "net_homographies", "to_network"]


@dataclass(frozen=True)
class ClipParams:
    """The random draw of one clip: the geometry and the colour jitter."""

    net_from_orig: np.ndarray
    flip: bool
    brightness: float = 1.0
    contrast: float = 1.0
    saturation: float = 1.0
    hue: float = 0.0


class ClipTransform:
    """Resize (and optionally augment) a clip to the network size.

    Args:
        image_size: network input ``(H, W)``.
        crop_top: fraction of the image height cut off at the top before anything else (sky and horizon
            carry no lane; lane detectors' "cut height"); the network sees rows ``[crop_top * H0, H0)``.
        crop_scale: range of the crop side as a fraction of the original side (same for both axes, so the
            aspect ratio is kept); ``(1, 1)`` = no crop.
        flip_prob: probability of a horizontal flip.
        brightness: brightness factor drawn from ``[1 - b, 1 + b]``.
        contrast: contrast factor drawn from ``[1 - c, 1 + c]``.
        saturation: saturation factor drawn from ``[1 - s, 1 + s]``.
        hue: hue shift drawn from ``[-hue, hue]`` in fractions of a full turn (<= 0.5).
    """

    def __init__(
        self,
        image_size: tuple[int, int],
        *,
        crop_top: float = 0.0,
        crop_scale: tuple[float, float] = (1.0, 1.0),
        flip_prob: float = 0.0,
        brightness: float = 0.0,
        contrast: float = 0.0,
        saturation: float = 0.0,
        hue: float = 0.0,
    ) -> None:
        if len(image_size) != 2 or min(image_size) < 8:
            raise ValueError(f"image_size must be (H, W) with sides >= 8, got {image_size}")
        if not 0.0 <= crop_top < 0.9:
            raise ValueError(f"crop_top must be in [0, 0.9), got {crop_top}")
        lo, hi = crop_scale
        if not 0 < lo <= hi <= 1:
            raise ValueError(f"crop_scale must satisfy 0 < lo <= hi <= 1, got {crop_scale}")
        if not 0 <= flip_prob <= 1:
            raise ValueError(f"flip_prob must be in [0, 1], got {flip_prob}")
        for name, v in (("brightness", brightness), ("contrast", contrast), ("saturation", saturation)):
            if not 0 <= v < 1:
                raise ValueError(f"{name} must be in [0, 1), got {v}")
        if not 0 <= hue <= 0.5:
            raise ValueError(f"hue must be in [0, 0.5], got {hue}")
        self.image_size = (int(image_size[0]), int(image_size[1]))
        self.crop_top = float(crop_top)
        self.crop_scale = (float(lo), float(hi))
        self.flip_prob = float(flip_prob)
        self.brightness, self.contrast, self.saturation, self.hue = brightness, contrast, saturation, hue

    @property
    def augments(self) -> bool:
        """Whether any random change is configured (else ``draw`` is deterministic)."""
        return (
            self.crop_scale != (1.0, 1.0)
            or self.flip_prob > 0
            or any(v > 0 for v in (self.brightness, self.contrast, self.saturation, self.hue))
        )

    def draw(self, orig_size: tuple[int, int], rng: np.random.Generator | None = None) -> ClipParams:
        """Draw the parameters of one clip.

        Args:
            orig_size: original image ``(H, W)``.
            rng: random generator (needed only when ``augments``).
        """
        h0, w0 = orig_size
        net_h, net_w = self.image_size
        rng = rng if rng is not None else np.random.default_rng(0)
        frac = float(rng.uniform(*self.crop_scale)) if self.crop_scale != (1.0, 1.0) else 1.0
        top = self.crop_top * h0
        cw, ch = w0 * frac, (h0 - top) * frac
        x0 = float(rng.uniform(0, w0 - cw)) if frac < 1 else 0.0
        y0 = top + (float(rng.uniform(0, h0 - top - ch)) if frac < 1 else 0.0)
        sx, sy = net_w / cw, net_h / ch
        m = np.array([[sx, 0, (0.5 - x0) * sx - 0.5], [0, sy, (0.5 - y0) * sy - 0.5], [0, 0, 1.0]])
        flip = bool(rng.random() < self.flip_prob) if self.flip_prob > 0 else False
        if flip:
            m = np.array([[-1.0, 0, net_w - 1], [0, 1, 0], [0, 0, 1]]) @ m

        def factor(v: float) -> float:
            return float(rng.uniform(1 - v, 1 + v)) if v > 0 else 1.0

        hue = float(rng.uniform(-self.hue, self.hue)) if self.hue > 0 else 0.0
        return ClipParams(m, flip, factor(self.brightness), factor(self.contrast), factor(self.saturation), hue)

    def apply_frames(self, frames: list[np.ndarray], key_from_hist: np.ndarray, params: ClipParams) -> np.ndarray:
        """Align, crop, flip, resize and jitter the frames of one clip.

        Args:
            frames: T BGR uint8 images (H0, W0, 3), oldest first, key last, original size.
            key_from_hist: (T, 3, 3) alignment of each frame to the key frame in ORIGINAL pixels.
            params: the clip's draw.

        Returns:
            float32 (T, 3, H, W) RGB in [0, 1]; pixels a warped history frame does not cover are 0.
        """
        net_h, net_w = self.image_size
        out = np.empty((len(frames), 3, net_h, net_w), np.float32)
        for t, frame in enumerate(frames):
            out[t] = to_network(self.warp_frame(frame, key_from_hist[t], params))
        return out

    def warp_frame(self, frame: np.ndarray, key_from_hist: np.ndarray, params: ClipParams) -> np.ndarray:
        """One frame of `apply_frames` before its conversion to floats (`to_network`).

        Args:
            frame: a BGR uint8 image (H0, W0, 3), original size.
            key_from_hist: (3, 3) its alignment to the key frame in ORIGINAL pixels.
            params: the clip's draw.

        Returns:
            RGB uint8 (H, W, 3) at the network size: aligned, cropped, flipped, resized and jittered.
        """
        net_h, net_w = self.image_size
        scale = float(np.sqrt(abs(np.linalg.det(params.net_from_orig[:2, :2]))))
        m = params.net_from_orig @ key_from_hist
        if scale < 0.6:  # shrink by area first: a bilinear warp alone would alias the road texture
            frame, pre = _area_shrink(frame, min(1.0, 2.0 * scale))
            m = m @ np.linalg.inv(pre)
        warped = cv2.warpPerspective(
            frame, m, (net_w, net_h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0)
        )
        return cv2.cvtColor(self._jitter(warped, params), cv2.COLOR_BGR2RGB)

    @staticmethod
    def _jitter(img: np.ndarray, p: ClipParams) -> np.ndarray:
        if p.hue != 0.0 or p.saturation != 1.0:
            hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV).astype(np.float32)
            hsv[..., 0] = np.mod(hsv[..., 0] + p.hue * 180.0, 180.0)
            hsv[..., 1] = np.clip(hsv[..., 1] * p.saturation, 0, 255)
            img = cv2.cvtColor(hsv.astype(np.uint8), cv2.COLOR_HSV2BGR)
        if p.brightness != 1.0 or p.contrast != 1.0:
            mean = float(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).mean())
            # out = (img - mean) * contrast + mean, then * brightness
            alpha = p.contrast * p.brightness
            beta = mean * (1.0 - p.contrast) * p.brightness
            img = cv2.convertScaleAbs(img, alpha=alpha, beta=beta)
        return img

    @staticmethod
    def map_lanes(lanes: list[np.ndarray], matrix: np.ndarray) -> list[np.ndarray]:
        """Map lanes ``(N, 2)`` through a 3x3 matrix (e.g. ``net_from_orig`` or its inverse)."""
        out = []
        for lane in lanes:
            if len(lane) == 0:
                out.append(np.zeros((0, 2)))
                continue
            hom = np.c_[lane, np.ones(len(lane))] @ np.asarray(matrix, dtype=np.float64).T
            out.append(hom[:, :2] / hom[:, 2:3])
        return out


def to_network(rgb: np.ndarray) -> np.ndarray:
    """A warped frame (`ClipTransform.warp_frame`: RGB uint8 (H, W, 3)) as the network reads it: float32 (3, H, W)
    in [0, 1]."""
    out: np.ndarray = rgb.transpose(2, 0, 1).astype(np.float32) / 255.0
    return out


def net_homographies(key_from_hist: np.ndarray, net_from_orig: np.ndarray) -> np.ndarray:
    """Express original-pixel homographies in network-input pixels: ``net_from_orig @ H @ inv(net_from_orig)``.

    Args:
        key_from_hist: ``(T, 3, 3)`` history -> key frame, ORIGINAL pixels (identity for the key frame).
        net_from_orig: ``(3, 3)`` original -> network pixels of the clip's draw (`ClipParams.net_from_orig`).

    Returns:
        ``(T, 3, 3)`` float64 history -> key frame in NETWORK pixels, normalised so ``[2, 2] = 1``; an identity
        (up to 1e-12, float rounding) becomes the exact identity, so the key frame and unaligned frames are not
        resampled.
    """
    mats = np.asarray(key_from_hist, dtype=np.float64)
    if mats.ndim != 3 or mats.shape[1:] != (3, 3):
        raise ValueError(f"key_from_hist must be (T, 3, 3), got {mats.shape}")
    net = np.asarray(net_from_orig, dtype=np.float64)
    if net.shape != (3, 3):
        raise ValueError(f"net_from_orig must be (3, 3), got {net.shape}")
    out = net @ mats @ np.linalg.inv(net)
    out /= out[:, 2:3, 2:3]
    identity = (np.abs(mats / mats[:, 2:3, 2:3] - np.eye(3)) <= 1e-12).all(axis=(1, 2))
    out[identity] = np.eye(3)
    return out


def _area_shrink(frame: np.ndarray, factor: float) -> tuple[np.ndarray, np.ndarray]:
    """Resize by ``factor`` with area averaging; returns the image and ``small_from_orig`` (3, 3)."""
    h0, w0 = frame.shape[:2]
    w1, h1 = max(1, round(w0 * factor)), max(1, round(h0 * factor))
    fx, fy = w1 / w0, h1 / h0
    small = cv2.resize(frame, (w1, h1), interpolation=cv2.INTER_AREA)
    return small, np.array([[fx, 0, 0.5 * fx - 0.5], [0, fy, 0.5 * fy - 0.5], [0, 0, 1.0]])
