"""``StamLaneModule``: the LightningModule around encoder, fusion and decoder (paper 3, 4.1.2).

Training logs the loss terms separately (``train/loss``, ``train/loss_seg``, ``train/loss_var``,
``train/loss_dist``, ``train/loss_reg``). Validation and test decode lanes with
`stamlane.predict.postprocess.decode_lanes` (numpy, outside any ``forward``) and return the dict that
``stamlane_eval.integrations.lightning.LaneEvalCallback`` reads: ``pred_lanes`` (per image, lanes in
original pixels), ``gt_lanes``, ``h_samples``, ``orig_size``, ``run_time`` (ms per image, network
share of the batch + post-processing) and ``image_id`` (the image's index in its split). ``val/loss`` and
``test/loss`` are the mean of every image's own loss, gathered from every process in the order of the split (one
process's number to the last bit under DDP). ``predict_step`` returns lanes with each sample's meta.

Alignment space: a batch of ``warp="image"`` data holds history frames already warped onto the key frame and
runs ``LaneNet.forward``; a batch of ``warp="feature"`` data also holds ``key_from_hist_net`` (B, T, 3, 3,
network pixels) and runs `stamlane.models.forward_feature_aligned` (every frame encoded once, the history's
deepest features warped), the computation of `stamlane.stream.StreamingPredictor`, in training, validation,
test and prediction alike.

Optimisation (paper 4.1.2): SGD with momentum 0.9 and a poly learning rate ``lr * (1 - step / total)^0.9``
stepped every iteration; ``total`` is the trainer's ``estimated_stepping_batches`` (``max_steps`` when
set), so the schedule length is never written twice; a run resumed with ``--ckpt_path`` and a larger ``max_steps``
follows the new length from the step it resumes at (`PolyLR.load_state_dict`).
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from lightning.pytorch import LightningModule
from lightning.pytorch.utilities import rank_zero_info
from stamlane_eval.integrations.distributed import gather_records, is_distributed
from torch import Tensor, nn
from torch.optim import Optimizer
from torch.optim.lr_scheduler import LRScheduler

from stamlane.data.datamodule import INDEX_KEY
from stamlane.models import LaneNet, forward_feature_aligned
from stamlane.predict.postprocess import PostprocessConfig, decode_lanes
from stamlane.safety.budget import check_clip, check_frames
from stamlane.safety.checkpoints import CheckpointError, read_checkpoint
from stamlane.training.hardware import resolve_bf16
from stamlane.training.lightning_compat import drop_hyperparameters
from stamlane.training.losses import LaneLoss
from stamlane.types import NET_HOMOGRAPHIES, nameable
from stamlane.weights import resolve

__all__ = ["PolyLR", "StamLaneModule", "paper_sgd"]


OptimizerCallable = Callable[[Iterable[Any]], Optimizer]
SchedulerCallable = Callable[[Optimizer, int], LRScheduler]


@nameable
def paper_sgd(params: Iterable[Any]) -> Optimizer:
    """SGD as in the paper: momentum 0.9. The paper's base learning rate was lost from our copy of the text;
    0.05 (with weight decay 5e-4) is the reference LaneNet implementation's (MaybeShewill-CV/lanenet)."""
    return torch.optim.SGD(params, lr=0.05, momentum=0.9, weight_decay=5e-4)


@nameable
class PolyLR(LRScheduler):
    """Poly learning-rate policy: ``base_lr * (1 - step / total_steps) ** power``, stepped every iteration.

    Args:
        optimizer: the wrapped optimizer.
        total_steps: the step at which the learning rate reaches 0 (the run's number of optimizer steps).
        power: the exponent (paper: 0.9).
    """

    def __init__(self, optimizer: Optimizer, total_steps: int, power: float = 0.9) -> None:
        if total_steps < 1:
            raise ValueError(f"total_steps must be >= 1, got {total_steps}")
        self.total_steps = int(total_steps)
        self.power = float(power)
        super().__init__(optimizer)

    def get_lr(self) -> list[float | Tensor]:
        factor = max(0.0, 1.0 - min(self.last_epoch, self.total_steps) / self.total_steps) ** self.power
        return [base_lr * factor for base_lr in self.base_lrs]

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        """Restore the position in the schedule (``last_epoch``, ``base_lrs``) but keep THIS run's length: a run
        resumed with a larger ``max_steps`` follows ``base_lr * (1 - step / new_total) ** power`` from the step it
        resumes at, as a run of ``new_total`` steps from the start would (the checkpoint's length would leave every
        added step at learning rate 0). The optimizer's rates, restored before the schedule, are set anew."""
        total = self.total_steps
        super().load_state_dict(state_dict)
        self.total_steps = total
        self._last_lr = self.get_lr()
        for group, lr in zip(self.optimizer.param_groups, self._last_lr, strict=True):
            group["lr"] = lr


def _is_plain(value: Any) -> bool:
    """True for values a ``weights_only`` checkpoint can hold (yaml-like: numbers, strings, lists, dicts)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return True
    if isinstance(value, (list, tuple)):
        return all(_is_plain(v) for v in value)
    if isinstance(value, dict):
        return all(isinstance(k, str) and _is_plain(v) for k, v in value.items())
    return False


class StamLaneModule(LightningModule):
    """Lane detection on clips: ``LaneNet(encoder, fusion, decoder)`` trained with ``LaneLoss``.

    Args:
        encoder: per-frame encoder with ``out_channels`` (e.g. ``stamlane.models.VGGEncoder``).
        fusion: factory ``fusion(channels) -> module (B, T, C, h, w) -> (B, C, h, w)`` (e.g. ``STAM``).
        decoder: factory ``decoder(encoder.out_channels) -> module`` (e.g. ``LaneDecoder``).
        loss: the loss, ``loss(logits, embedding, binary, instance) -> {"loss", "seg", "var", "dist", "reg"}``.
        optimizer: ``optimizer(params) -> Optimizer``; default `paper_sgd`.
        scheduler: ``scheduler(optimizer, total_steps) -> LRScheduler`` stepped every iteration, or ``None``
            for a constant rate; default `PolyLR` (power 0.9).
        postprocess: options of the lane decoding (DBSCAN, curve fit).
        num_frames: T, frames per clip the network expects (linked from the data); checked on every batch.
        image_size: ``(H, W)`` of the network input (linked from the data); must be multiples of the
            encoder's stride; sets ``example_input_array``.
        crop_top: fraction of the frame height cut off above the network input (linked from ``data.clip.crop_top``);
            recorded so that streaming and export feed the network as it was trained.
        bf16: run the network under ``torch.autocast(dtype=bfloat16)``; losses and decoding stay float32.
            ``"auto"`` (default): where the device the module is on runs bf16 natively (CPU: AMX / AVX512-BF16;
            CUDA: ``torch.cuda.is_bf16_supported``), float32 elsewhere (emulated bf16 is far slower: measured in
            docs/results/timings/); asked again when the module moves (`bf16`); see `stamlane.training.hardware`.
        channels_last: keep conv weights (and so activations) channels_last (faster on CPU with oneDNN).
        report_run_time: hand each image's ``run_time`` to the evaluator (TuSimple scores an image over
            200 ms as missed); False leaves it out, so scores do not depend on the machine's load.
        init_weights: a checkpoint of this module (same network), or a shipped model's name where no file of that
            name is here (`stamlane.weights.resolve`), whose weights start ``fit``: fine-tuning, e.g.
            an image-space model with ``warp="feature"`` data for the streaming predictor. Only the weights
            (optimizer, schedule and step start afresh); read at the start of ``fit``, so a resumed run
            (``--ckpt_path``) keeps its own weights, and loading or testing the result never needs the file.
            The encoder and decoder must fit exactly; a fusion module other than the checkpoint's (another
            aggregator) keeps its own initialisation, which is printed.
        fusion_lr_scale: the fusion modules' learning rate as a multiple of the optimizer's (their own parameter
            group; the schedule scales both alike). A fusion that starts from scratch on a pretrained encoder
            and decoder may need a larger one to catch up (docs/training.md).
        fuse_skip: fuse the second-deepest encoder stage (stride 8) over time too, with a second module of the
            fusion's kind whose output replaces the key frame's skip there (`stamlane.models.LaneNet`).
    """

    def __init__(
        self,
        encoder: nn.Module,
        fusion: Callable[[int], nn.Module],
        decoder: Callable[[Sequence[int]], nn.Module],
        loss: LaneLoss | None = None,
        optimizer: OptimizerCallable = paper_sgd,
        scheduler: SchedulerCallable | None = PolyLR,
        postprocess: PostprocessConfig | None = None,
        num_frames: int | None = None,
        image_size: tuple[int, int] | None = None,
        crop_top: float = 0.0,
        bf16: bool | Literal["auto"] = "auto",
        channels_last: bool = False,
        report_run_time: bool = True,
        init_weights: str | None = None,
        fusion_lr_scale: float = 1.0,
        fuse_skip: bool = False,
    ) -> None:
        super().__init__()
        with warnings.catch_warnings():  # "Attribute 'encoder' is an instance of nn.Module": dropped just below
            warnings.filterwarnings("ignore", message="Attribute .* is an instance of `nn.Module`")
            self.save_hyperparameters()
        # keep only what a weights_only checkpoint can hold (under LightningCLI the hparams are the plain
        # config, which all stays; built objects passed from Python are dropped)
        drop_hyperparameters(self, [k for k, v in self.hparams.items() if not _is_plain(v)])
        if num_frames is not None and num_frames < 1:
            raise ValueError(f"num_frames must be >= 1, got {num_frames}")
        if num_frames is not None:
            check_frames(num_frames, "model num_frames")  # before anything sized by it (a checkpoint's too)
        if image_size is not None:
            check_clip(num_frames or 1, list(image_size), "model")
        self.net = LaneNet(encoder, fusion, decoder, fuse_skip)
        self.loss = loss if loss is not None else LaneLoss()
        self.optimizer_factory = optimizer
        self.scheduler_factory = scheduler
        self.postprocess = postprocess if postprocess is not None else PostprocessConfig()
        self.num_frames = num_frames
        self.crop_top = float(crop_top)
        resolve_bf16(bf16)  # a bad value fails here, at construction
        self.bf16 = bf16
        self.channels_last = channels_last
        self.report_run_time = report_run_time
        self.init_weights = init_weights
        if not fusion_lr_scale > 0:
            raise ValueError(f"fusion_lr_scale must be > 0, got {fusion_lr_scale}")
        self.fusion_lr_scale = float(fusion_lr_scale)
        if image_size is not None:
            stride = int(getattr(encoder, "total_stride", 1))
            height, width = image_size
            if height % stride or width % stride or height <= 0 or width <= 0:
                raise ValueError(
                    f"image_size must be positive multiples of the encoder stride {stride}, got {tuple(image_size)}"
                )
            self.example_input_array = torch.zeros(1, num_frames or 1, 3, height, width)
        if channels_last:
            # torch's stub of Module.to lists no memory_format, which Module.to takes
            self.net.to(memory_format=torch.channels_last)  # type: ignore[call-overload]
        self._eval_losses: list[tuple[Any, float]] = []  # (image key, loss) of this evaluation epoch
        self._eval_seen = 0

    @property
    def bf16(self) -> bool:
        """Whether the network runs under bfloat16 autocast on the device the module is on NOW: ``"auto"`` is
        resolved per device, so a module built on a CPU without native bf16 and trained on a GPU uses it there."""
        return resolve_bf16(self._bf16, self.device.type)

    @bf16.setter
    def bf16(self, value: bool | Literal["auto"]) -> None:
        self._bf16 = value

    def setup(self, stage: str) -> None:
        """Load the encoder's ImageNet weights (``VGGEncoder(weights=...)``), then ``init_weights``, at the start of
        ``fit`` (a resumed checkpoint is restored after this)."""
        load = getattr(self.net.encoder, "load_weights", None)
        if stage == "fit" and load is not None and load():
            rank_zero_info(f"encoder: ImageNet weights from {self.net.encoder.weights}")
        if stage == "fit" and self.init_weights:
            try:
                # a shipped model's name from a config file or a RunSpec too, not only from the command line
                state = read_checkpoint(resolve(self.init_weights))["state_dict"]
            except CheckpointError as err:
                raise CheckpointError(f"init_weights: {err}") from None
            own = self.state_dict()
            for fusion in ("net.fusion.", "net.skip_fusion."):

                def shapes(weights: dict[str, Tensor], prefix: str = fusion) -> dict[str, tuple[int, ...]]:
                    return {k: tuple(v.shape) for k, v in weights.items() if k.startswith(prefix)}

                if shapes(state) == shapes(own):
                    continue
                # another fusion (a row of the paper's tables, or one the checkpoint lacks): it starts afresh
                state = {k: v for k, v in state.items() if not k.startswith(fusion)}
                state |= {k: v for k, v in own.items() if k.startswith(fusion)}
                name = fusion[len("net.") : -1]
                rank_zero_info(
                    f"init_weights: encoder and decoder from {self.init_weights}; the {name} module "
                    f"({type(getattr(self.net, name)).__name__}) differs from the checkpoint's and starts from its "
                    f"own initialisation"
                )
            try:
                self.load_state_dict(state)
            except RuntimeError as err:  # other architecture: missing / unexpected keys, other shapes
                raise ValueError(f"init_weights: {self.init_weights!r} does not fit this network: {err}") from err

    @classmethod
    def from_checkpoint(cls, path: str | Path) -> StamLaneModule:
        """The module stored in a checkpoint, built safely, on the CPU, in eval mode.

        The file is read with ``weights_only=True``; its hyperparameters are checked against the closed registry
        and the network is built from it (`stamlane.training.registry.build_module`): every class is looked up by its
        exact name, nothing named in the file is imported (Lightning's own ``load_from_checkpoint`` would import
        and call whatever the file names).

        Raises:
            CheckpointError: see `stamlane.safety.checkpoints.read_checkpoint` and `stamlane.training.registry.check_hparams`;
                also for hyperparameters that build no stamlane network and for weights of another network.
        """
        from stamlane.training.registry import build_module

        module: StamLaneModule = build_module(read_checkpoint(path), path)  # built from the registry
        return module

    # ------------------------------------------------------------------ network
    def forward(self, clip: Tensor, key_from_hist_net: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """Run the network, the history aligned in image space (pre-aligned clip) or in feature space.

        Args:
            clip: (B, T, 3, H, W) float in [0, 1], key frame last; history pre-aligned when ``key_from_hist_net``
                is None, else unwarped.
            key_from_hist_net: None, or (B, T, 3, 3) homographies history -> key frame in NETWORK pixels (key
                frame last): the history's deepest encoder features are warped with them
                (`stamlane.models.forward_feature_aligned`).

        Returns:
            ``(logits (B, 2, H, W), embedding (B, E, H, W))``, float32.
        """
        if clip.ndim != 5:
            raise ValueError(f"expected a clip of shape (B, T, 3, H, W), got {tuple(clip.shape)}")
        if self.num_frames is not None and clip.shape[1] != self.num_frames:
            raise ValueError(f"expected clips of {self.num_frames} frames, got {clip.shape[1]} ({tuple(clip.shape)})")
        with torch.autocast(device_type=clip.device.type, dtype=torch.bfloat16, enabled=self.bf16):
            if key_from_hist_net is None:
                logits, embedding = self.net(clip)
            else:
                logits, embedding = forward_feature_aligned(self.net, clip, key_from_hist_net)
        return logits.float(), embedding.float()

    def _run(self, batch: dict[str, Any]) -> tuple[Tensor, Tensor]:
        """The network on a batch, in the alignment space of its data (``key_from_hist_net`` present or not)."""
        out: tuple[Tensor, Tensor] = self(batch["frames"], batch.get(NET_HOMOGRAPHIES))
        return out

    def _losses(self, batch: dict[str, Any], logits: Tensor, embedding: Tensor) -> dict[str, Tensor]:
        terms: dict[str, Tensor] = self.loss(logits, embedding, batch["binary"], batch["instance"])
        return terms

    # ------------------------------------------------------------------ steps
    def training_step(self, batch: dict[str, Any], batch_idx: int) -> Tensor:
        logits, embedding = self._run(batch)
        terms = self._losses(batch, logits, embedding)
        size = batch["frames"].shape[0]
        self.log("train/loss", terms["loss"], prog_bar=True, batch_size=size)
        for name in ("seg", "var", "dist", "reg"):
            self.log(f"train/loss_{name}", terms[name], batch_size=size)
        return terms["loss"]

    def decode(self, logits: Tensor, embedding: Tensor, metas: Sequence[dict[str, Any]]) -> list[list[np.ndarray]]:
        """Lanes of each image of a batch, in original pixels (see `stamlane.predict.postprocess.decode_lanes`).

        Args:
            logits: (B, 2, H, W) lane / background logits.
            embedding: (B, E, H, W) pixel embeddings.
            metas: per-sample meta (``net_from_orig``, ``orig_size``, ``h_samples``; see `stamlane.types`).

        Returns:
            per image, its lanes: ``(N, 2)`` ``(x, y)`` float arrays in original pixels.
        """
        prob = logits.detach().float().softmax(dim=1)[:, 1].cpu().numpy()
        emb = embedding.detach().float().cpu().numpy()
        lanes = []
        for i, meta in enumerate(metas):
            orig_from_net = np.linalg.inv(np.asarray(meta["net_from_orig"], dtype=np.float64))
            lanes.append(
                decode_lanes(
                    prob[i],
                    emb[i],
                    orig_from_net,
                    self.postprocess,
                    y_samples=meta.get("h_samples"),
                    orig_size=tuple(meta["orig_size"]),
                )
            )
        return lanes

    def _detect(self, batch: dict[str, Any]) -> tuple[Tensor, Tensor, list[list[np.ndarray]], list[float]]:
        start = time.perf_counter()
        logits, embedding = self._run(batch)
        network_ms = (time.perf_counter() - start) * 1000.0 / max(len(batch["meta"]), 1)
        lanes, run_time = [], []
        for i, meta in enumerate(batch["meta"]):
            start = time.perf_counter()
            lanes += self.decode(logits[i : i + 1], embedding[i : i + 1], [meta])
            run_time.append(network_ms + (time.perf_counter() - start) * 1000.0)
        return logits, embedding, lanes, run_time

    def _eval_step(self, batch: dict[str, Any], stage: str) -> dict[str, Any]:
        logits, embedding, lanes, run_time = self._detect(batch)
        metas = batch["meta"]
        keys = [self._image_key(meta, i) for i, meta in enumerate(metas)]
        if "binary" in batch and "instance" in batch:
            # per image (its own class weights), so that the loss is the images', not the batches' nor the processes'
            for i, key in enumerate(keys):
                one = {"binary": batch["binary"][i : i + 1], "instance": batch["instance"][i : i + 1]}
                terms = self._losses(one, logits[i : i + 1], embedding[i : i + 1])
                self._eval_losses.append((key, float(terms["loss"])))
        self._eval_seen += len(metas)
        return {
            "pred_lanes": lanes,
            "gt_lanes": batch["lanes"],
            "h_samples": [m.get("h_samples") for m in metas],
            "orig_size": [tuple(m["orig_size"]) for m in metas],
            "run_time": run_time if self.report_run_time else None,
            "raw_file": [m.get("raw_file") for m in metas],
            "image_id": keys,
        }

    def _image_key(self, meta: dict[str, Any], i: int) -> Any:
        """An image's key in its split: its index (``meta["index"]``, `stamlane.data.datamodule.Indexed`), else its
        position on this process with the rank (the order of a strided sampler)."""
        index = meta.get(INDEX_KEY)
        return int(index) if index is not None else (self._eval_seen + i, self.global_rank)

    def on_validation_epoch_start(self) -> None:
        self._eval_losses, self._eval_seen = [], 0

    on_test_epoch_start = on_validation_epoch_start

    def on_validation_epoch_end(self) -> None:
        self._log_eval_loss("val")

    def on_test_epoch_end(self) -> None:
        self._log_eval_loss("test")

    def _log_eval_loss(self, stage: str) -> None:
        """Log ``{stage}/loss``: the mean of every image's loss, summed in the order of the split on every process,
        so that it is one process's number to the last bit whatever the number of processes (an image that came
        twice is refused: `stamlane_eval.integrations.distributed.gather_records`)."""
        losses = [loss for _, loss in gather_records(self._eval_losses, f"{stage} losses")]
        self._eval_losses = []
        if not losses:
            return
        mean = sum(losses) / len(losses)
        if is_distributed():  # the same number on every process: max gives it back exactly (mean may not)
            self.log(f"{stage}/loss", mean, sync_dist=True, reduce_fx="max")
        else:
            self.log(f"{stage}/loss", mean)

    def validation_step(self, batch: dict[str, Any], batch_idx: int) -> dict[str, Any]:
        return self._eval_step(batch, "val")

    def test_step(self, batch: dict[str, Any], batch_idx: int) -> dict[str, Any]:
        return self._eval_step(batch, "test")

    def predict_step(self, batch: dict[str, Any], batch_idx: int, dataloader_idx: int = 0) -> list[dict[str, Any]]:
        """Per image: ``{"lanes", "meta", "run_time"}`` (lanes in original pixels, run_time in ms)."""
        _, _, lanes, run_time = self._detect(batch)
        return [
            {"lanes": image_lanes, "meta": meta, "run_time": ms}
            for image_lanes, meta, ms in zip(lanes, batch["meta"], run_time)
        ]

    # ------------------------------------------------------------------ optimisation
    def configure_optimizers(self) -> Any:
        fusion = [*self.net.fusion.parameters(), *(self.net.skip_fusion.parameters() if self.net.skip_fusion else ())]
        if self.fusion_lr_scale == 1.0 or not fusion:
            optimizer = self.optimizer_factory(self.parameters())
        else:
            owned = {id(p) for p in fusion}
            others = [p for p in self.parameters() if id(p) not in owned]
            optimizer = self.optimizer_factory([{"params": others}, {"params": fusion}])
            optimizer.param_groups[1]["lr"] *= self.fusion_lr_scale  # before the schedule reads its base rates
        if self.scheduler_factory is None:
            return optimizer
        total = self.trainer.estimated_stepping_batches
        if not math.isfinite(total):
            raise ValueError("the poly LR schedule needs a finite run: set trainer.max_steps or trainer.max_epochs")
        scheduler = self.scheduler_factory(optimizer, int(total))
        return {"optimizer": optimizer, "lr_scheduler": {"scheduler": scheduler, "interval": "step"}}
