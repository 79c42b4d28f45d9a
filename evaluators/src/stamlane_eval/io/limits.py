"""The memory limits every reader and metric applies: sizes of files, images, lanes and the canvases lanes are drawn
on, never coordinate values (docs/evaluators.md, "What is scored and what is refused", point 4)."""

from __future__ import annotations

from collections.abc import Iterable

__all__ = [
    "MAX_COORDINATE",
    "MAX_DRAWN_PIXELS",
    "MAX_FILE_BYTES",
    "MAX_IMAGE_POINTS",
    "MAX_IMAGE_SIDE",
    "MAX_LANES",
    "MAX_LANE_POINTS",
    "MAX_LANE_WIDTH",
    "CanvasBudget",
    "check_image_size",
]

MAX_IMAGE_SIDE = 16384
"""Largest image side (px) accepted from a label file or ``--size``: the CULane metric draws every lane into a mask of
the image's size, so a declared 200000x200000 frame would ask for tens of GiB."""
MAX_DRAWN_PIXELS = 1 << 30
"""Most pixels of canvases the lanes of one image (CULane, video) or one frame (temporal) are drawn on (1 GiB of
uint8): each lane is drawn into a canvas cropped to it, never larger than the image; `CanvasBudget` counts them
before each canvas is allocated."""
MAX_LANES = 64
"""Most lanes in one image: the CULane matching grows with the cube of the lane count (1,500 lanes: a minute)."""
MAX_LANE_POINTS = 10000
"""Most points (rows) in one TuSimple or VIL-100 lane. CULane text has no limit per lane: ``MAX_IMAGE_POINTS``."""
MAX_IMAGE_POINTS = 100_000
"""Most points in the lanes of one CULane/ApolloScape ``.lines.txt`` (the memory budget of one image, not a limit
per lane): the C++ metric resamples a lane at 50 points per segment, about 3 KB per input point while it is
resampled (measured: one lane of 100,000 points, ``stamlane-eval culane``, peaks at 0.33 GB in 3.6 s); the C++
tool's own inputs hold a few hundred points per image."""
MAX_LANE_WIDTH = 1024
"""Widest lane line (px) the CULane metric may draw."""
MAX_COORDINATE = 100_000.0
"""Largest absolute pixel coordinate of a LABEL (6x ``MAX_IMAGE_SIDE``): a ground truth beyond it is refused. Not a
limit on predictions: lane.py scores a prediction's 1e9 as a miss, and so do we (with one warning line)."""
MAX_FILE_BYTES = 512 << 20
"""Largest input text file (512 MiB): TuSimple's 2,782 test predictions take 4 MiB, and parsed json-lines cost about
9x their size in memory."""


def check_image_size(size: object) -> tuple[int, int]:
    """THE check of an image size that canvases are sized by (``--size``, ``--sizes``, a label's ``info``, the
    Python API): ``(H, W)``, two integers in ``1..MAX_IMAGE_SIDE``.

    Raises:
        ValueError: naming the size.
    """
    try:
        if not isinstance(size, Iterable):
            raise TypeError(size)
        h, w = (int(v) for v in size)
    except (TypeError, ValueError):
        raise ValueError(f"size must be the image (H, W), two integers, got {size!r:.60}") from None
    if not (0 < h <= MAX_IMAGE_SIDE and 0 < w <= MAX_IMAGE_SIDE):
        raise ValueError(f"size must be the image (H, W) with sides in 1..{MAX_IMAGE_SIDE}, got {size!r:.60}")
    return h, w


class CanvasBudget:
    """The pixels the lanes of one image may still be drawn on (``MAX_DRAWN_PIXELS``), taken before each canvas is
    allocated: the CULane, video and temporal metrics refuse the same input at the same point.

    Args:
        size: the image ``(H, W)`` (for the message).
    """

    def __init__(self, size: tuple[int, int]) -> None:
        self.size = size
        self.left = MAX_DRAWN_PIXELS

    def take(self, h: int, w: int) -> None:
        """Count an ``(h, w)`` canvas about to be allocated.

        Raises:
            ValueError: past the budget, before anything is allocated.
        """
        self.left -= h * w
        if self.left < 0:
            raise ValueError(
                f"the lanes of this image cover more than {MAX_DRAWN_PIXELS >> 20} Mpx of {self.size[1]}x{self.size[0]} "
                f"canvases: too large to draw in memory (fewer or shorter lanes, or a smaller --size)"
            )
