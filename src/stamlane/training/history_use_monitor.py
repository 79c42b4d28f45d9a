"""``HistoryUseMonitor``: during validation, how much a multi-frame model's output depends on its history frames.

A network that scores the same with its history frames replaced by copies of the key frame does not read them,
whatever its clip length. This callback runs every validation batch a second time with exactly that probe (the
key frame copied into every history slot, alignment the identity) and logs, at the end of each validation:

- ``val/history_use_f1``: the TuSimple F1 (paper's) with the real history minus with the key frame copied;
- ``val/keycopy_tusimple_f1``: the second of those;
- ``val/history_use_seg_loss``: the segmentation loss with the key frame copied minus with the real history
  (> 0 when the history helps the pixels, a finer signal than F1 early in training);
- ``val/history_prob_change``: the mean absolute change of the lane probability between the two.

So history use can be followed over training steps (``metrics.csv``) and a recipe chosen on it, on validation
data. It costs one more network pass and one more lane decoding per validation image. Single-frame batches are
skipped (nothing logged).
"""

from __future__ import annotations

from typing import Any

import lightning.pytorch as pl
import torch
from lightning.pytorch import Callback
from stamlane_eval.integrations.torchmetrics import TuSimpleMetric
from stamlane_eval.tusimple import lanes_to_xs

from stamlane.training.module import StamLaneModule
from stamlane.types import NET_HOMOGRAPHIES, nameable

__all__ = ["HistoryUseMonitor", "key_copied"]


def key_copied(batch: dict[str, Any]) -> tuple[torch.Tensor, torch.Tensor | None]:
    """The network input of a batch with every history slot holding the key frame.

    Args:
        batch: a collated batch (``frames`` (B, T, 3, H, W), key frame last; ``key_from_hist_net`` (B, T, 3, 3)
            for feature-space alignment).

    Returns:
        ``(frames, key_from_hist_net)``: the key frame repeated T times, (B, T, 3, H, W), and identity
        homographies (or None when the batch has none).
    """
    frames = batch["frames"]
    probe = frames[:, -1:].expand_as(frames).contiguous()
    homs = batch.get(NET_HOMOGRAPHIES)
    if homs is not None:
        homs = torch.eye(3, dtype=homs.dtype, device=homs.device).expand_as(homs).contiguous()
    return probe, homs


@nameable
class HistoryUseMonitor(Callback):
    """Log how much validation scores depend on the history frames (see the module docstring).

    Args:
        prefix: log-name prefix (``"val"``).
    """

    def __init__(self, prefix: str = "val") -> None:
        self.prefix = prefix
        self._reset()

    def _reset(self) -> None:
        self.real, self.copied = TuSimpleMetric(), TuSimpleMetric()
        self.loss_gap = self.prob_change = 0.0
        self.images = self.scored = 0

    def on_validation_epoch_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self._reset()

    @torch.no_grad()
    def on_validation_batch_end(
        self,
        trainer: pl.Trainer,
        pl_module: pl.LightningModule,
        outputs: Any,
        batch: Any,
        batch_idx: int,
        dataloader_idx: int = 0,
    ) -> None:
        if not isinstance(batch, dict) or batch["frames"].shape[1] < 2:
            return
        if not isinstance(pl_module, StamLaneModule):
            raise TypeError(f"HistoryUseMonitor watches a StamLaneModule, got {type(pl_module).__name__}")
        logits, embedding = pl_module(batch["frames"], batch.get(NET_HOMOGRAPHIES))
        probe_logits, probe_embedding = pl_module(*key_copied(batch))
        if "binary" in batch and "instance" in batch:
            real = pl_module.loss(logits, embedding, batch["binary"], batch["instance"])["seg"]
            copied = pl_module.loss(probe_logits, probe_embedding, batch["binary"], batch["instance"])["seg"]
            self.loss_gap += float(copied - real) * len(batch["meta"])
        prob, probe_prob = logits.softmax(1)[:, 1], probe_logits.softmax(1)[:, 1]
        self.prob_change += float((prob - probe_prob).abs().mean(dim=(1, 2)).sum())
        self.images += len(batch["meta"])
        lanes = pl_module.decode(logits, embedding, batch["meta"])
        probe_lanes = pl_module.decode(probe_logits, probe_embedding, batch["meta"])
        scored = [i for i, meta in enumerate(batch["meta"]) if meta.get("h_samples")]
        if not scored:
            return
        rows = [batch["meta"][i]["h_samples"] for i in scored]
        target = [lanes_to_xs(batch["lanes"][i], r) for i, r in zip(scored, rows)]
        self.real.update([lanes_to_xs(lanes[i], r) for i, r in zip(scored, rows)], target, rows)
        self.copied.update([lanes_to_xs(probe_lanes[i], r) for i, r in zip(scored, rows)], target, rows)
        self.scored += len(scored)

    def on_validation_epoch_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if not self.images:
            return
        p = self.prefix
        pl_module.log(f"{p}/history_use_seg_loss", self.loss_gap / self.images)
        pl_module.log(f"{p}/history_prob_change", self.prob_change / self.images)
        if self.scored:
            real, copied = float(self.real.compute()["f1"]), float(self.copied.compute()["f1"])
            pl_module.log(f"{p}/keycopy_tusimple_f1", copied)
            pl_module.log(f"{p}/history_use_f1", real - copied)
