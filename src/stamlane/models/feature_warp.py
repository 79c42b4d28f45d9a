"""Warp history-frame feature maps onto the key frame in feature space (feature-space alignment).

The pre-alignment of the paper (3.1) warps history IMAGES before the encoder, so every frame is encoded
again each time it is history (T encoder passes per new frame). Streaming (`stamlane.stream`) encodes every
frame once and applies the same homography to its deepest-stage feature map instead; training with
``warp="feature"`` data does the same (`stamlane.models.feature_aligned`). Pure torch + numpy.

Frames involved, all with pixel centres at integer coordinates (``stamlane.types``):

- original pixels: where ``stamlane.align`` estimates ``key_from_hist`` (pass ``net_from_orig``);
- network-input pixels: the resized image the encoder sees, ``x_net = net_from_orig @ x_orig``;
- feature cells of a stage of stride ``s``: cell ``j`` covers network pixels ``j*s .. j*s + s - 1``, so its
  centre is ``x_feat = (x_net + 0.5) / s - 0.5`` (``feat_from_net``).

A homography in one frame becomes ``B @ H @ inv(B)`` in another (``B`` maps the old frame to the new one).
The feature map is resampled with ``grid_sample`` (bilinear, zeros outside, ``align_corners=False``: the
normalised coordinate ``-1`` is the left EDGE of cell 0, matching the pixel-centre convention above).
"""

from __future__ import annotations

import functools

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

__all__ = ["feat_from_net", "feature_homography", "sampling_grid", "warp_features"]

MatrixLike = Tensor | np.ndarray


def feat_from_net(stride: int | float) -> np.ndarray:
    """``(3, 3)`` float64 map from network-input pixels to the feature cells of a stage of ``stride``.

    ``x_feat = (x_net + 0.5) / stride - 0.5`` (and the same for ``y``): pixel centres to cell centres.
    """
    if not stride > 0:
        raise ValueError(f"stride must be > 0, got {stride}")
    s = 1.0 / float(stride)
    return np.array([[s, 0.0, 0.5 * s - 0.5], [0.0, s, 0.5 * s - 0.5], [0.0, 0.0, 1.0]])


def _as_batch_of_matrices(value: MatrixLike, name: str) -> Tensor:
    """``(3, 3)`` or ``(B, 3, 3)`` array/tensor -> ``(B, 3, 3)`` float64 CPU tensor, finite."""
    matrix = torch.as_tensor(np.asarray(value) if isinstance(value, np.ndarray) else value)
    matrix = matrix.detach().to(device="cpu", dtype=torch.float64)
    if matrix.ndim == 2:
        matrix = matrix[None]
    if matrix.ndim != 3 or tuple(matrix.shape[1:]) != (3, 3):
        raise ValueError(f"{name} must be (3, 3) or (B, 3, 3), got {tuple(matrix.shape)}")
    if not torch.isfinite(matrix).all():
        raise ValueError(f"{name} must be finite, got {matrix.tolist()}")
    return matrix


def feature_homography(
    key_from_hist: MatrixLike, stride: int | float, net_from_orig: MatrixLike | None = None
) -> Tensor:
    """An image homography expressed on the feature grid of a stage.

    Args:
        key_from_hist: ``(B, 3, 3)`` or ``(3, 3)``: history pixels -> key pixels, in NETWORK-input pixels, or in
            ORIGINAL pixels when ``net_from_orig`` is given.
        stride: the stage's stride w.r.t. the network input (16 for ``VGGEncoder``'s deepest stage).
        net_from_orig: ``(3, 3)`` or ``(B, 3, 3)``: original pixels -> network pixels (``None``: ``key_from_hist``
            is already in network pixels).

    Returns:
        ``(B, 3, 3)`` float64: history feature cells -> key feature cells, normalised so ``[2, 2] = 1``.

    Raises:
        ValueError: on wrong shapes, non-finite or singular matrices, a non-positive stride.
    """
    h = _as_batch_of_matrices(key_from_hist, "key_from_hist")
    if net_from_orig is not None:
        n = _as_batch_of_matrices(net_from_orig, "net_from_orig")
        if n.shape[0] not in (1, h.shape[0]):
            raise ValueError(f"net_from_orig holds {n.shape[0]} matrices for {h.shape[0]} homographies")
        h = n @ h @ _inverse(n, "net_from_orig")
    f = torch.from_numpy(feat_from_net(stride))
    h = f @ h @ torch.linalg.inv(f)
    scale = h[:, 2:3, 2:3]
    if (scale.abs() < 1e-12).any():
        raise ValueError(f"key_from_hist has a zero [2, 2] entry on the feature grid: {h.tolist()}")
    normalised: Tensor = h / scale
    return normalised


def _inverse(matrix: Tensor, name: str) -> Tensor:
    det = torch.linalg.det(matrix)
    if (det.abs() < 1e-12).any():
        raise ValueError(f"{name} is singular: {matrix.tolist()}")
    inverse: Tensor = torch.linalg.inv(matrix)
    return inverse


@functools.lru_cache(maxsize=16)
def _cells(height: int, width: int) -> Tensor:
    """Homogeneous centres ``(x, y, 1)`` of the cells of an ``(h, w)`` grid, row-major, ``(h*w, 3)`` float64."""
    ys, xs = torch.meshgrid(
        torch.arange(height, dtype=torch.float64), torch.arange(width, dtype=torch.float64), indexing="ij"
    )
    return torch.stack([xs, ys, torch.ones_like(xs)], dim=-1).reshape(-1, 3)


def sampling_grid(key_from_hist_feat: Tensor, size: tuple[int, int]) -> Tensor:
    """The ``grid_sample`` grid that pulls history features into key-frame cells.

    Args:
        key_from_hist_feat: ``(B, 3, 3)`` float64, history cells -> key cells (`feature_homography`).
        size: ``(h, w)`` of the feature map (the same for history and key frame).

    Returns:
        ``(B, h, w, 2)`` float64: for each key cell, the history location in ``grid_sample``'s normalised
        coordinates (``align_corners=False``); cells whose source lies behind the camera (non-positive
        homogeneous coordinate) get a location far outside, i.e. zeros.
    """
    height, width = size
    hist_from_key = _inverse(key_from_hist_feat, "key_from_hist")
    src = _cells(height, width) @ hist_from_key.transpose(1, 2)  # (B, h*w, 3)
    w = src[..., 2:3]
    valid = w > 1e-9
    xy = src[..., :2] / torch.where(valid, w, torch.ones_like(w))
    scale = torch.tensor([2.0 / width, 2.0 / height], dtype=torch.float64)
    grid = (xy + 0.5) * scale - 1.0  # cell centre x -> (x + 0.5) / w * 2 - 1
    grid = torch.where(valid, grid, torch.full_like(grid, -4.0))
    return grid.reshape(-1, height, width, 2)


def warp_features(
    feats: Tensor,
    key_from_hist: MatrixLike,
    stride: int | float,
    *,
    net_from_orig: MatrixLike | None = None,
) -> Tensor:
    """Warp history feature maps onto the key frame (bilinear, zeros where the history frame has no source).

    Args:
        feats: history-frame features, ``(B, C, h, w)``, a stage of ``stride`` of the network input.
        key_from_hist: ``(B, 3, 3)`` (or ``(3, 3)`` for all) homographies history -> key, in NETWORK-input
            pixels, or in ORIGINAL pixels when ``net_from_orig`` is given. Tensor or numpy; any float dtype.
        stride: the stage's stride w.r.t. the network input.
        net_from_orig: ``(3, 3)`` or ``(B, 3, 3)``, original -> network pixels; ``None`` = ``key_from_hist`` is in
            network pixels.

    Returns:
        ``(B, C, h, w)`` features of the history frames as seen from the key frame, same dtype and device as
        ``feats``. The identity returns ``feats`` up to float rounding of the sampling positions (< 1e-6).

    Raises:
        ValueError: on a feats tensor that is not 4-d, a number of homographies that is neither 1 nor ``B``,
            non-finite or singular matrices.
    """
    if feats.ndim != 4:
        raise ValueError(f"expected feats of shape (B, C, h, w), got {tuple(feats.shape)}")
    h = feature_homography(key_from_hist, stride, net_from_orig)
    batch = feats.shape[0]
    if h.shape[0] not in (1, batch):
        raise ValueError(f"expected 1 or {batch} homographies for {batch} feature maps, got {h.shape[0]}")
    grid = sampling_grid(h, (feats.shape[-2], feats.shape[-1])).expand(batch, -1, -1, -1)
    # sampled in float32 at least: a bfloat16 grid would misplace cells by up to 1/128 of the map's width
    work = feats.float() if feats.dtype in (torch.float16, torch.bfloat16) or not feats.is_floating_point() else feats
    grid = grid.to(device=feats.device, dtype=work.dtype)
    out = F.grid_sample(work, grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    return out.to(feats.dtype)
