"""The conventions every stamlane module shares, written once.

Clips and frames
    A clip is a tensor ``(B, T, C, H, W)`` (or one sample ``(T, C, H, W)``) with the KEY frame LAST,
    index ``-1``; history frames come before it, oldest first. Image tensors are float32 in ``[0, 1]``;
    the encoder standardises them itself. numpy images are ``(H, W, 3)`` uint8 BGR (OpenCV order).

Points and lanes
    A point is ``(x, y)`` float in ORIGINAL-image pixels (x right, y down, pixel centres at integers).
    A lane is a ``(N, 2)`` float array of such points ordered by ``y`` descending or ascending as read;
    an image's lanes are a ``list`` of lanes. Normalised coordinates never cross a module boundary.

Sizes
    An image size is ``(H, W)``, like a tensor's shape and torch (``orig_size``, ``image_size``, a warp's output,
    the CULane metric's canvas); ``WxH`` only where a person types or reads it (``--size 1640x590``:
    ``stamlane_eval.cli_tools.parse_wxh`` / ``format_wxh``). OpenCV's ``(W, H)`` ``dsize`` is built at the call.

Transforms
    A 3x3 matrix is named by the frames it maps between, target first: ``key_from_hist`` maps
    history-frame pixels to key-frame pixels; ``net_from_orig`` maps original-image pixels to
    network-input pixels (crop + scale); ``orig_from_net`` is its inverse.

Samples (what a dataset returns, what the LightningModule consumes)
    ``frames``        float32 ``(T, 3, H, W)`` in [0, 1], key frame last, history pre-aligned if asked
                      (``warp="image"``; with ``warp="feature"`` every frame only gets the key frame's crop).
    ``binary``        int64 ``(H, W)``: 1 on lane pixels, 0 elsewhere, at the network resolution.
    ``instance``      int64 ``(H, W)``: 0 background, lanes 1..n in left-to-right order.
    ``key_from_hist`` float32 ``(T, 3, 3)``: the alignment applied to each frame (identity for the key).
    ``key_from_hist_net`` (``NET_HOMOGRAPHIES``) float32 ``(T, 3, 3)``, only with ``warp="feature"`` data:
                      history -> key frame in NETWORK pixels (``net_from_orig @ key_from_hist @ inv(net_from_orig)``,
                      identity for the key); the model warps the history's features with it.
    ``lanes``         list of ``(N, 2)`` float arrays: the key frame's lanes in original pixels.
    ``meta``          dict: ``raw_file`` (str, the benchmark's name of the key frame), ``orig_size``
                      ``(H, W)``, ``net_from_orig`` (3x3 list), ``h_samples`` (list[int] or None),
                      ``frame_paths`` (list[str]), ``format`` ("tusimple" | "culane" | "apollo" | "vil100").
    A batch (see ``stamlane.data.collate_clips``) stacks the tensors and keeps ``lanes`` and ``meta``
    as per-sample lists.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import TypeVar

import numpy as np

__all__ = ["NET_HOMOGRAPHIES", "Lane", "Lanes", "nameable", "nameable_objects"]

NET_HOMOGRAPHIES = "key_from_hist_net"
"""Sample / batch key of the history -> key homographies in network pixels (``warp="feature"`` data only)."""

Lane = np.ndarray
"""One lane: ``(N, 2)`` float array of ``(x, y)`` points in original-image pixels."""

Lanes = list[Lane]
"""All lanes of one image."""


_T = TypeVar("_T")
_NAMEABLE: dict[str, object] = {}


def nameable(obj: _T) -> _T:
    """Register a class (or function) that a stored run may name, where it is defined (a decorator).

    A checkpoint's hyper_parameters or a run folder's ``config.yaml`` may build only what is registered, by its
    exact defining name (``stamlane.models.stam.STAM``); the closed registry (`stamlane.training.registry`) adds the
    name its package exports it under (``stamlane.models.STAM``). Registering imports nothing: the registry imports
    the packages that define such classes itself, never because a file names one.
    """
    name = f"{obj.__module__}.{obj.__qualname__}"  # type: ignore[attr-defined]
    if _NAMEABLE.setdefault(name, obj) is not obj:
        raise ValueError(f"{name} is registered twice")
    return obj


def nameable_objects() -> Mapping[str, object]:
    """Exact defining name -> object, of everything `nameable` registered so far (a read-only view)."""
    return MappingProxyType(_NAMEABLE)
