"""One image's score against its labels, as an overlay prints it (``stamlane predict`` on a labelled split).

With ``h_samples`` (TuSimple layout): the official per-image accuracy (``LaneEval.bench``,
`stamlane_eval.tusimple.evaluate_image`, lanes sampled at the image's rows as the evaluation callback samples them)
and the annotated lanes matched; the picture scores the lanes, not the time (the 200 ms rule is left out).
Otherwise (CULane, ApolloScape, VIL-100): the CULane IoU F1 at 0.5 (`stamlane_eval.culane.evaluate_image`), the
lanes drawn `iou_width` pixels wide.
"""

from __future__ import annotations

from collections.abc import Sequence

from stamlane.types import Lanes

__all__ = ["image_score", "iou_width"]


def iou_width(size: tuple[int, int]) -> int:
    """The CULane metric's line thickness for images of ``size`` (H, W): the protocol's 30 px on CULane's
    1640-px-wide frames, scaled with the image width (12 px at 640), so that a lane covers the same fraction of
    the image as in the benchmark (`stamlane.experiments.split_scores` scores whole splits with it)."""
    from stamlane_eval.culane import CULANE_SIZE, LANE_WIDTH

    return max(1, round(LANE_WIDTH * size[1] / CULANE_SIZE[1]))


def image_score(lanes: Lanes, gt_lanes: Lanes, h_samples: Sequence[int] | None, size: tuple[int, int]) -> str:
    """The score line of one image, e.g. ``"TuSimple acc 93.8 %, 3/4 lanes"`` or ``"IoU F1@0.5 0.86 (3 of 4 lanes,
    1 false)"``.

    Args:
        lanes: predicted lanes, ``(N, 2)`` ``(x, y)`` in original pixels.
        gt_lanes: annotated lanes, the same form.
        h_samples: the image's TuSimple rows, or None.
        size: the image's ``(H, W)``.
    """
    if h_samples:
        from stamlane_eval.tusimple import evaluate_image as tusimple_image
        from stamlane_eval.tusimple import lanes_to_xs

        rows = list(h_samples)
        result = tusimple_image(lanes_to_xs(lanes, rows), lanes_to_xs(gt_lanes, rows), rows)
        return f"TuSimple acc {100 * result.acc:.1f} %, {result.matched}/{result.n_gt} lanes"
    from stamlane_eval.aggregate import prf
    from stamlane_eval.culane import evaluate_image as culane_image

    counts = culane_image(lanes, gt_lanes, (0.5,), iou_width(size), size).counts
    tp, fp, fn = counts[0.5]
    f1 = prf(tp, fp, fn)[2]  # the evaluators' convention: 0 where nothing was labelled or predicted
    return f"IoU F1@0.5 {f1:.2f} ({tp} of {tp + fn} lanes, {fp} false)"
