"""What history can reveal, and what a model recovers of it, on synthetic sets with paint visibility.

Two measurements on the labels of a split with ``visibility/<split>.json`` (generator format 5,
`stamlane.synth.visibility`):

- **recall per visibility class** of a model's predictions: every labelled key-frame point is ``visible`` (its
  paint shows in the key frame), ``revealed`` (hidden in the key frame, shown by one of the model's history
  frames at exact alignment) or ``hidden``; a point is recalled when the predicted lane that TuSimple's
  ``lane.py`` matches to its annotated lane (the one with the most rows within the angle-scaled 20-px threshold)
  is within that threshold on the point's row. A model that reads its history recalls more ``revealed`` points
  than one that does not; ``visible`` points are the single frame's job.
- **the oracle headroom** of a split (a property of the data, not of a model): TuSimple F1 of lanes fitted, with
  the demo's post-processing fit (`stamlane.predict.postprocess.fit_curve` and `sample_lanes`), to the labelled points
  visible in the key frame, and to those visible in the key frame or its aligned history. Their difference is
  what perfect use of ``num_frames`` aligned frames can add over a perfect detector of the key frame's paint:
  where it is about 0 (the fitted lines bridge the gaps anyway), no model can show the paper's effect. A third
  oracle reads the history UNALIGNED: a point only the history shows is placed where the nearest history frame
  that shows it has it (its pixel in that frame, through the exact homographies): aligned minus unaligned is what
  pre-alignment can be worth on the split. The oracles are no upper bound of a model: a network's priors (lane
  width, straightness, where lanes run) can beat a curve fitted to the visible points alone, so their absolute
  values are reported beside every difference.

Both give per-image quantities (columns) so that intervals over clips come from the same bootstrap as every F1.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from stamlane_eval.tusimple import PIXEL_THRESH

from stamlane.predict.postprocess import PostprocessConfig, fit_curve, sample_lanes
from stamlane.synth.layout import VISIBILITY_DIR
from stamlane.synth.visibility import VISIBILITY_CLASSES, visibility_class

__all__ = [
    "ORACLES",
    "class_counts",
    "hist_from_key",
    "oracle_predictions",
    "point_hits",
    "read_visibility",
    "recall_of_counts",
]


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
    return h / h[2, 2]


def read_visibility(root: Path, split: str) -> dict[str, list[list[int]]] | None:
    """``raw_file`` -> per lane, per h_sample visibility mask, from ``<root>/visibility/<split>.json``; None for a set
    without one (format 4 and older, or a split without visibility)."""
    path = Path(root) / VISIBILITY_DIR / f"{split}.json"
    if not path.is_file():
        return None
    found = {}
    for line in path.read_text().splitlines():
        record = json.loads(line)
        found[record["raw_file"]] = record["visibility"]
    return found


def _threshold(gt: np.ndarray, ys: np.ndarray) -> float:
    """lane.py's per-lane pixel threshold: 20 px / cos(angle of the least-squares x = k y + b through its points)."""
    on = gt >= 0
    if on.sum() < 2:
        return PIXEL_THRESH
    k = np.polyfit(ys[on], gt[on], 1)[0]
    return PIXEL_THRESH / np.cos(np.arctan(k))


def point_hits(
    pred: Sequence[Sequence[float]], gt: Sequence[Sequence[float]], h_samples: Sequence[float]
) -> list[list[bool]]:
    """Whether each labelled point of an image is recalled (see the module docstring).

    Args:
        pred: predicted lanes as TuSimple x lists (negative = no point), (P, R).
        gt: annotated lanes, (G, R).
        h_samples: the R rows.

    Returns:
        per annotated lane, per row: True where the lane's best-matching prediction is within the threshold there
        (False on rows without a label point too: read them with the visibility mask, which marks those absent).
    """
    ys = np.asarray(h_samples, dtype=np.float64)
    preds = np.where(np.asarray(pred, dtype=np.float64) >= 0, np.asarray(pred, dtype=np.float64), -100.0)
    preds = preds.reshape(len(pred), len(ys))
    hits = []
    for lane in gt:
        g = np.asarray(lane, dtype=np.float64)
        if len(preds) == 0:
            hits.append([False] * len(ys))
            continue
        thresh = _threshold(g, ys)
        close = np.abs(preds - np.where(g >= 0, g, -100.0)[None, :]) < thresh  # (P, R), lane.py's comparison
        best = int(np.argmax(close.mean(axis=1)))
        hits.append([bool(c and x >= 0) for c, x in zip(close[best], g)])
    return hits


def class_counts(hits: list[list[bool]], masks: list[list[int]], num_frames: int, stride: int = 1) -> list[float]:
    """Per-image quantities of the class recall: ``[recalled, points]`` of each class of `VISIBILITY_CLASSES` in
    turn (6 numbers), for a model of ``num_frames`` frames at ``stride``."""
    counts = np.zeros((len(VISIBILITY_CLASSES), 2))
    for lane_hits, lane_masks in zip(hits, masks):
        for hit, mask in zip(lane_hits, lane_masks):
            cls = visibility_class(mask, num_frames, stride)
            if cls is not None:
                counts[VISIBILITY_CLASSES.index(cls)] += (float(hit), 1.0)
    return counts.ravel().tolist()


def recall_of_counts(means: np.ndarray, cls: str) -> float:
    """The recall of class ``cls`` from the means of `class_counts` columns (nan where the class has no point)."""
    i = VISIBILITY_CLASSES.index(cls)
    points = float(means[2 * i + 1])
    return float(means[2 * i]) / points if points > 0 else float("nan")


def _fitted(points: list[np.ndarray], config: PostprocessConfig, h_samples: Sequence[int], size: tuple[int, int]):
    curves = [c for c in (fit_curve(p, config) for p in points if len(p) >= 2) if c is not None]
    return sample_lanes(curves, config, h_samples, size)


def _first_history_frame(mask: int, num_frames: int, stride: int) -> int | None:
    """How many frames back the nearest history frame of the span that shows the paint lies (None: none does)."""
    return next((k * stride for k in range(1, num_frames) if mask >> (k * stride) & 1), None)


def oracle_predictions(
    gts: Sequence[Mapping],
    visibility: Mapping[str, list[list[int]]],
    num_frames: int,
    config: PostprocessConfig,
    size: tuple[int, int],
    stride: int = 1,
    root: Path | None = None,
) -> dict[str, list[dict]]:
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
    found: dict[str, list[dict]] = {name: [] for name in names}
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
