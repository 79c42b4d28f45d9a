"""Batching of clip samples."""

from __future__ import annotations

from typing import Any

import torch

from stamlane.types import NET_HOMOGRAPHIES

__all__ = ["collate_clips"]

_STACKED = ("frames", "binary", "instance", "key_from_hist")
_OPTIONAL = (NET_HOMOGRAPHIES,)  # stacked when every sample has it (``warp="feature"`` data)


def collate_clips(samples: list[dict[str, Any]]) -> dict[str, Any]:
    """Stack the tensors of samples into a batch; keep ``lanes`` and ``meta`` as per-sample lists.

    Args:
        samples: dataset samples (see ``stamlane.types``), all of one clip length and network size.

    Returns:
        ``frames`` (B, T, 3, H, W), ``binary`` and ``instance`` (B, H, W), ``key_from_hist`` (B, T, 3, 3),
        ``key_from_hist_net`` (B, T, 3, 3) when the samples have it, ``lanes`` list of B lane lists, ``meta``
        list of B dicts.
    """
    if not samples:
        raise ValueError("collate_clips needs at least one sample, got an empty list")
    shapes = {tuple(s["frames"].shape) for s in samples}
    if len(shapes) > 1:
        raise ValueError(f"samples of one batch must share the clip shape (T, 3, H, W), got {sorted(shapes)}")
    batch: dict[str, Any] = {k: torch.stack([s[k] for s in samples]) for k in _STACKED}
    for key in _OPTIONAL:
        have = sum(key in s for s in samples)
        if have == len(samples):
            batch[key] = torch.stack([s[key] for s in samples])
        elif have:
            raise ValueError(f"{key} is in {have} of the {len(samples)} samples of a batch; mix of warp modes?")
    batch["lanes"] = [s["lanes"] for s in samples]
    batch["meta"] = [s["meta"] for s in samples]
    return batch
