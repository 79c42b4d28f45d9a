"""Losses of the two decoder branches (paper 3.2, docs/method.md §4).

Binary branch: cross-entropy with bounded inverse class weights ``w_c = 1 / ln(1.02 + p_c)``, ``p_c`` the
frequency of class c among the pixels of the CURRENT BATCH (computed per batch, not per dataset; a class
absent from the batch gets the bound ``1 / ln 1.02 ~ 50.5``, harmless since no pixel carries it).

Embedding branch: the discriminative loss (De Brabandere et al. 2017) over the lanes of each image:

- ``L_var  = 1/C sum_c 1/N_c sum_{i in c} max(0, ||mu_c - x_i|| - delta_v)^2``
- ``L_dist = 1/(C(C-1)) sum_{a != b} max(0, 2 delta_d - ||mu_a - mu_b||)^2``
- ``L_reg  = 1/C sum_c ||mu_c||``

delta_d convention: the paper's / De Brabandere's — the hinge is at ``2 * delta_d`` with ``delta_d = 1.5``,
so cluster centres are pushed 3.0 apart (LaneNet's TF code writes ``delta_d = 3`` with the hinge at
``delta_d``; same margin). Background pixels (instance 0) form no cluster. An image with no lane gives
0 for all three terms, one lane gives 0 for ``L_dist``; never NaN. Per-image terms are averaged over the
images of the batch (lane-less images count as 0).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from stamlane.types import nameable

__all__ = ["CE_WEIGHT_OFFSET", "LaneLoss", "class_weights", "discriminative_loss"]

CE_WEIGHT_OFFSET = 1.02
"""c in w = 1 / ln(c + p) (ENet, Paszke et al. 2016): bounds every class weight by 1 / ln(1.02) ~ 50.5."""


def class_weights(labels: Tensor, num_classes: int = 2) -> Tensor:
    """Bounded inverse class weights of one batch, ``w_c = 1 / ln(1.02 + p_c)``.

    Args:
        labels: class index per pixel, int64, any shape (e.g. binary lane mask (B, H, W)); values in
            ``[0, num_classes)``.
        num_classes: number of classes.

    Returns:
        float32 weights, (num_classes,); no gradient.
    """
    if labels.numel() == 0:
        raise ValueError(f"labels must not be empty, got shape {tuple(labels.shape)}")
    counts = torch.bincount(labels.reshape(-1), minlength=num_classes)
    if counts.numel() != num_classes:
        raise ValueError(f"labels must lie in [0, {num_classes}), got max {int(labels.max())}")
    freq = counts.float() / labels.numel()
    return 1.0 / torch.log(CE_WEIGHT_OFFSET + freq)


def discriminative_loss(
    embedding: Tensor,
    instance: Tensor,
    delta_v: float = 0.5,
    delta_d: float = 1.5,
    alpha: float = 1.0,
    beta: float = 1.0,
    gamma: float = 0.001,
) -> dict[str, Tensor]:
    """Discriminative loss, vectorised over lanes and images (no Python loop).

    Args:
        embedding: pixel embeddings, (B, E, H, W); computed in float32 whatever the input dtype.
        instance: lane id per pixel, int64 (B, H, W); 0 = background, lanes 1..n.
        delta_v: pull margin: pixels closer than this to their lane's mean are not pulled.
        delta_d: push margin: lane means are pushed ``2 * delta_d`` apart.
        alpha: weight of ``L_var``.
        beta: weight of ``L_dist``.
        gamma: weight of ``L_reg``.

    Returns:
        ``{"var": alpha * L_var, "dist": beta * L_dist, "reg": gamma * L_reg}``, scalar tensors, WEIGHTED, so
        their sum is the discriminative loss; each the mean over the batch's images.
    """
    if embedding.ndim != 4:
        raise ValueError(f"expected embedding of shape (B, E, H, W), got {tuple(embedding.shape)}")
    if instance.shape != (embedding.shape[0], *embedding.shape[2:]):
        raise ValueError(
            f"expected instance of shape {(embedding.shape[0], *embedding.shape[2:])}, got {tuple(instance.shape)}"
        )
    batch = embedding.shape[0]
    embedding = embedding.float()
    zero = embedding.sum() * 0.0  # keeps the graph (and device, dtype) for lane-less batches
    lane = instance > 0
    if not bool(lane.any()):
        return {"var": zero, "dist": zero, "reg": zero}

    # one cluster id per (image, lane): image * (max_id + 1) + lane_id
    stride = int(instance.max()) + 1
    image_index = torch.arange(batch, device=instance.device).view(-1, 1, 1).expand_as(instance)
    global_id = (image_index * stride + instance)[lane]  # (P,)
    pixels = embedding.permute(0, 2, 3, 1)[lane]  # (P, E)
    cluster_ids, inverse = torch.unique(global_id, return_inverse=True)
    num_clusters = cluster_ids.numel()
    cluster_image = cluster_ids // stride  # (M,)

    counts = torch.bincount(inverse, minlength=num_clusters).float()  # (M,)
    means = pixels.new_zeros(num_clusters, pixels.shape[1]).index_add(0, inverse, pixels) / counts[:, None]

    pull = F.relu(torch.linalg.vector_norm(means[inverse] - pixels, dim=1) - delta_v) ** 2  # (P,)
    var_cluster = pixels.new_zeros(num_clusters).index_add(0, inverse, pull) / counts  # (M,)

    lanes_per_image = torch.bincount(cluster_image, minlength=batch).float()  # (B,)
    per_cluster_norm = lanes_per_image.clamp_min(1.0)
    var_image = pixels.new_zeros(batch).index_add(0, cluster_image, var_cluster) / per_cluster_norm
    reg_image = pixels.new_zeros(batch).index_add(0, cluster_image, torch.linalg.vector_norm(means, dim=1))
    reg_image = reg_image / per_cluster_norm

    # pairs (a, b), a != b, of lanes of the same image
    same_image = cluster_image[:, None] == cluster_image[None, :]
    pair = same_image & ~torch.eye(num_clusters, dtype=torch.bool, device=means.device)
    gap = torch.linalg.vector_norm(means[:, None, :] - means[None, :, :], dim=2)  # (M, M)
    push = (F.relu(2.0 * delta_d - gap) ** 2) * pair
    dist_image = pixels.new_zeros(batch).index_add(0, cluster_image, push.sum(dim=1))
    dist_image = dist_image / (lanes_per_image * (lanes_per_image - 1)).clamp_min(1.0)

    return {
        "var": alpha * var_image.mean(),
        "dist": beta * dist_image.mean(),
        "reg": gamma * reg_image.mean(),
    }


@nameable
class LaneLoss(nn.Module):
    """Total LaneNet loss: ``seg_weight * CE + embed_weight * (alpha L_var + beta L_dist + gamma L_reg)``.

    CE uses `class_weights` of the batch (bounded inverse frequency, per batch); the discriminative terms
    follow the module docstring (hinge at ``2 * delta_d``, delta_d = 1.5).

    Args:
        seg_weight: weight of the binary cross-entropy.
        embed_weight: weight of the discriminative loss.
        delta_v: pull margin of the discriminative loss.
        delta_d: push margin (centres pushed ``2 * delta_d`` apart).
        alpha: weight of ``L_var`` inside the discriminative loss.
        beta: weight of ``L_dist``.
        gamma: weight of ``L_reg``.
        class_weighting: use the bounded inverse class weights (False: plain CE).
    """

    def __init__(
        self,
        seg_weight: float = 1.0,
        embed_weight: float = 1.0,
        delta_v: float = 0.5,
        delta_d: float = 1.5,
        alpha: float = 1.0,
        beta: float = 1.0,
        gamma: float = 0.001,
        class_weighting: bool = True,
    ) -> None:
        super().__init__()
        if delta_v < 0 or delta_d < 0:
            raise ValueError(f"delta_v and delta_d must be >= 0, got {delta_v}, {delta_d}")
        self.seg_weight = seg_weight
        self.embed_weight = embed_weight
        self.delta_v = delta_v
        self.delta_d = delta_d
        self.alpha = alpha
        self.beta = beta
        self.gamma = gamma
        self.class_weighting = class_weighting

    def forward(self, logits: Tensor, embedding: Tensor, binary: Tensor, instance: Tensor) -> dict[str, Tensor]:
        """Compute the loss terms.

        Args:
            logits: lane / background logits, (B, 2, H, W).
            embedding: pixel embeddings, (B, E, H, W).
            binary: int64 (B, H, W), 1 on lane pixels.
            instance: int64 (B, H, W), 0 background, lanes 1..n.

        Returns:
            ``{"loss": total, "seg": CE, "var", "dist", "reg"}``: scalar float32 tensors; ``var``/``dist``/``reg``
            carry alpha/beta/gamma (not ``embed_weight``), ``seg`` is unweighted.
        """
        if logits.ndim != 4 or logits.shape[1] != 2:
            raise ValueError(f"expected logits of shape (B, 2, H, W), got {tuple(logits.shape)}")
        expected = (logits.shape[0], *logits.shape[2:])
        if binary.shape != expected:
            raise ValueError(f"expected binary of shape {expected}, got {tuple(binary.shape)}")
        weight = class_weights(binary, 2).to(logits.device) if self.class_weighting else None
        seg = F.cross_entropy(logits.float(), binary, weight=weight)
        terms = discriminative_loss(embedding, instance, self.delta_v, self.delta_d, self.alpha, self.beta, self.gamma)
        total = self.seg_weight * seg + self.embed_weight * (terms["var"] + terms["dist"] + terms["reg"])
        return {"loss": total, "seg": seg, **terms}
