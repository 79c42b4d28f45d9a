"""The size budget: every allocation sized by a config value, a flag or a checkpoint is checked here first.

One place, the same numbers for a config (``data.clip.num_frames``), a flag (``stream --num-frames``) and a
checkpoint (``model.num_frames``), checked before the tensor or the image is made. The budgets fit every
legitimate use with room to spare: the paper fuses up to 5 frames (8 in the widest variants); images are up to
1920x1080 at full size; the evaluators read image sides up to 16,384 px. Past them, one line says which
(README, "Errors and limits").
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from stamlane_eval.io import MAX_IMAGE_SIDE

__all__ = [
    "MAX_CLIP_PIXELS",
    "MAX_FPS",
    "MAX_FRAMES",
    "MAX_RECORD_BYTES",
    "MAX_SIDE",
    "MAX_STREAM_BYTES",
    "MAX_SYNTH_FRAMES",
    "MAX_WORKERS",
    "BudgetError",
    "check_clip",
    "check_frames",
    "check_rate",
    "check_size",
    "check_stream_buffers",
    "check_workers",
    "stream_bytes",
]

MAX_FRAMES = 32
"""Frames a network fuses (T): the paper's 5 and its 8-frame variants, four times over."""
MAX_SYNTH_FRAMES = 1000
"""Frames of one generated synthetic clip (the default set: 20)."""
MAX_SIDE = MAX_IMAGE_SIDE
"""Image side in pixels (16,384: the evaluators' limit), of a network input, a frame or a generated frame."""
MAX_CLIP_PIXELS = 1 << 26
"""Pixels of one clip, frames x height x width (64 Mi px: 32 full-HD 1920x1080 frames; a float32 RGB clip of it
takes 768 MiB)."""
MAX_FPS = 1000.0
"""Frame rate of a written or simulated video, frames per second."""
MAX_WORKERS = 256
"""Worker processes of one pool (``synth --workers``, ``data.loader.num_workers``)."""
MAX_STREAM_BYTES = 8 << 30
"""Memory of the streaming predictor's tensors at their peak (8 GiB): a full-HD frame through the paper's full-width
VGG16 with 8 frames takes about 3.5 GiB by `stream_bytes`; the demo's 80x256 network a few MiB."""
MAX_RECORD_BYTES = 64 << 20
"""Largest summary, table index, run record or run config read (64 MiB; the largest written takes a few MiB)."""


class BudgetError(ValueError):
    """A size over its budget: one line naming the option, the value and the budget; exit status 2."""


def check_frames(num_frames: object, what: str = "num_frames", limit: int = MAX_FRAMES) -> int:
    """``num_frames`` as an int in ``1..limit``.

    Raises:
        BudgetError: not an integer, < 1 or over ``limit``.
    """
    if isinstance(num_frames, bool) or not isinstance(num_frames, int):
        raise BudgetError(f"{what} must be an integer, got {num_frames!r}")
    if not 1 <= num_frames <= limit:
        raise BudgetError(f"{what} must be in 1..{limit}, got {num_frames}")
    return num_frames


def check_size(size: Sequence[object], what: str = "image_size") -> tuple[int, int]:
    """An image size ``(H, W)`` of positive integers, each side at most `MAX_SIDE`.

    Raises:
        BudgetError: not two integers, a side < 1 or over `MAX_SIDE`.
    """
    if isinstance(size, (str, bytes)) or len(size) != 2:
        raise BudgetError(f"{what} must be (H, W), got {size!r}")
    if any(isinstance(s, bool) or not isinstance(s, int) for s in size):
        raise BudgetError(f"{what} must be two integers (H, W), got {list(size)!r}")
    h, w = int(size[0]), int(size[1])  # type: ignore[call-overload]
    if min(h, w) < 1 or max(h, w) > MAX_SIDE:
        raise BudgetError(f"{what} must have sides in 1..{MAX_SIDE} px, got {[h, w]}")
    return h, w


def check_clip(
    num_frames: object, size: Sequence[object], what: str = "clip", frames_limit: int = MAX_FRAMES
) -> tuple[int, tuple[int, int]]:
    """A clip's frames and size, each within its budget and together within `MAX_CLIP_PIXELS`.

    Raises:
        BudgetError: naming ``what``, the values and the budget.
    """
    t = check_frames(num_frames, f"{what} num_frames", frames_limit)
    h, w = check_size(size, f"{what} image_size")
    if t * h * w > MAX_CLIP_PIXELS:
        raise BudgetError(
            f"{what}: {t} frames of {h}x{w} px is {t * h * w:,} px, over the budget of {MAX_CLIP_PIXELS:,} px "
            "(frames x height x width)"
        )
    return t, (h, w)


def check_workers(workers: object, what: str, minimum: int = 0) -> int:
    """A count of worker processes in ``minimum..MAX_WORKERS``.

    Raises:
        BudgetError: not an integer or out of that range.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or not minimum <= workers <= MAX_WORKERS:
        raise BudgetError(f"{what} must be an integer in {minimum}..{MAX_WORKERS}, got {workers!r}")
    return workers


def check_rate(fps: object, what: str = "--fps") -> float:
    """A frame rate: a finite number in ``(0, MAX_FPS]``.

    Raises:
        BudgetError: not a number, not finite, <= 0 or over `MAX_FPS`.
    """
    if isinstance(fps, bool) or not isinstance(fps, (int, float)):
        raise BudgetError(f"{what} must be a number, got {fps!r}")
    if not math.isfinite(fps) or not 0 < fps <= MAX_FPS:
        raise BudgetError(f"{what} must be a finite rate in (0, {MAX_FPS:g}] frames/s, got {fps}")
    return float(fps)


def stream_bytes(
    num_frames: int, size: tuple[int, int], channels: Sequence[int], strides: Sequence[int], embed_dim: int
) -> int:
    """Bytes of float32 tensors the streaming predictor holds at once for one frame at the network size ``size``
    (measured within 20% on CPU: 262 B/px for the 0.125-wide VGG at 2048x2048, against 284 B/px here):

    - the frame and its standardised copy (3 + 3 values a pixel);
    - every encoder stage's features, kept for the decoder's skips (``channels[i] / strides[i]**2`` a pixel), and
      the working copy of the widest stage (``channels[0]``);
    - the history ring of ``num_frames - 1`` deepest features, their stacked and their warped copies (3 times);
    - the decoder at full resolution (three maps of ``channels[0]``), its logits and embedding (``2 + embed_dim``)
      and their float32, CPU and softmax copies (three times).
    """
    h, w = size
    pixels = h * w
    per_pixel = 6 + sum(c / s**2 for c, s in zip(channels, strides, strict=True)) + 4 * channels[0]
    per_pixel += 3 * (2 + embed_dim)
    history = 3 * (num_frames - 1) * channels[-1] * pixels / strides[-1] ** 2
    return int(4 * (per_pixel * pixels + history))


def check_stream_buffers(
    num_frames: int,
    size: tuple[int, int],
    channels: Sequence[int],
    strides: Sequence[int],
    embed_dim: int,
    what: str = "the streamed network",
    *,
    clips: bool = False,
) -> int:
    """The bytes `stream_bytes` counts, refused over `MAX_STREAM_BYTES` before any of them is allocated (a
    checkpoint's recorded ``image_size`` of 8192 a side passes `check_clip` with one frame, and asks ~20 GiB).
    With ``clips``, the frames go through the network together (``stamlane export``'s clip graph): T times more.

    Raises:
        BudgetError: naming ``what``, the frames, the size, the bytes and the budget.
    """
    if not channels or len(channels) != len(strides):
        raise BudgetError(f"{what}: encoder channels {list(channels)} and strides {list(strides)} do not pair")
    need = stream_bytes(num_frames, size, channels, strides, embed_dim)
    if clips:  # a whole clip through the network at once (the ONNX clip graph, traced): every frame's buffers
        need = num_frames * stream_bytes(1, size, channels, strides, embed_dim) + need
    if need > MAX_STREAM_BYTES:
        raise BudgetError(
            f"{what}: {num_frames} frame(s) of {size[0]}x{size[1]} px need about {need / (1 << 30):.1f} GiB of "
            f"buffers, over the budget of {MAX_STREAM_BYTES >> 30} GiB"
        )
    return need
