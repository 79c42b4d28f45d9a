"""torchmetrics versions of the metrics: ``update`` calls the same per-image functions as the CLI.

States are summed across processes (``dist_reduce_fx="sum"``), so DDP gives the numbers of one process
(floating-point sums may differ in the last bits because the order of addition differs).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torchmetrics import Metric

from stamlane_eval import culane, tusimple

__all__ = ["CULaneMetric", "TuSimpleMetric"]


def _to_numpy(lane: object) -> np.ndarray:
    if isinstance(lane, torch.Tensor):
        return lane.detach().cpu().double().numpy()
    return np.asarray(lane, dtype=np.float64)


class TuSimpleMetric(Metric):
    """TuSimple accuracy / FP / FN (official ``lane.py``), the paper's F1 and lane-count precision/recall/F1.

    ``compute`` divides the sums by the number of images given to ``update`` (the official tool divides by
    the number of unique gt ``raw_file``s: the same unless the gt repeats an image).
    """

    full_state_update = False
    higher_is_better = True

    def __init__(self, **kwargs: object) -> None:
        super().__init__(**kwargs)
        for name in ("acc_sum", "fp_sum", "fn_sum"):
            self.add_state(name, default=torch.tensor(0.0, dtype=torch.float64), dist_reduce_fx="sum")
        for name in ("images", "lane_tp", "lane_pred", "lane_gt"):
            self.add_state(name, default=torch.tensor(0, dtype=torch.int64), dist_reduce_fx="sum")

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
        for r in tusimple.evaluate_batch(preds, target, h_samples, run_times):
            self.acc_sum += r.acc  # one image at a time: the official left-to-right float sum
            self.fp_sum += r.fp
            self.fn_sum += r.fn
            self.images += 1
            self.lane_tp += r.matched
            self.lane_pred += r.n_pred
            self.lane_gt += r.n_gt

    def compute(self) -> dict[str, torch.Tensor]:
        """``accuracy``, ``fp``, ``fn``, ``f1`` (paper), ``lane_precision``, ``lane_recall``, ``lane_f1``."""
        n = max(int(self.images), 1)
        acc, fp, fn = float(self.acc_sum) / n, float(self.fp_sum) / n, float(self.fn_sum) / n
        tp, n_pred, n_gt = int(self.lane_tp), int(self.lane_pred), int(self.lane_gt)
        lp, lr, lf = tusimple.prf(tp, n_pred - tp, n_gt - tp)
        vals = {
            "accuracy": acc,
            "fp": fp,
            "fn": fn,
            "f1": tusimple.paper_f1(fp, fn),
            "lane_precision": lp,
            "lane_recall": lr,
            "lane_f1": lf,
        }
        return {k: torch.tensor(v, dtype=torch.float64) for k, v in vals.items()}


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
        for i, (p, g) in enumerate(zip(preds, target, strict=True)):
            size = self.size if sizes is None else (int(sizes[i][0]), int(sizes[i][1]))
            r = culane.evaluate_image(
                [_to_numpy(x) for x in p],
                [_to_numpy(x) for x in g],
                self.iou_thresholds,
                self.width,
                size,
                self.variant,
            )
            counts = torch.tensor([r.counts[t] for t in self.iou_thresholds], dtype=torch.int64, device=self.tp.device)
            self.tp += counts[:, 0]
            self.fp += counts[:, 1]
            self.fn += counts[:, 2]
            self.images += 1

    def compute(self) -> dict[str, torch.Tensor]:
        """``{f"precision@{t}", f"recall@{t}", f"f1@{t}", f"tp@{t}", f"fp@{t}", f"fn@{t}"}`` for each threshold."""
        out = {}
        for i, t in enumerate(self.iou_thresholds):
            c = culane.counts_to_prf(int(self.tp[i]), int(self.fp[i]), int(self.fn[i]))
            for name in ("precision", "recall", "f1"):
                out[f"{name}@{t:g}"] = torch.tensor(getattr(c, name), dtype=torch.float64)
            for name in ("tp", "fp", "fn"):
                out[f"{name}@{t:g}"] = torch.tensor(getattr(c, name), dtype=torch.int64)
        return out
