"""The size budgets every reader and metric applies: sizes of files, images, lanes and the canvases lanes are drawn
on, never coordinate values (docs/evaluators.md, "What is scored and what is refused", point 4).

The parity rule: what the official tool scores, stamlane scores the same. A limit here refuses only what would
exceed a budget of memory or time (each says which, and what it costs at the limit); none refuses a value."""

from __future__ import annotations

from collections.abc import Iterable

__all__ = [
    "MAX_COMPARED_CELLS",
    "MAX_COORDINATE",
    "MAX_DRAWN_PIXELS",
    "MAX_FILE_BYTES",
    "MAX_IMAGE_POINTS",
    "MAX_IMAGE_SIDE",
    "MAX_LANES",
    "MAX_LANE_POINTS",
    "MAX_LANE_WIDTH",
    "MAX_TUSIMPLE_VALUES",
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
MAX_LANES = 512
"""Most lanes in one image, either side (time): the CULane metric compares every predicted lane with every annotated
one and matches them in time cubic in the lane count (what it costs: docs/results/evaluators/). The C++ tool scores any
count (65 predicted lanes: 2 matched, 63 FP); real images hold at most a dozen. TuSimple files scored by lane.py's
rule have no lane count limit: `MAX_TUSIMPLE_VALUES` and `MAX_COMPARED_CELLS` are their budgets."""
MAX_LANE_POINTS = 10000
"""Most points (rows) in one TuSimple lane read as the frames of a sequence or by the training datasets (the padded
arrays those readers build). lane.py's own scoring has no limit per lane (`MAX_TUSIMPLE_VALUES`); VIL-100 and
CULane text have none either (``MAX_IMAGE_POINTS`` per image)."""
MAX_TUSIMPLE_VALUES = 1 << 25
"""Most values of the padded ``(lanes, longest lane)`` float64 array a TuSimple file is held in for lane.py's
scoring (memory: 256 MiB). TuSimple's 2,782 test images take 0.8 M (5 lanes of 56 rows): any lane count and lane
length lane.py scores fits, as long as the file's lanes padded to its longest do."""
MAX_COMPARED_CELLS = 1 << 28
"""Most (predicted lane, gt lane, row) comparisons of one TuSimple image that lane.py compares (time, measured at the
limit in docs/results/evaluators/; memory stays bounded, the comparison runs a few gt lanes at a time; a TuSimple test image takes
7 x 5 x 56 = 1,960). An image that lane.py's lane-count or run-time rule scores (0, 0, 1) unseen costs nothing."""
MAX_IMAGE_POINTS = 100_000
"""Most points in the lanes of one CULane/ApolloScape ``.lines.txt`` or VIL-100 ``.json`` (the memory budget of one image, not a limit
per lane): the C++ metric resamples a lane at 50 points per segment, about 3 KB per input point while it is
resampled (measured at the limit: docs/results/evaluators/); the C++
tool's own inputs hold a few hundred points per image."""
MAX_LANE_WIDTH = 32767
"""Widest lane line (px) the CULane metric may draw: OpenCV's ``MAX_THICKNESS``, past which the C++ tool's
``cv::line`` raises (it scores every width up to it). Memory stays bounded by `CanvasBudget`: a lane's canvas is
cropped to it and never larger than the image."""
MAX_COORDINATE = 100_000.0
"""Largest absolute pixel coordinate counted as a pixel (6x ``MAX_IMAGE_SIDE``). No evaluator refuses a value beyond
it, label or prediction: the official tools score it (lane.py: a gt x of 150,000 steepens its lane's angle fit and
widens its threshold; the C++ tool draws it clipped), and so do we (TuSimple: with one warning line). Only the training
datasets' labels (``tusimple_record_error``) must lie within it."""
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
