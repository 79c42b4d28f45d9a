"""A Lightning callback that scores the lanes a LightningModule predicts, with the official metrics."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import lightning.pytorch as pl
import numpy as np
import torch

from stamlane_eval import culane as _culane
from stamlane_eval import temporal as _temporal
from stamlane_eval import video as _video
from stamlane_eval.integrations.distributed import broadcast_from_zero, gather_records, is_distributed, rank
from stamlane_eval.integrations.torchmetrics import CULaneMetric, TemporalStabilityMetric, TuSimpleMetric, VideoMetric
from stamlane_eval.names import CULANE, TEMPORAL, TUSIMPLE, VIDEO, metric_key, metric_name
from stamlane_eval.tusimple import lanes_to_xs
from stamlane_eval.tusimple import late_message as tusimple_late_message

__all__ = ["LaneEvalCallback"]

_KEYS = ("pred_lanes", "gt_lanes", "h_samples", "orig_size")


def _lanes(lanes: Sequence[object]) -> list[np.ndarray]:
    out = []
    for lane in lanes:
        arr = lane.detach().cpu().double().numpy() if isinstance(lane, torch.Tensor) else np.asarray(lane, float)
        out.append(arr.reshape(-1, 2))
    return out


class LaneEvalCallback(pl.Callback):
    """Score validation (and test) predictions with the TuSimple and CULane metrics and log them.

    Contract with the LightningModule: ``validation_step`` (and ``test_step``) returns a dict with, per image
    of the batch (lists of equal length):

    - ``pred_lanes``: list of ``(N, 2)`` float arrays/tensors, ``(x, y)`` in original-image pixels;
    - ``gt_lanes``: the same for the ground truth;
    - ``h_samples``: ``list[int]`` (TuSimple rows) or ``None``;
    - ``orig_size``: ``(H, W)`` of the original image;
    - ``run_time`` (optional): milliseconds per image (TuSimple scores images over 200 ms as missed where
      ``tusimple_time_limit`` applies the rule: by default in the test stage only); their count is logged as
      ``{prefix}/tusimple_late`` and, the first time the rule scores any, one warning says so;
    - ``sequence`` (needed by ``video`` and ``temporal``): per image, the name of the sequence it is a frame of;
      the frames of a sequence must come in time order (in the order of the keys);
    - ``image_id`` (optional): per image, its index in the split (any sortable key naming one image).

    Several processes (DDP): every image is scored once and in the order of the split, so the logged numbers are
    one process's to the last bit, whatever the number of processes. The images' records are kept until the epoch
    ends, gathered on process 0 in the order of their ``image_id`` (without one: each process's n-th image is the
    split's ``n * world_size + rank``-th, the order of PyTorch's and Lightning's strided samplers), scored there with
    the metrics (not synchronised: they see every image) and the numbers sent to every process; an image that comes
    twice (a sampler that pads its shards) is refused (`stamlane_eval.integrations.distributed.RepeatedImageError`)
    rather than scored twice. Give each process a non-repeating sampler.

    TuSimple metrics use images with ``h_samples`` only (lanes are converted with
    :func:`stamlane_eval.tusimple.lanes_to_xs`, gt included: gaps inside a gt lane become interpolated rows).
    The CULane metric draws each image at ``culane_size`` if given, else at the image's ``orig_size``.

    At epoch end it logs ``{prefix}/tusimple_accuracy``, ``{prefix}/tusimple_fp``, ``{prefix}/tusimple_fn``,
    ``{prefix}/tusimple_f1`` (the paper's F1), ``{prefix}/tusimple_late`` (images over 200 ms),
    ``{prefix}/culane_f1@0.5``, ``{prefix}/culane_precision@0.5``,
    ``{prefix}/culane_recall@0.5`` (and the same @0.3, ... for every threshold) through ``pl_module.log``.
    With ``video``:
    ``{prefix}/video_miou``, ``{prefix}/video_f1@0.5`` (and precision, recall, at every ``video_iou_thresholds``)
    as MMA-Net computes them; with ``temporal``: ``{prefix}/temporal_rs@0.5``, ``{prefix}/temporal_rj@0.5``,
    ``{prefix}/temporal_rm@0.5`` (and @0.8) as RVLD's script. ``prefix`` is ``"val"`` for validation; the test
    stage logs under ``test_prefix`` (``"test"``). Metrics with no image (temporal: no lane matched across a
    pair) are not logged.

    Args:
        tusimple: compute the TuSimple metrics.
        culane: compute the CULane area metric.
        culane_size: ``(H, W)`` to draw every image at, or None for each image's ``orig_size``.
        iou_thresholds: CULane IoU thresholds.
        width: CULane line width in pixels.
        prefix: log-name prefix of the validation stage.
        test_prefix: log-name prefix of the test stage.
        variant: CULane variant, ``"official"`` or ``"lanedet"``.
        video: compute mIoU and F as MMA-Net (needs ``sequence``).
        temporal: compute RVLD's Rs / Rj / Rm (needs ``sequence``).
        video_iou_thresholds: thresholds of the video F and of Stable / Jump / Missing.
        temporal_protocol: ``"vil100"`` or ``"openlane-v"``.
        tusimple_time_limit: where TuSimple's 200 ms rule (lane.py's) applies: ``"test"`` (default) in the test
            stage only, so that validation, and the best checkpoint chosen by it, does not depend on the machine's
            speed or load; ``True`` in both stages; ``False`` in neither (every image scored on its lanes). The count
            of images over 200 ms is logged in both stages (``{prefix}/tusimple_late``) whenever run times are given.
    """

    def __init__(
        self,
        tusimple: bool = True,
        culane: bool = True,
        culane_size: tuple[int, int] | None = None,
        iou_thresholds: Sequence[float] = _culane.IOU_THRESHOLDS,
        width: int = _culane.LANE_WIDTH,
        prefix: str = "val",
        test_prefix: str = "test",
        variant: str = "official",
        video: bool = False,
        temporal: bool = False,
        video_iou_thresholds: Sequence[float] = _video.VIDEO_IOU_THRESHOLDS,
        temporal_protocol: str = "vil100",
        tusimple_time_limit: bool | Literal["test"] = "test",
    ) -> None:
        super().__init__()
        if culane_size is not None and (len(culane_size) != 2 or min(culane_size) <= 0):
            raise ValueError(f"culane_size must be (H, W) or None, got {culane_size!r}")
        self.use_tusimple = tusimple
        self.use_culane = culane
        self.culane_size = None if culane_size is None else (int(culane_size[0]), int(culane_size[1]))
        self.prefix = prefix
        self.test_prefix = test_prefix
        if tusimple_time_limit not in (True, False, "test"):
            raise ValueError(f"tusimple_time_limit must be true, false or 'test', got {tusimple_time_limit!r}")
        self.tusimple_time_limit = tusimple_time_limit
        self.tusimple_metric = TuSimpleMetric(time_limit=tusimple_time_limit is True, sync_on_compute=False)
        self._late_warned = False  # the 200 ms rule is said once per callback, not every validation
        self.culane_metric = CULaneMetric(
            iou_thresholds, width, self.culane_size or _culane.CULANE_SIZE, variant=variant, sync_on_compute=False
        )
        self.use_video = video
        self.use_temporal = temporal
        size = self.culane_size or _culane.CULANE_SIZE
        # every image is scored on process 0 (`_log`): the metrics see them all and are never synchronised
        self.video_metric = VideoMetric(video_iou_thresholds, size, sync_on_compute=False)
        self.temporal_metric = TemporalStabilityMetric(
            video_iou_thresholds, size, protocol=temporal_protocol, sync_on_compute=False
        )
        # (key, one image's inputs) of this epoch: the key and the values are the step's (any sortable key)
        self._records: list[tuple[Any, dict[str, Any]]] = []

    # ---------------------------------------------------------------------------------------- hooks
    def on_validation_epoch_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self._reset(pl_module)

    on_test_epoch_start = on_validation_epoch_start  # the test stage scores exactly as validation does

    def on_validation_batch_end(
        self,
        trainer: pl.Trainer,
        pl_module: pl.LightningModule,
        outputs: object,
        batch: object,
        batch_idx: int,
        dataloader_idx: int = 0,
    ) -> None:
        self._keep(outputs)

    on_test_batch_end = on_validation_batch_end

    def on_validation_epoch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if trainer.sanity_checking:
            self._reset(pl_module)
            return
        self._log(pl_module, self.prefix)

    def on_test_epoch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self._log(pl_module, self.test_prefix)

    # -------------------------------------------------------------------------------------- helpers
    def _reset(self, pl_module: pl.LightningModule) -> None:
        self._records = []
        for m in self._metrics():
            m.to(pl_module.device)  # states must live where the process group reduces (NCCL: the GPU)
            m.reset()

    def _metrics(self) -> tuple[TuSimpleMetric | CULaneMetric | VideoMetric | TemporalStabilityMetric, ...]:
        return self.tusimple_metric, self.culane_metric, self.video_metric, self.temporal_metric

    def _keep(self, outputs: object) -> None:
        """Check one batch's dict and keep its images' records (scored when the epoch ends, `_log`)."""
        if not isinstance(outputs, Mapping) or any(k not in outputs for k in _KEYS):
            have = sorted(outputs) if isinstance(outputs, Mapping) else type(outputs).__name__
            raise ValueError(f"LaneEvalCallback needs the step to return a dict with keys {list(_KEYS)}, got {have}")
        n = len(outputs["pred_lanes"])
        lists = {k: outputs[k] for k in (*_KEYS, "run_time", "sequence", "image_id") if outputs.get(k) is not None}
        if any(len(v) != n for v in lists.values()):
            said = ", ".join(f"{k} {len(v)}" for k, v in lists.items())
            raise ValueError(f"LaneEvalCallback: per-image lists differ in length: {said}")
        if (self.use_video or self.use_temporal) and "sequence" not in lists:
            raise ValueError("LaneEvalCallback(video/temporal) needs 'sequence' per image in the step's dict, got none")
        ids = lists.get("image_id")
        for i in range(n):
            # without image_id: the n-th image of this process is the split's n * world + rank (strided samplers)
            key = _key(ids[i]) if ids is not None else (len(self._records), rank())
            record = {k: v[i] for k, v in lists.items() if k != "image_id"}
            record["pred_lanes"], record["gt_lanes"] = _lanes(record["pred_lanes"]), _lanes(record["gt_lanes"])
            self._records.append((key, record))

    def _score(self, records: list[dict[str, Any]]) -> None:
        """Update the metrics with every image's record, in the order given (that of the split)."""
        n = len(records)
        preds = [r["pred_lanes"] for r in records]
        gts = [r["gt_lanes"] for r in records]
        h_samples = [r["h_samples"] for r in records]
        sizes = [r["orig_size"] for r in records]
        timed = n > 0 and all("run_time" in r for r in records)
        run_times = [r["run_time"] for r in records] if timed else None
        if self.use_tusimple:
            idx = [i for i in range(n) if h_samples[i] is not None]
            if idx:
                hs = [[float(v) for v in h_samples[i]] for i in idx]
                self.tusimple_metric.update(
                    [lanes_to_xs(preds[i], h) for i, h in zip(idx, hs, strict=True)],
                    [lanes_to_xs(gts[i], h) for i, h in zip(idx, hs, strict=True)],
                    hs,
                    None if run_times is None else [float(run_times[i]) for i in idx],
                )
        if self.use_culane and n:
            per_image = None if self.culane_size is not None else [(int(s[0]), int(s[1])) for s in sizes]
            self.culane_metric.update(preds, gts, per_image)
        if (self.use_video or self.use_temporal) and n:
            sequences = [r["sequence"] for r in records]
            per_image = [self.culane_size or (int(s[0]), int(s[1])) for s in sizes]
            if self.use_video:
                self.video_metric.update(preds, gts, sequences, per_image)
            if self.use_temporal:
                self.temporal_metric.update(preds, gts, sequences, per_image)

    def _log(self, pl_module: pl.LightningModule, prefix: str) -> None:
        records = [record for _, record in gather_records(self._records, f"{prefix} scores")]
        self._records = []
        values = broadcast_from_zero(self._values(records, prefix) if rank() == 0 else None)
        assert values is not None  # process 0's numbers, on every process
        for name, value in values.items():
            if is_distributed():  # the same number on every process: max gives it back exactly (mean may not)
                pl_module.log(name, value, sync_dist=True, reduce_fx="max")
            else:
                pl_module.log(name, value)

    def _values(self, records: list[dict[str, Any]], prefix: str) -> dict[str, float]:
        """The logged numbers of every image's record (process 0), ``{log name: value}``."""
        limit = self.tusimple_time_limit
        self.tusimple_metric.time_limit = limit is True or (limit == "test" and prefix == self.test_prefix)
        self._score(records)
        out: dict[str, float] = {}

        def put(metric: str, quantity: str, vals: Mapping[str, torch.Tensor], threshold: float | None = None) -> None:
            out[metric_name(metric, quantity, threshold, stage=prefix)] = float(vals[metric_key(quantity, threshold)])

        images = int(self.tusimple_metric.images) if self.use_tusimple else 0
        if images:
            with warnings.catch_warnings():  # the metric's own warning names its switch; this one names ours
                warnings.simplefilter("ignore", UserWarning)
                vals = self.tusimple_metric.compute()
            for name in ("accuracy", "fp", "fn", "f1", "late"):
                put(TUSIMPLE, name, vals)
            late = int(vals["late"])
            if late and self.tusimple_metric.time_limit and not self._late_warned:
                self._late_warned = True
                switch = "LaneEvalCallback(tusimple_time_limit=False)"
                warnings.warn(f"{prefix}: {tusimple_late_message(late, images, switch)}", stacklevel=3)
        if self.use_culane and int(self.culane_metric.images):
            vals = self.culane_metric.compute()
            for t in self.culane_metric.iou_thresholds:
                for name in ("f1", "precision", "recall"):
                    put(CULANE, name, vals, t)
        if self.use_video and int(self.video_metric.images):
            vals = self.video_metric.compute()
            put(VIDEO, "miou", vals)
            for t in self.video_metric.iou_thresholds:
                for name in ("f1", "precision", "recall"):
                    put(VIDEO, name, vals, t)
        if self.use_temporal and int(self.temporal_metric.images):
            vals = self.temporal_metric.compute()
            for t in self.temporal_metric.iou_thresholds:
                if not _temporal.StabilityCounts(*(int(vals[metric_key(k, t)]) for k in ("ns", "nj", "nm"))).total:
                    continue  # no lane matched across a pair: Rs, Rj, Rm are 0/0
                for name in ("rs", "rj", "rm"):
                    put(TEMPORAL, name, vals, t)
        for m in self._metrics():
            m.reset()
        return out


def _key(value: object) -> object:
    """An image key as a plain value (a one-element tensor, as a collate function may make it, becomes its item)."""
    return value.item() if isinstance(value, torch.Tensor) else value
