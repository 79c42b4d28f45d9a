"""A Lightning callback that scores the lanes a LightningModule predicts, with the official metrics."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import lightning.pytorch as pl
import numpy as np
import torch

from stamlane_eval import culane as _culane
from stamlane_eval import temporal as _temporal
from stamlane_eval import video as _video
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
    - ``run_time`` (optional): milliseconds per image (TuSimple scores images over 200 ms as missed, unless
      ``tusimple_time_limit=False``; their count is logged as ``{prefix}/tusimple_late`` and, the first time the
      rule scores any, one warning says so);
    - ``sequence`` (needed by ``video`` and ``temporal``): per image, the name of the sequence it is a frame of;
      the frames of a sequence must come in time order (within this process: see
      :class:`~stamlane_eval.integrations.torchmetrics.TemporalStabilityMetric` for DDP).

    TuSimple metrics use images with ``h_samples`` only (lanes are converted with
    :func:`stamlane_eval.tusimple.lanes_to_xs`, gt included: gaps inside a gt lane become interpolated rows).
    The CULane metric draws each image at ``culane_size`` if given, else at the image's ``orig_size``.

    At epoch end it logs ``{prefix}/tusimple_accuracy``, ``{prefix}/tusimple_fp``, ``{prefix}/tusimple_fn``,
    ``{prefix}/tusimple_f1`` (the paper's F1), ``{prefix}/tusimple_late`` (images over 200 ms),
    ``{prefix}/culane_f1@0.5``, ``{prefix}/culane_precision@0.5``,
    ``{prefix}/culane_recall@0.5`` (and the same @0.3, ... for every threshold) through ``pl_module.log``;
    the sums are synchronised across processes by the torchmetrics states. With ``video``:
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
        tusimple_time_limit: apply TuSimple's 200 ms rule (lane.py does); False scores every image on its lanes.
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
        tusimple_time_limit: bool = True,
    ) -> None:
        super().__init__()
        if culane_size is not None and (len(culane_size) != 2 or min(culane_size) <= 0):
            raise ValueError(f"culane_size must be (H, W) or None, got {culane_size!r}")
        self.use_tusimple = tusimple
        self.use_culane = culane
        self.culane_size = None if culane_size is None else (int(culane_size[0]), int(culane_size[1]))
        self.prefix = prefix
        self.test_prefix = test_prefix
        self.tusimple_metric = TuSimpleMetric(time_limit=tusimple_time_limit)
        self._late_warned = False  # the 200 ms rule is said once per callback, not every validation
        self.culane_metric = CULaneMetric(
            iou_thresholds, width, self.culane_size or _culane.CULANE_SIZE, variant=variant
        )
        self.use_video = video
        self.use_temporal = temporal
        size = self.culane_size or _culane.CULANE_SIZE
        self.video_metric = VideoMetric(video_iou_thresholds, size)
        self.temporal_metric = TemporalStabilityMetric(video_iou_thresholds, size, protocol=temporal_protocol)

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
        self._update(outputs)

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
        for m in self._metrics():
            m.to(pl_module.device)  # states must live where the process group reduces (NCCL: the GPU)
            m.reset()

    def _metrics(self) -> tuple[TuSimpleMetric | CULaneMetric | VideoMetric | TemporalStabilityMetric, ...]:
        return self.tusimple_metric, self.culane_metric, self.video_metric, self.temporal_metric

    def _update(self, outputs: object) -> None:
        if not isinstance(outputs, Mapping) or any(k not in outputs for k in _KEYS):
            have = sorted(outputs) if isinstance(outputs, Mapping) else type(outputs).__name__
            raise ValueError(f"LaneEvalCallback needs the step to return a dict with keys {list(_KEYS)}, got {have}")
        preds = [_lanes(p) for p in outputs["pred_lanes"]]
        gts = [_lanes(g) for g in outputs["gt_lanes"]]
        n = len(preds)
        h_samples, sizes = outputs["h_samples"], outputs["orig_size"]
        run_times = outputs.get("run_time")
        if len(gts) != n or len(h_samples) != n or len(sizes) != n or (run_times is not None and len(run_times) != n):
            raise ValueError(
                f"LaneEvalCallback: per-image lists differ in length: pred_lanes {n}, gt_lanes {len(gts)}, "
                f"h_samples {len(h_samples)}, orig_size {len(sizes)}"
            )
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
        if self.use_culane:
            per_image = None if self.culane_size is not None else [(int(s[0]), int(s[1])) for s in sizes]
            self.culane_metric.update(preds, gts, per_image)
        if self.use_video or self.use_temporal:
            sequences = outputs.get("sequence")
            if sequences is None or len(sequences) != n:
                got = "none" if sequences is None else f"{len(sequences)} for {n} images"
                raise ValueError(
                    f"LaneEvalCallback(video/temporal) needs 'sequence' per image in the step's dict, got {got}"
                )
            per_image = [self.culane_size or (int(s[0]), int(s[1])) for s in sizes]
            if self.use_video:
                self.video_metric.update(preds, gts, list(sequences), per_image)
            if self.use_temporal:
                self.temporal_metric.update(preds, gts, list(sequences), per_image)

    def _log(self, pl_module: pl.LightningModule, prefix: str) -> None:
        def log(metric: str, quantity: str, vals: Mapping[str, torch.Tensor], threshold: float | None = None) -> None:
            name = metric_name(metric, quantity, threshold, stage=prefix)
            pl_module.log(name, float(vals[metric_key(quantity, threshold)]))

        images = self._image_count(self.tusimple_metric) if self.use_tusimple else 0
        if images:
            with warnings.catch_warnings():  # the metric's own warning names its switch; this one names ours
                warnings.simplefilter("ignore", UserWarning)
                vals = self.tusimple_metric.compute()
            for name in ("accuracy", "fp", "fn", "f1", "late"):
                log(TUSIMPLE, name, vals)
            late = int(vals["late"])
            if late and self.tusimple_metric.time_limit and not self._late_warned:
                self._late_warned = True
                switch = "LaneEvalCallback(tusimple_time_limit=False)"
                warnings.warn(f"{prefix}: {tusimple_late_message(late, images, switch)}", stacklevel=2)
        if self.use_culane and self._image_count(self.culane_metric):
            vals = self.culane_metric.compute()
            for t in self.culane_metric.iou_thresholds:
                for name in ("f1", "precision", "recall"):
                    log(CULANE, name, vals, t)
        if self.use_video and self._image_count(self.video_metric):
            vals = self.video_metric.compute()
            log(VIDEO, "miou", vals)
            for t in self.video_metric.iou_thresholds:
                for name in ("f1", "precision", "recall"):
                    log(VIDEO, name, vals, t)
        if self.use_temporal and self._image_count(self.temporal_metric):
            vals = self.temporal_metric.compute()  # synchronised: every process takes the same branch below
            for t in self.temporal_metric.iou_thresholds:
                if not _temporal.StabilityCounts(*(int(vals[metric_key(k, t)]) for k in ("ns", "nj", "nm"))).total:
                    continue  # no lane matched across a pair: Rs, Rj, Rm are 0/0
                for name in ("rs", "rj", "rm"):
                    log(TEMPORAL, name, vals, t)
        for m in self._metrics():
            m.reset()

    @staticmethod
    def _image_count(metric: TuSimpleMetric | CULaneMetric | VideoMetric | TemporalStabilityMetric) -> int:
        """The images every process saw, summed (every rank must take the same branch before compute's sync)."""
        n = metric.images.clone()
        if torch.distributed.is_available() and torch.distributed.is_initialized():
            torch.distributed.all_reduce(n)
        return int(n)
