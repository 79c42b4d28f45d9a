"""torchmetrics versions of the metrics: ``update`` calls the same per-image functions as the CLI, and both
``update`` and ``compute`` fold with the same helpers as the functions (``stamlane_eval.aggregate``), so the class
and ``tusimple.evaluate`` / ``culane.evaluate`` give the same numbers on the same images, to the last bit.

States are the sums of ``stamlane_eval.aggregate`` summed across processes (``dist_reduce_fx="sum"``), so DDP
gives the numbers of one process (floating-point sums may differ in the last bits because the order of addition
differs).
"""

from __future__ import annotations

import hashlib
import warnings
from abc import abstractmethod
from collections.abc import Hashable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import torch
from torchmetrics import Metric
from torchmetrics.utilities import dim_zero_cat

from stamlane_eval import culane, temporal, tusimple, video
from stamlane_eval.aggregate import (
    TuSimpleSums,
    count_update,
    dataset_miou,
    prf,
    sequence_miou,
    tusimple_compute,
    tusimple_update,
)
from stamlane_eval.names import metric_key

__all__ = ["CULaneMetric", "TemporalStabilityMetric", "TuSimpleMetric", "VideoMetric"]


def _to_numpy(lane: object) -> np.ndarray:
    if isinstance(lane, torch.Tensor):
        return lane.detach().cpu().double().numpy()
    return np.asarray(lane, dtype=np.float64)


def _add_counts(
    states: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
    counts: Iterable[Mapping[float, Sequence[int]]],
    thresholds: Sequence[float],
) -> None:
    """Add count triples to three ``(k,)`` int64 states, one value per threshold, in place
    (`stamlane_eval.aggregate.count_update`, the functions' own sums)."""
    sums = count_update(torch.stack(states, 1).tolist(), counts, thresholds)
    new = torch.tensor(sums, dtype=torch.int64, device=states[0].device)
    for k, state in enumerate(states):
        state.copy_(new[:, k])


def _add_sum_states(metric: Metric, counts: Sequence[str], k: int, totals: Sequence[str]) -> None:
    """Add the states of a metric that counts, zero and summed across processes (``dist_reduce_fx="sum"``):
    ``counts``, ``(k,)`` int64 (one value per threshold), then ``totals``, 0-d int64."""
    for name in counts:
        metric.add_state(name, default=torch.zeros(k, dtype=torch.int64), dist_reduce_fx="sum")
    for name in totals:
        metric.add_state(name, default=torch.tensor(0, dtype=torch.int64), dist_reduce_fx="sum")


class _LaneCountMetric(Metric):
    """What the metrics that match lanes by IoU share (CULane, video): TP / FP / FN counts per threshold and the
    images, summed across processes, and their precision / recall / F1 (``stamlane_eval.aggregate.prf``)."""

    full_state_update = False
    higher_is_better = True
    # the states (add_state): (k,) int64 counts per threshold, 0-d int64 images
    tp: torch.Tensor
    fp: torch.Tensor
    fn: torch.Tensor
    images: torch.Tensor

    def _add_count_states(self, iou_thresholds: Sequence[float]) -> None:
        """Keep the thresholds (``iou_thresholds``) and add the count states, zero."""
        self.iou_thresholds = tuple(float(t) for t in iou_thresholds)
        _add_sum_states(self, ("tp", "fp", "fn"), len(self.iou_thresholds), ("images",))

    def _counts_out(self) -> dict[str, torch.Tensor]:
        """``{f"precision@{t}", f"recall@{t}", f"f1@{t}"}`` (float64) and ``{f"tp@{t}", f"fp@{t}", f"fn@{t}"}``
        (int64) for each threshold."""
        out = {}
        for i, t in enumerate(self.iou_thresholds):
            counts = (int(self.tp[i]), int(self.fp[i]), int(self.fn[i]))
            for name, v in zip(("precision", "recall", "f1"), prf(*counts), strict=True):
                out[metric_key(name, t)] = torch.tensor(v, dtype=torch.float64)
            for name, v in zip(("tp", "fp", "fn"), counts, strict=True):
                out[metric_key(name, t)] = torch.tensor(v, dtype=torch.int64)
        return out


class TuSimpleMetric(Metric):
    """TuSimple accuracy / FP / FN (official ``lane.py``), the paper's F1 and lane-count precision/recall/F1.

    The sums and the division are ``tusimple.evaluate``'s (``stamlane_eval.aggregate``): over the images given to
    ``update``, which the function refuses to see twice (a gt naming an image twice). As the function, ``compute``
    returns totals outside [0, 1] as lane.py computes them (images with more than 5 gt lanes; FP below 0): a
    training run logs them rather than stopping (``stamlane-eval`` refuses them: ``tusimple.check_rates``).

    Images whose ``run_time`` exceeds 200 ms (``tusimple.MAX_RUN_TIME_MS``) are scored as missed, as lane.py
    does, unless ``time_limit=False``; ``compute`` returns their count as ``late`` and, when the rule scored any,
    warns once (a ``UserWarning`` naming the count and ``time_limit=False``).

    Args:
        time_limit: apply the benchmark's 200 ms rule (``tusimple.evaluate(..., time_limit=...)``).
    """

    full_state_update = False
    higher_is_better = True
    _FLOATS = ("acc", "fp", "fn")
    _INTS = ("images", "lane_tp", "lane_pred", "lane_gt")
    # the states (add_state), 0-d: float64 sums, int64 counts
    acc_sum: torch.Tensor
    fp_sum: torch.Tensor
    fn_sum: torch.Tensor
    images: torch.Tensor
    lane_tp: torch.Tensor
    lane_pred: torch.Tensor
    lane_gt: torch.Tensor
    late: torch.Tensor

    def __init__(self, time_limit: bool = True, **kwargs: object) -> None:
        super().__init__(**kwargs)
        self.time_limit = bool(time_limit)
        for name in self._FLOATS:
            self.add_state(f"{name}_sum", default=torch.tensor(0.0, dtype=torch.float64), dist_reduce_fx="sum")
        for name in self._INTS:
            self.add_state(name, default=torch.tensor(0, dtype=torch.int64), dist_reduce_fx="sum")
        self.add_state("late", default=torch.tensor(0, dtype=torch.int64), dist_reduce_fx="sum")

    def _sums(self) -> TuSimpleSums:
        return TuSimpleSums(
            acc=float(self.acc_sum),
            fp=float(self.fp_sum),
            fn=float(self.fn_sum),
            images=int(self.images),
            lane_tp=int(self.lane_tp),
            lane_pred=int(self.lane_pred),
            lane_gt=int(self.lane_gt),
        )

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
            run_times: per image, milliseconds (default 0); over 200 ms: missed, unless ``time_limit=False``.
        """
        per_image = tusimple.evaluate_batch(preds, target, h_samples, run_times if self.time_limit else None)
        if run_times is not None:
            if len(run_times) != len(preds):  # evaluate_batch checks it only when the rule applies
                raise ValueError(f"expected {len(preds)} run_times, got {len(run_times)}")
            self.late += tusimple.late_count([float(v) for v in run_times])
        sums = tusimple_update(self._sums(), per_image)
        for name in self._FLOATS:
            getattr(self, f"{name}_sum").fill_(getattr(sums, name))
        for name in self._INTS:
            getattr(self, name).fill_(getattr(sums, name))

    def compute(self) -> dict[str, torch.Tensor]:
        """``accuracy``, ``fp``, ``fn``, ``f1`` (paper), ``lane_precision``, ``lane_recall``, ``lane_f1`` and
        ``late`` (int64: images over 200 ms).

        Warns:
            UserWarning: once per call, when the 200 ms rule scored images as missed.
        """
        out = {k: torch.tensor(v, dtype=torch.float64) for k, v in tusimple_compute(self._sums()).items()}
        late = int(self.late)
        if late and self.time_limit:
            warnings.warn(
                tusimple.late_message(late, int(self.images), "TuSimpleMetric(time_limit=False)"), stacklevel=2
            )
        out["late"] = torch.tensor(late, dtype=torch.int64)
        return out


class CULaneMetric(_LaneCountMetric):
    """CULane / ApolloScape area metric (official C++ tool or lanedet) at one or more IoU thresholds.

    Args:
        iou_thresholds: TP when the matched IoU is strictly greater.
        width: line thickness in pixels.
        size: image ``(H, W)``; ``update(..., sizes=...)`` may give each image its own.
        variant: ``"official"`` or ``"lanedet"``.
    """

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
        self._add_count_states(iou_thresholds)
        self.width = int(width)
        self.size = (int(size[0]), int(size[1]))
        self.variant = variant

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
        _add_counts((self.tp, self.fp, self.fn), (r.counts for r in per_image), self.iou_thresholds)
        self.images += len(per_image)

    def compute(self) -> dict[str, torch.Tensor]:
        """``{f"precision@{t}", f"recall@{t}", f"f1@{t}", f"tp@{t}", f"fp@{t}", f"fn@{t}"}`` for each threshold."""
        return self._counts_out()


def _sequence_key(name: Hashable) -> int:
    """A sequence's name as an int64 every process computes alike (a tensor state cannot hold strings)."""
    digest = hashlib.blake2b(repr(name).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little", signed=True)


def _name(sequence: Hashable) -> Hashable:
    """A sequence name as a plain value: a one-element tensor (as a collate function makes it) becomes its item."""
    return sequence.item() if isinstance(sequence, torch.Tensor) else sequence


_FrameInput = tuple[Hashable, list[np.ndarray], list[np.ndarray], tuple[int, int] | None]
"""One checked frame: its sequence, predicted lanes, annotated lanes, ``(H, W)`` or None (the metric's size)."""


def _frames(
    preds: Sequence[Sequence[object]],
    target: Sequence[Sequence[object]],
    sequences: Sequence[Hashable] | None,
    sizes: Sequence[tuple[int, int]] | None,
) -> list[_FrameInput]:
    n = len(preds)
    if len(target) != n:
        raise ValueError(f"got {n} prediction frames and {len(target)} target frames")
    if sequences is not None and len(sequences) != n:
        raise ValueError(f"got {len(sequences)} sequence names for {n} frames")
    if sizes is not None and len(sizes) != n:
        raise ValueError(f"got {len(sizes)} sizes for {n} frames")
    return [
        (
            "" if sequences is None else _name(sequences[i]),
            [_to_numpy(x) for x in preds[i]],
            [_to_numpy(x) for x in target[i]],
            None if sizes is None else (int(sizes[i][0]), int(sizes[i][1])),
        )
        for i in range(n)
    ]


class _SequenceMetric(Metric):
    """What the metrics of sequences share: ``update`` takes frames with the sequence of each, checks them
    (`_frames`) and hands them to ``_add_frames``."""

    def update(
        self,
        preds: Sequence[Sequence[object]],
        target: Sequence[Sequence[object]],
        sequences: Sequence[Hashable] | None = None,
        sizes: Sequence[tuple[int, int]] | None = None,
    ) -> None:
        """Add frames, in time order within each sequence.

        Args:
            preds: per frame, predicted lanes, each ``(N, 2)`` ``(x, y)`` in original pixels (array or tensor).
            target: per frame, annotated lanes, same form.
            sequences: per frame, the name of its sequence (default: one sequence).
            sizes: per frame ``(H, W)``; default ``size``.
        """
        self._add_frames(_frames(preds, target, sequences, sizes))

    @abstractmethod
    def _add_frames(self, frames: list[_FrameInput]) -> None:
        """Add checked frames, `_FrameInput` each."""


class VideoMetric(_SequenceMetric, _LaneCountMetric):
    """mIoU and F@t as MMA-Net computes them for VIL-100 (:mod:`stamlane_eval.video`).

    ``update`` takes frames in time order with the sequence each belongs to; the mIoU is averaged per sequence,
    then over sequences, so every frame's value is kept (a ``"cat"`` state: under DDP each process may hold any
    frames of any sequence). F sums TP/FP/FN.

    Args:
        iou_thresholds: TP when the matched IoU is strictly greater.
        size: image ``(H, W)``; ``update(..., sizes=...)`` may give each frame its own.
    """

    # the states (add_state) besides the counts: "cat" lists of (n,) tensors
    frame_miou: list[torch.Tensor]
    frame_sequence: list[torch.Tensor]

    def __init__(
        self,
        iou_thresholds: Sequence[float] = video.VIDEO_IOU_THRESHOLDS,
        size: tuple[int, int] = culane.CULANE_SIZE,
        **kwargs: object,
    ) -> None:
        super().__init__(**kwargs)
        self._add_count_states(iou_thresholds)
        self.size = (int(size[0]), int(size[1]))
        self.add_state("frame_miou", default=[], dist_reduce_fx="cat")
        self.add_state("frame_sequence", default=[], dist_reduce_fx="cat")

    def _add_frames(self, frames: list[_FrameInput]) -> None:
        per_frame, mious, keys = [], [], []
        for i, (seq, p, g, size) in enumerate(frames):
            try:
                r = culane.evaluate_image(p, g, self.iou_thresholds, culane.LANE_WIDTH, size or self.size, "official")
            except ValueError as e:
                raise ValueError(f"sequence {seq!r}, frame {i} of this update: {e}") from None
            per_frame.append(r.counts)
            mious.append(video.frame_miou(r))
            keys.append(_sequence_key(seq))
        _add_counts((self.tp, self.fp, self.fn), per_frame, self.iou_thresholds)
        self.images += len(mious)
        if mious:
            self.frame_miou.append(torch.tensor(mious, dtype=torch.float64, device=self.tp.device))
            self.frame_sequence.append(torch.tensor(keys, dtype=torch.int64, device=self.tp.device))

    def compute(self) -> dict[str, torch.Tensor]:
        """``{"miou", f"f1@{t}", f"precision@{t}", f"recall@{t}", f"tp@{t}", f"fp@{t}", f"fn@{t}"}``."""
        per_sequence: dict[int, list[float]] = {}
        if int(self.images):
            keys = dim_zero_cat(self.frame_sequence).tolist()
            for key, value in zip(keys, dim_zero_cat(self.frame_miou).tolist(), strict=True):
                per_sequence.setdefault(key, []).append(value)
        # frames of a sequence in the order they came; no list is empty, so no mIoU is None
        mious = [m for m in map(sequence_miou, per_sequence.values()) if m is not None]
        return {"miou": torch.tensor(dataset_miou(mious), dtype=torch.float64), **self._counts_out()}


class TemporalStabilityMetric(_SequenceMetric):
    """RVLD's temporal stability (:mod:`stamlane_eval.temporal`): Ns, Nj, Nm summed, Rs, Rj, Rm from the sums.

    ``update`` takes frames in time order with the sequence each belongs to. The metric keeps the last frame of
    every sequence it has seen (on this process, until ``reset``), so a sequence may arrive over many updates: a
    frame pairs with the previous frame of its sequence. Under DDP give each process whole sequences, or runs of
    consecutive frames (a pair split between two processes is not counted); the counts of the processes sum.
    ``forward`` only updates (a batch of frames has no stability of its own) and returns None.

    Args:
        iou_thresholds: thresholds T of Stable / Jump / Missing.
        size: image ``(H, W)`` (vil100); ``update(..., sizes=...)`` may give each frame its own.
        protocol: ``"vil100"`` or ``"openlane-v"`` (lanes in 1920x1280 pixels; ``size`` is not used).
    """

    full_state_update = False
    higher_is_better = None  # Rs up, Rj and Rm down
    # the states (add_state): (k,) int64 counts per threshold, 0-d int64 images and pairs
    ns: torch.Tensor
    nj: torch.Tensor
    nm: torch.Tensor
    images: torch.Tensor
    pairs: torch.Tensor

    def __init__(
        self,
        iou_thresholds: Sequence[float] = temporal.TEMPORAL_IOU_THRESHOLDS,
        size: tuple[int, int] | None = culane.CULANE_SIZE,
        protocol: str = "vil100",
        **kwargs: object,
    ) -> None:
        super().__init__(**kwargs)
        if protocol not in temporal.PROTOCOLS:
            raise ValueError(f"protocol must be one of {temporal.PROTOCOLS}, got {protocol!r}")
        self.iou_thresholds = tuple(float(t) for t in iou_thresholds)
        self.size = None if size is None or protocol == "openlane-v" else (int(size[0]), int(size[1]))
        self.protocol = protocol
        _add_sum_states(self, ("ns", "nj", "nm"), len(self.iou_thresholds), ("images", "pairs"))
        self._last: dict[Hashable, temporal.TemporalFrame] = {}

    def _add_frames(self, frames: list[_FrameInput]) -> None:
        per_pair = []
        for i, (seq, p, g, size) in enumerate(frames):
            prev = self._last.get(seq)
            try:
                frame = temporal.evaluate_frame(p, g, size or self.size, self.protocol)
                c = None if prev is None else temporal.evaluate_pair(prev, frame, self.iou_thresholds)
            except ValueError as e:
                raise ValueError(f"sequence {seq!r}, frame {i} of this update: {e}") from None
            if c is not None:
                per_pair.append(c)
            self._last[seq] = frame
        _add_counts((self.ns, self.nj, self.nm), per_pair, self.iou_thresholds)
        self.images += len(frames)
        self.pairs += len(per_pair)

    def forward(self, *args: Any, **kwargs: Any) -> None:
        self.update(*args, **kwargs)

    def reset(self) -> None:
        super().reset()
        self._last = {}

    def compute(self) -> dict[str, torch.Tensor]:
        """``{f"rs@{t}", f"rj@{t}", f"rm@{t}"}`` (NaN when nothing was counted) and ``{f"ns@{t}", f"nj@{t}",
        f"nm@{t}"}`` for each threshold."""
        out = {}
        for i, t in enumerate(self.iou_thresholds):
            c = temporal.StabilityCounts(int(self.ns[i]), int(self.nj[i]), int(self.nm[i]))
            for name in ("rs", "rj", "rm"):
                out[metric_key(name, t)] = torch.tensor(getattr(c, name), dtype=torch.float64)
            for name in ("ns", "nj", "nm"):
                out[metric_key(name, t)] = torch.tensor(getattr(c, name), dtype=torch.int64)
        return out
