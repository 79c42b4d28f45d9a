"""The oracles of the labels: what history can reveal on a synthetic split with paint-visibility masks.

The **oracle headroom** of a split is a property of the data, not of a model: TuSimple F1 of lanes fitted, with the
demo's post-processing fit (`stamlane.predict.postprocess.fit_curve` and `sample_lanes`), to the labelled points
visible in the key frame (``key``), and to those visible in the key frame or its aligned history (``history``).
Their difference is what perfect use of ``num_frames`` aligned frames can add over a perfect detector of the key
frame's paint: where it is about 0 (the fitted lines bridge the gaps anyway), no model can show the paper's effect.
A third oracle reads the history UNALIGNED (``unaligned``): a point only the history shows is placed where the
nearest history frame that shows it has it (its pixel in that frame, through the exact homographies): aligned minus
unaligned is what pre-alignment can be worth on the split. The oracles are no upper bound of a model: a network's
priors (lane width, straightness, where lanes run) can beat a curve fitted to the visible points alone, so their
absolute values are reported beside every difference.

A point's class (``visible``, ``revealed``, ``hidden``: `stamlane.synth.visibility`) comes from the split's masks
(`stamlane.experiments.split_scores.read_visibility`, which also scores a model's recall per class). The oracles'
predictions are scored as a model's are, so their intervals over clips come from the same bootstrap.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from stamlane.predict.postprocess import PostprocessConfig, fit_curve, sample_lanes
from stamlane.synth.visibility import visibility_class
from stamlane.types import Lanes

__all__ = ["ORACLES", "hist_from_key", "oracle_predictions"]


ORACLES = ("key", "history", "unaligned")
"""The oracles of `oracle_predictions`, in order."""


def hist_from_key(root: Path, raw_file: str, back: int) -> np.ndarray:
    """The exact ground homography from a synthetic key frame's pixels to the frame ``back`` frames before it, (3, 3),
    from ``homographies/<clip>.json`` (the key frame named ``<n>.jpg``, frames numbered from 1)."""
    clip, name = raw_file.rsplit("/", 1)
    geometry = json.loads((Path(root) / "homographies" / f"{clip.rsplit('/', 1)[-1]}.json").read_text())
    key = geometry["frames"].index(name)
    image_from_ground = np.asarray(geometry["image_from_ground"], dtype=np.float64)
    h = image_from_ground[key - back] @ np.linalg.inv(image_from_ground[key])
    normalised: np.ndarray = h / h[2, 2]
    return normalised


def _fitted(
    points: list[np.ndarray], config: PostprocessConfig, h_samples: Sequence[int], size: tuple[int, int]
) -> Lanes:
    curves = [c for c in (fit_curve(p, config) for p in points if len(p) >= 2) if c is not None]
    return sample_lanes(curves, config, h_samples, size)


def _first_history_frame(mask: int, num_frames: int, stride: int) -> int | None:
    """How many frames back the nearest history frame of the span that shows the paint lies (None: none does)."""
    return next((k * stride for k in range(1, num_frames) if mask >> (k * stride) & 1), None)


def oracle_predictions(
    gts: Sequence[Mapping[str, Any]],
    visibility: Mapping[str, list[list[int]]],
    num_frames: int,
    config: PostprocessConfig,
    size: tuple[int, int],
    stride: int = 1,
    root: Path | None = None,
) -> dict[str, list[dict[str, Any]]]:
    """TuSimple prediction records of the oracles of the module docstring.

    Args:
        gts: TuSimple label records (``raw_file``, ``lanes``, ``h_samples``) of the key frames.
        visibility: `read_visibility` of the same split.
        num_frames: T of the multi-frame oracles (history frames ``stride``, ``2 stride``, ... back).
        config: the post-processing whose fit the oracles use (the demo model's: ``degree``, ``extend``).
        size: ``(H, W)`` of the frames.
        stride: frames between the clip's frames.
        root: the synthetic set (its ``homographies/``); None: no unaligned oracle.

    Returns:
        per oracle of `ORACLES` (``"unaligned"`` only with ``root``), per key frame, ``raw_file``, ``lanes`` (x at
        ``h_samples``, -2 = none), ``h_samples`` and ``run_time`` 0: lanes fitted to the points visible in the
        key frame (``key``); to those and the points one of its ``num_frames - 1`` aligned history frames shows
        (``history``); to the same points with each point only the history shows placed where the nearest such
        history frame has it, as a network without alignment sees it (``unaligned``).
    """
    from stamlane_eval.tusimple import lanes_to_xs

    names = ORACLES if root is not None else ORACLES[:2]
    found: dict[str, list[dict[str, Any]]] = {name: [] for name in names}
    for gt in gts:
        masks = visibility.get(gt["raw_file"])
        if masks is None:
            raise KeyError(f"no visibility for {gt['raw_file']}")
        h_samples = gt["h_samples"]
        moved: dict[int, np.ndarray] = {}
        for name in names:
            points = []
            for lane, lane_masks in zip(gt["lanes"], masks):
                kept = []
                for x, y, m in zip(lane, h_samples, lane_masks):
                    cls = visibility_class(m, num_frames, stride) if x >= 0 else None
                    if cls == "visible" or (cls == "revealed" and name != "key"):
                        if cls == "revealed" and name == "unaligned":
                            back = _first_history_frame(m, num_frames, stride)
                            # revealed: a history frame shows it; unaligned: an oracle of a set with its root
                            assert back is not None and root is not None
                            if back not in moved:
                                moved[back] = hist_from_key(root, gt["raw_file"], back)
                            p = moved[back] @ np.array([x, y, 1.0])
                            x, y = p[0] / p[2], p[1] / p[2]
                        kept.append((x, y))
                points.append(np.array(kept, dtype=np.float64).reshape(-1, 2))
            lanes = _fitted(points, config, h_samples, size)
            found[name].append(
                {
                    "raw_file": gt["raw_file"],
                    "lanes": lanes_to_xs(lanes, h_samples),
                    "h_samples": h_samples,
                    "run_time": 0,
                }
            )
    return found
