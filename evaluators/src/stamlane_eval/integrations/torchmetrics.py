"""torchmetrics versions of the metrics: ``update`` calls the same per-image functions as the CLI, and both
``update`` and ``compute`` fold with the same helpers as the functions (``stamlane_eval.aggregate``), so the class
and ``tusimple.evaluate`` / ``culane.evaluate`` give the same numbers on the same images, to the last bit.

States are the sums of ``stamlane_eval.aggregate`` summed across processes (``dist_reduce_fx="sum"``), so DDP
gives the numbers of one process (floating-point sums may differ in the last bits because the order of addition
differs).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torchmetrics import Metric

from stamlane_eval import culane, tusimple
from stamlane_eval.aggregate import TuSimpleSums, culane_update, prf, tusimple_compute, tusimple_update

__all__ = ["CULaneMetric", "TuSimpleMetric"]


def _to_numpy(lane: object) -> np.ndarray:
    if isinstance(lane, torch.Tensor):
        return lane.detach().cpu().double().numpy()
    return np.asarray(lane, dtype=np.float64)


class TuSimpleMetric(Metric):
    """TuSimple accuracy / FP / FN (official ``lane.py``), the paper's F1 and lane-count precision/recall/F1.

    The sums and the division are ``tusimple.evaluate``'s (``stamlane_eval.aggregate``): over the images given to
    ``update``, which the function refuses to see twice (a gt naming an image twice). Unlike the function,
    ``compute`` returns totals outside [0, 1] as they are (images with more than 5 gt lanes; FP below 0): a
    training run logs them rather than stopping.
    """

    full_state_update = False
    higher_is_better = True
    _FLOATS = ("acc", "fp", "fn")
    _INTS = ("images", "lane_tp", "lane_pred", "lane_gt")

    def __init__(self, **kwargs: object) -> None:
        super().__init__(**kwargs)
        for name in self._FLOATS:
            self.add_state(f"{name}_sum", default=torch.tensor(0.0, dtype=torch.float64), dist_reduce_fx="sum")
        for name in self._INTS:
            self.add_state(name, default=torch.tensor(0, dtype=torch.int64), dist_reduce_fx="sum")

    def _sums(self) -> TuSimpleSums:
        floats = {name: float(getattr(self, f"{name}_sum")) for name in self._FLOATS}
        return TuSimpleSums(**floats, **{name: int(getattr(self, name)) for name in self._INTS})

    def update(
        self,
        preds: Sequence[object],
        target: Sequence[object],
        h_samples: Sequence[Sequence[float]],
        run_times: Sequence[float] | None = None,
    ) -> None:
        """Add images.

        Args:
            preds: per image, predicted lanes as TuSimple x lists (``(P, R)``; -2 = absent). Convert polylines
                with :func:`stamlane_eval.tusimple.lanes_to_xs`.
            target: per image, gt lanes ``(G, R)``.
            h_samples: per image, the ``R`` row y values.
            run_times: per image, milliseconds (default 0).
        """
        sums = tusimple_update(self._sums(), tusimple.evaluate_batch(preds, target, h_samples, run_times))
        for name in self._FLOATS:
            getattr(self, f"{name}_sum").fill_(getattr(sums, name))
        for name in self._INTS:
            getattr(self, name).fill_(getattr(sums, name))

    def compute(self) -> dict[str, torch.Tensor]:
        """``accuracy``, ``fp``, ``fn``, ``f1`` (paper), ``lane_precision``, ``lane_recall``, ``lane_f1``."""
        return {k: torch.tensor(v, dtype=torch.float64) for k, v in tusimple_compute(self._sums()).items()}


class CULaneMetric(Metric):
    """CULane / ApolloScape area metric (official C++ tool or lanedet) at one or more IoU thresholds.

    Args:
        iou_thresholds: TP when the matched IoU is strictly greater.
        width: line thickness in pixels.
        size: image ``(H, W)``; ``update(..., sizes=...)`` may give each image its own.
        variant: ``"official"`` or ``"lanedet"``.
    """

    full_state_update = False
    higher_is_better = True

    def __init__(
        self,
        iou_thresholds: Sequence[float] = culane.IOU_THRESHOLDS,
        width: int = culane.LANE_WIDTH,
        size: tuple[int, int] = culane.CULANE_SIZE,
        variant: str = "official",
        **kwargs: object,
    ) -> None:
        super().__init__(**kwargs)
        if variant not in culane.VARIANTS:
            raise ValueError(f"variant must be one of {culane.VARIANTS}, got {variant!r}")
        self.iou_thresholds = tuple(float(t) for t in iou_thresholds)
        self.width = int(width)
        self.size = (int(size[0]), int(size[1]))
        self.variant = variant
        k = len(self.iou_thresholds)
        for name in ("tp", "fp", "fn"):
            self.add_state(name, default=torch.zeros(k, dtype=torch.int64), dist_reduce_fx="sum")
        self.add_state("images", default=torch.tensor(0, dtype=torch.int64), dist_reduce_fx="sum")

    def update(
        self,
        preds: Sequence[Sequence[object]],
        target: Sequence[Sequence[object]],
        sizes: Sequence[tuple[int, int]] | None = None,
    ) -> None:
        """Add images.

        Args:
            preds: per image, predicted lanes, each ``(N, 2)`` ``(x, y)`` in original pixels (array or tensor).
            target: per image, annotated lanes, same form.
            sizes: per image ``(H, W)``; default ``size`` for every image.
        """
        if len(preds) != len(target):
            raise ValueError(f"got {len(preds)} prediction images and {len(target)} target images")
        if sizes is not None and len(sizes) != len(preds):
            raise ValueError(f"got {len(sizes)} sizes for {len(preds)} images")
        per_image = [
            culane.evaluate_image(
                [_to_numpy(x) for x in p],
                [_to_numpy(x) for x in g],
                self.iou_thresholds,
                self.width,
                self.size if sizes is None else (int(sizes[i][0]), int(sizes[i][1])),
                self.variant,
            )
            for i, (p, g) in enumerate(zip(preds, target, strict=True))
        ]
        sums = culane_update(torch.stack([self.tp, self.fp, self.fn], 1).tolist(), per_image, self.iou_thresholds)
        counts = torch.tensor(sums, dtype=torch.int64, device=self.tp.device)
        self.tp.copy_(counts[:, 0])
        self.fp.copy_(counts[:, 1])
        self.fn.copy_(counts[:, 2])
        self.images += len(per_image)

    def compute(self) -> dict[str, torch.Tensor]:
        """``{f"precision@{t}", f"recall@{t}", f"f1@{t}", f"tp@{t}", f"fp@{t}", f"fn@{t}"}`` for each threshold."""
        out = {}
        for i, t in enumerate(self.iou_thresholds):
            counts = (int(self.tp[i]), int(self.fp[i]), int(self.fn[i]))
            for name, v in zip(("precision", "recall", "f1"), prf(*counts), strict=True):
                out[f"{name}@{t:g}"] = torch.tensor(v, dtype=torch.float64)
            for name, v in zip(("tp", "fp", "fn"), counts, strict=True):
                out[f"{name}@{t:g}"] = torch.tensor(v, dtype=torch.int64)
        return out
