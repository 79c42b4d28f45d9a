"""Adapting a trained model to a user's camera from unlabelled frames (``stamlane adapt``; docs/adapt.md).

Offline self-training with a temporal-consistency filter, in three steps:

1. **Teacher pass**: the model as given, in eval mode, predicts every frame of the user's video or folder as the key
   frame of its own clip (read as ``stamlane predict --source`` reads it: `stamlane.data.frames.FolderClips`, the
   model's clip options, the history pre-aligned by ORB on the fly). Each frame's lane probability is kept.
2. **Pseudo-labels**: for each key frame with a full history, the history frames' probabilities are carried onto
   the key frame by the same ground homographies that pre-align its clip, and a pixel is labelled lane or background
   only where the key frame and its history agree (`stamlane.predict.pseudo_labels`); everything else is ignored
   by the loss. A frame with too few agreed lane pixels is not used.
3. **Student**: the same network fine-tuned for a few hundred steps on batches of pseudo-labelled real clips (the
   binary branch's cross-entropy, ignored pixels left out) mixed with labelled synthetic clips (the full loss), the
   recipe of the shipped ``stam4-dashcam`` (AdamW, the encoder and decoder at a hundredth of the STAM's rate, poly
   decay), with every batch-norm layer's statistics frozen (batch-norm in eval mode: a batch of two real clips
   would otherwise replace the statistics the model was trained with) and the embedding head frozen (the
   pseudo-labels say where lanes are, not which lane a pixel belongs to: the synthetic clips' discriminative loss
   keeps the shared trunk's embeddings what they were).

The result is the input checkpoint with the student's weights and a record of the adaptation (`ADAPT_KEY`): every
command opens it as it opens the input.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor, nn
from tqdm import tqdm

from stamlane.data.clips import ClipDataset
from stamlane.data.transforms import net_homographies
from stamlane.predict.pseudo_labels import IGNORE, PseudoLabelConfig, clip_pseudo_labels
from stamlane.safety.checkpoints import read_checkpoint
from stamlane.safety.guard import atomic_path
from stamlane.training.losses import class_weights
from stamlane.training.module import PolyLR, StamLaneModule

__all__ = [
    "ADAPT_KEY",
    "AdaptConfig",
    "PseudoLabelled",
    "TeacherPass",
    "adapt_student",
    "pseudo_label",
    "teacher_pass",
    "write_adapted",
]

ADAPT_KEY = "stamlane_adaptation"
"""Checkpoint key of the adaptation's record (its settings, the pseudo-labels' statistics, the source's name)."""


@dataclass(frozen=True)
class AdaptConfig:
    """The settings of one adaptation.

    Attributes:
        steps: optimizer steps of the student.
        lr: AdamW learning rate of the encoder and decoder (the shipped ``stam4-dashcam`` recipe's, 0.00002).
        fusion_lr_scale: the fusion modules' rate as a multiple of ``lr`` (the recipe's 100: the STAM at 0.002).
        weight_decay: AdamW weight decay (the recipe's 0.0001).
        real_batch: pseudo-labelled real clips per batch.
        synthetic_batch: labelled synthetic clips per batch (0: none; the model may then forget its training).
        real_weight: weight of the real clips' cross-entropy against the synthetic clips' loss.
        min_lane_pixels: a key frame with fewer agreed lane pixels is not used.
        seed: the draws of the batches (and torch's seed).
        pseudo: when a teacher's probabilities become labels.
    """

    steps: int = 150
    lr: float = 2e-5
    fusion_lr_scale: float = 100.0
    weight_decay: float = 1e-4
    real_batch: int = 2
    synthetic_batch: int = 2
    real_weight: float = 1.0
    min_lane_pixels: int = 50
    seed: int = 0
    pseudo: PseudoLabelConfig = field(default_factory=PseudoLabelConfig)

    def __post_init__(self) -> None:
        if self.steps < 1:
            raise ValueError(f"steps must be >= 1, got {self.steps}")
        if not (self.lr > 0 and math.isfinite(self.lr)):
            raise ValueError(f"lr must be a positive number, got {self.lr}")
        if not (self.fusion_lr_scale > 0 and math.isfinite(self.fusion_lr_scale)):
            raise ValueError(f"fusion_lr_scale must be a positive number, got {self.fusion_lr_scale}")
        if not self.weight_decay >= 0:
            raise ValueError(f"weight_decay must be >= 0, got {self.weight_decay}")
        if self.real_batch < 1 or self.synthetic_batch < 0:
            raise ValueError(
                f"real_batch must be >= 1 and synthetic_batch >= 0, got {self.real_batch}, {self.synthetic_batch}"
            )
        if not (self.real_weight > 0 and math.isfinite(self.real_weight)):
            raise ValueError(f"real_weight must be a positive number, got {self.real_weight}")
        if self.min_lane_pixels < 1:
            raise ValueError(f"min_lane_pixels must be >= 1, got {self.min_lane_pixels}")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class TeacherPass:
    """What the teacher saw: every sample's network clip and each frame's lane probability.

    Attributes:
        clips: uint8 ``(N, T, 3, H, W)``: each sample's clip as the network reads it (history pre-aligned).
        probs: float32 ``(N, H, W)``: the teacher's lane probability of each sample's key frame.
        key_from_hist: float64 ``(N, T, 3, 3)``: each sample's history -> key frame, NETWORK pixels.
        frames: ``(N, T)``: the sample index of each frame of each clip (key frame last), so that ``probs[frames[i,
            j]]`` is frame ``j`` of clip ``i`` predicted as a key frame of its own.
        names: the key frames' names.
    """

    clips: Tensor
    probs: np.ndarray
    key_from_hist: np.ndarray
    frames: np.ndarray
    names: list[str]


@dataclass
class PseudoLabelled:
    """The real clips the student trains on.

    Attributes:
        clips: uint8 ``(M, T, 3, H, W)``.
        labels: int64 ``(M, H, W)``: 1 lane, 0 background, `IGNORE` elsewhere.
        names: their key frames' names.
        stats: how many frames were labelled and kept, and the shares of lane, background and ignored pixels.
    """

    clips: Tensor
    labels: Tensor
    names: list[str]
    stats: dict[str, Any]


def _to_uint8(frames: Tensor) -> Tensor:
    return (frames.clamp(0.0, 1.0) * 255.0).round().to(torch.uint8)


def teacher_pass(module: StamLaneModule, dataset: ClipDataset, batch: int = 4, progress: bool = True) -> TeacherPass:
    """Predict every sample of ``dataset`` with ``module`` as it is (eval mode, no gradient).

    Args:
        module: the teacher.
        dataset: the user's frames, each the key frame of a clip of its predecessors (`FolderClips`; every
            sample's key frame is a frame of the folder, and its history frames are other samples' key frames).
        batch: clips per forward pass.
        progress: show a progress bar.

    Returns:
        the clips, the probabilities and the homographies (`TeacherPass`).
    """
    module.eval()
    position = {entry.frame_paths[-1]: i for i, entry in enumerate(dataset.entries)}
    clips, probs, homs, frames, names = [], [], [], [], []
    order = range(0, len(dataset), batch)
    with torch.no_grad():
        for start in tqdm(order, desc="teacher", unit="batch", disable=not progress):
            samples = [dataset[i] for i in range(start, min(start + batch, len(dataset)))]
            clip = torch.stack([s["frames"] for s in samples])
            logits, _ = module(clip)
            probs.append(logits.softmax(dim=1)[:, 1].numpy().astype(np.float32))
            clips.append(_to_uint8(clip))
            for sample in samples:
                meta = sample["meta"]
                net_from_orig = np.asarray(meta["net_from_orig"], dtype=np.float64)
                homs.append(net_homographies(sample["key_from_hist"].numpy(), net_from_orig))
                frames.append([position.get(p, -1) for p in meta["frame_paths"]])
                names.append(str(meta["raw_file"]))
    return TeacherPass(
        torch.cat(clips), np.concatenate(probs), np.stack(homs), np.asarray(frames, dtype=np.int64), names
    )


def pseudo_label(seen: TeacherPass, config: AdaptConfig) -> PseudoLabelled:
    """The key frames whose clip agrees on enough lane pixels, with their labels (`clip_pseudo_labels`).

    A key frame whose history is not made of distinct, earlier frames of the source (the first frames of a video,
    whose history repeats the first frame) is not labelled: it would agree with itself.
    """
    keep, labels, counts = [], [], np.zeros(3, dtype=np.int64)
    for i, index in enumerate(seen.frames):
        if (index < 0).any() or len(set(index.tolist())) != len(index):
            continue
        label = clip_pseudo_labels(seen.probs[index], seen.key_from_hist[i], config.pseudo)
        lane = int((label == 1).sum())
        counts += [lane, int((label == 0).sum()), int((label == IGNORE).sum())]
        if lane >= config.min_lane_pixels:
            keep.append(i)
            labels.append(label)
    full = int(sum((index >= 0).all() and len(set(index.tolist())) == len(index) for index in seen.frames))
    total = max(1, int(counts.sum()))
    stats = {
        "frames": len(seen.frames),
        "with_history": full,
        "kept": len(keep),
        "lane_share": round(float(counts[0]) / total, 5),
        "background_share": round(float(counts[1]) / total, 5),
        "ignored_share": round(float(counts[2]) / total, 5),
    }
    if not keep:
        return PseudoLabelled(seen.clips[:0], torch.zeros((0, *seen.probs.shape[1:]), dtype=torch.int64), [], stats)
    return PseudoLabelled(seen.clips[keep], torch.from_numpy(np.stack(labels)), [seen.names[i] for i in keep], stats)


def _anchor_pool(dataset: ClipDataset, count: int, rng: np.random.Generator, progress: bool) -> dict[str, Tensor]:
    """``count`` labelled samples of ``dataset`` (drawn without replacement), read once: ``frames`` uint8, ``binary``
    and ``instance`` int64."""
    picks = rng.permutation(len(dataset))[: min(count, len(dataset))]
    samples = [dataset[int(i)] for i in tqdm(picks, desc="synthetic clips", unit="clip", disable=not progress)]
    return {
        "frames": torch.stack([_to_uint8(s["frames"]) for s in samples]),
        "binary": torch.stack([s["binary"] for s in samples]),
        "instance": torch.stack([s["instance"] for s in samples]),
    }


def _freeze_statistics(module: nn.Module) -> None:
    """Batch-norm layers in eval mode (their running statistics used and kept), the rest as it is."""
    for layer in module.modules():
        if isinstance(layer, nn.modules.batchnorm._BatchNorm):
            layer.eval()


def _optimizer(module: StamLaneModule, config: AdaptConfig) -> torch.optim.Optimizer:
    net = module.net
    fusion = [*net.fusion.parameters(), *(net.skip_fusion.parameters() if net.skip_fusion else ())]
    owned = {id(p) for p in fusion}
    others = [p for p in module.parameters() if id(p) not in owned and p.requires_grad]
    groups = [{"params": others, "lr": config.lr}]
    if fusion:
        groups.append({"params": fusion, "lr": config.lr * config.fusion_lr_scale})
    return torch.optim.AdamW(groups, lr=config.lr, weight_decay=config.weight_decay)


def real_loss(logits: Tensor, labels: Tensor) -> Tensor:
    """The binary branch's cross-entropy on pseudo-labels: class weights of the labelled pixels (as `LaneLoss`'s
    of a batch), `IGNORE` pixels left out.

    Args:
        logits: ``(B, 2, H, W)``.
        labels: int64 ``(B, H, W)``, 0, 1 or `IGNORE`.
    """
    kept = labels[labels != IGNORE]
    if kept.numel() == 0:
        return logits.sum() * 0.0
    weight = class_weights(kept, 2).to(logits.device)
    return F.cross_entropy(logits.float(), labels, weight=weight, ignore_index=IGNORE)


def adapt_student(
    module: StamLaneModule,
    real: PseudoLabelled,
    synthetic: ClipDataset | None,
    config: AdaptConfig,
    progress: bool = True,
    synthetic_samples: int = 64,
) -> list[dict[str, float]]:
    """Fine-tune ``module`` in place on ``real``'s pseudo-labels mixed with ``synthetic``'s labelled clips.

    Args:
        module: the student (the teacher's weights at the start).
        real: the pseudo-labelled real clips (at least one).
        synthetic: labelled synthetic clips read as the model reads its clips, or None (``synthetic_batch`` 0).
        config: the settings.
        progress: show a progress bar.
        synthetic_samples: synthetic samples read once and drawn from.

    Returns:
        the loss every 25 steps: ``{"step", "loss", "real", "synthetic"}``.
    """
    if len(real.clips) == 0:
        raise ValueError("no pseudo-labelled clip to adapt on")
    rng = np.random.default_rng(config.seed)
    torch.manual_seed(config.seed)
    use_synthetic = config.synthetic_batch > 0 and synthetic is not None and len(synthetic) > 0
    pool = _anchor_pool(synthetic, synthetic_samples, rng, progress) if use_synthetic and synthetic else None
    embedding = getattr(module.net.decoder, "embedding_head", None)
    if embedding is not None:
        embedding.requires_grad_(False)
    optimizer = _optimizer(module, config)
    schedule = PolyLR(optimizer, config.steps)
    module.train()
    _freeze_statistics(module)
    history: list[dict[str, float]] = []
    bar = tqdm(range(config.steps), desc="adapting", unit="step", disable=not progress)
    for step in bar:
        ri = torch.from_numpy(rng.integers(0, len(real.clips), config.real_batch))
        parts = [real.clips[ri]]
        si = torch.from_numpy(rng.integers(0, len(pool["frames"]), config.synthetic_batch)) if pool else None
        if pool is not None and si is not None:
            parts.append(pool["frames"][si])
        frames = torch.cat(parts).float() / 255.0
        logits, emb = module(frames)
        r = config.real_batch
        loss_real = real_loss(logits[:r], real.labels[ri])
        loss = config.real_weight * loss_real
        loss_synthetic = torch.zeros(())
        if pool is not None and si is not None:
            loss_synthetic = module.loss(logits[r:], emb[r:], pool["binary"][si], pool["instance"][si])["loss"]
            loss = loss + loss_synthetic
        optimizer.zero_grad(set_to_none=True)
        loss.backward()  # type: ignore[no-untyped-call]
        optimizer.step()
        schedule.step()
        if step % 25 == 0 or step == config.steps - 1:
            record = {
                "step": float(step),
                "loss": float(loss.detach()),
                "real": float(loss_real.detach()),
                "synthetic": float(loss_synthetic.detach()),
            }
            history.append(record)
            bar.set_postfix(real=f"{record['real']:.3f}", synthetic=f"{record['synthetic']:.3f}")
    module.eval()
    if embedding is not None:
        embedding.requires_grad_(True)
    return history


def write_adapted(source_ckpt: str | Path, module: StamLaneModule, out: str | Path, record: dict[str, Any]) -> Path:
    """Write ``source_ckpt`` with ``module``'s weights and ``record`` (`ADAPT_KEY`) to ``out``, atomically.

    Everything else of the input checkpoint (its config, hyperparameters, data options) travels unchanged, so that
    every command opens the result as it opens the input; the optimizer's state, if any, is left out.
    """
    content = read_checkpoint(source_ckpt)
    own = {k: v.detach().cpu().clone().contiguous() for k, v in module.state_dict().items()}
    missing = sorted(set(content["state_dict"]) ^ set(own))
    if missing:
        raise ValueError(f"the adapted network's weights do not match {source_ckpt}'s ({missing[:3]})")
    content["state_dict"] = own
    for key in ("optimizer_states", "lr_schedulers", "loops", "callbacks"):
        content.pop(key, None)
    content[ADAPT_KEY] = record
    with atomic_path(out) as tmp:
        torch.save(content, tmp)
    return Path(out)


def summary_record(
    ckpt: str | Path,
    source: str | Path,
    config: AdaptConfig,
    labelled: PseudoLabelled,
    history: Sequence[dict[str, float]],
    synthetic: str,
    seconds: float,
) -> dict[str, Any]:
    """The plain record of an adaptation, stored in the checkpoint (`ADAPT_KEY`) and beside it (``adapt.json``)."""
    return {
        "from": Path(ckpt).name,
        "source": Path(source).name,
        "settings": config.as_dict(),
        "pseudo_labels": labelled.stats,
        "synthetic": synthetic,
        "losses": list(history),
        "minutes": round(seconds / 60.0, 2),
        "finished": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
