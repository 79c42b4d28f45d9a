"""Video lane metrics for every-frame annotated sequences (VIL-100 layout, synthetic sequences).

Every frame is scored with the CULane area metric of the official C++ tool (:func:`stamlane_eval.culane.
evaluate_image`: lanes drawn ``width`` px wide, maximum-IoU matching), then:

- **mIoU** as MMA-Net computes it for VIL-100 (yujun0-0/MMA-Net @ a88a5a70, ``evaluation/evaluate_iou.py``
  and its ``culane/src/counter.cpp``): per frame, the sum over the annotated lanes (in file order) of the
  IoU with the prediction matched to each, divided by the number of PREDICTED lanes; a frame with annotations
  but no prediction, or predictions but no annotation, scores 0; a frame with neither scores 1. Averaged over
  the frames of a sequence, then over sequences (each sequence weighs the same, whatever its length), from
  each sequence's mIoU as the C++ tool prints it (6 significant digits).
- **F@t** for each threshold t (default 0.5 and 0.8): TP = matched pairs with IoU > t, summed over all frames;
  P = TP/(TP+FP), R = TP/(TP+FN), F = 2PR/(P+R) (0 where undefined).
- **Temporal stability**, with ``match_iou`` (default 0.5) deciding whether an annotated lane is matched in a
  frame (matched pair with IoU > match_iou). Annotated lanes are followed by their identity (VIL-100
  ``lane_id``; else their line order), predicted lanes by theirs (the line order of the prediction file,
  i.e. the model's left-to-right lane slot, unless ids are given).

  - identity switch: an annotated lane matched in frames t-1 and t to predicted lanes of different
    identities. ``switch_rate`` = switches / (annotated lanes matched in two consecutive frames).
  - flicker: an annotated lane present in t-1, t and t+1, matched in t-1 and t+1 but not in t.
    ``flicker_rate`` = flickers / (annotated lanes present in the three frames and matched in t-1 and t+1).

Frames are consecutive in the order given (file-name order in the CLI).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from stamlane_eval import culane
from stamlane_eval._long_runs import map_sequences
from stamlane_eval.aggregate import MMA_NET_DIGITS, count_update, dataset_miou, sequence_miou
from stamlane_eval.io.video import Frame  # one annotated frame, as the readers give it

__all__ = [
    "MMA_NET_DIGITS",
    "VIDEO_IOU_THRESHOLDS",
    "Frame",
    "SequenceResult",
    "VideoResult",
    "dataset_miou",
    "evaluate",
    "evaluate_sequence",
    "frame_miou",
]

VIDEO_IOU_THRESHOLDS = (0.5, 0.8)  # the thresholds VIL-100 / MMA-Net report F at
MATCH_IOU = 0.5  # a pair counts as "matched" for identity switches and flicker above this IoU


@dataclass(frozen=True)
class SequenceResult:
    """One sequence: its mIoU, counts per threshold and stability counts."""

    name: str
    frames: int
    miou: float | None
    counts: dict[float, tuple[int, int, int]]
    id_switches: int
    switch_chances: int
    flickers: int
    flicker_chances: int
    frame_miou: list[float] = field(default_factory=list, repr=False)

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"sequence": self.name, "frames": self.frames, "miou": self.miou}
        out.update({str(t): list(c) for t, c in self.counts.items()})
        out.update(
            id_switches=self.id_switches,
            switch_chances=self.switch_chances,
            flickers=self.flickers,
            flicker_chances=self.flicker_chances,
        )
        return out


@dataclass(frozen=True)
class VideoResult:
    """Dataset numbers (see the module docstring for the formulas)."""

    miou: float
    totals: dict[float, culane.CULaneCounts]
    id_switches: int
    switch_rate: float
    flickers: int
    flicker_rate: float
    sequences: int
    frames: int
    per_sequence: list[SequenceResult] = field(default_factory=list, repr=False)

    def as_dict(self) -> dict[str, object]:
        """``{"miou", "0.5": {tp, fp, fn, precision, recall, f1}, "0.8": ..., "id_switches", ...}``."""
        out: dict[str, object] = {"miou": self.miou}
        out.update({str(t): c.as_dict() for t, c in self.totals.items()})
        out.update(
            id_switches=self.id_switches,
            switch_rate=self.switch_rate,
            flickers=self.flickers,
            flicker_rate=self.flicker_rate,
            sequences=self.sequences,
            frames=self.frames,
        )
        return out


def _ids(ids: Sequence[int] | None, n: int, what: str, i: int) -> list[int]:
    if ids is None:
        return list(range(n))
    ids = [int(v) for v in ids]
    if len(ids) != n:
        raise ValueError(f"frame {i}: {len(ids)} {what} ids for {n} lanes")
    if len(set(ids)) != n:
        raise ValueError(f"frame {i}: duplicate {what} ids {ids}")
    return ids


def frame_miou(r: culane.CULaneImageResult) -> float:
    """One frame's mIoU as MMA-Net's ``Counter::count_im_pair`` returns it.

    Args:
        r: the frame scored by :func:`stamlane_eval.culane.evaluate_image` (``variant="official"``).

    Returns:
        1.0 for a frame with neither lanes nor predictions, 0.0 when either is empty, else the IoUs of the
        matched pairs summed in annotation order, divided by the number of predicted lanes.
    """
    if not r.n_pred and not r.n_gt:
        return 1.0  # count_im_pair: make_tuple(anno_match, 0, 0, 0, 0, 1) when both lists are empty
    if not r.n_pred or not r.n_gt:
        return 0.0
    gt_to_pred = {g: p for p, g in enumerate(r.pred_to_gt.tolist()) if g >= 0}
    total = 0.0
    for g in range(r.n_gt):  # curr_iou += similarity[i][anno_match[i]], matched annotations in order
        if g in gt_to_pred:
            total += float(r.ious[gt_to_pred[g], g])
    return total / r.n_pred  # curr_iou / detect_lanes.size(): over the PREDICTED lanes


def evaluate_sequence(
    frames: Sequence[Frame],
    name: str = "",
    iou_thresholds: Sequence[float] = VIDEO_IOU_THRESHOLDS,
    match_iou: float = MATCH_IOU,
    width: int = culane.LANE_WIDTH,
    size: tuple[int, int] = culane.CULANE_SIZE,
) -> SequenceResult:
    """Score one sequence of consecutive frames.

    Args:
        frames: the frames in time order.
        name: the sequence's name (for results and messages).
        iou_thresholds: thresholds of F.
        match_iou: IoU above which an annotated lane counts as matched for the stability measures.
        width: line thickness in pixels.
        size: image ``(H, W)`` of frames that do not give their own.

    Returns:
        The sequence's mIoU (None when no frame was scored), counts and stability counts.
    """
    thresholds = tuple(float(t) for t in iou_thresholds)
    frame_counts: list[dict[float, tuple[int, int, int]]] = []
    frame_mious: list[float] = []
    matched: list[dict[int, int]] = []  # per frame: target id -> pred id (matched above match_iou)
    present: list[set[int]] = []  # per frame: target ids
    for i, fr in enumerate(frames):
        try:
            r = culane.evaluate_image(
                fr.preds, fr.target, (*thresholds, float(match_iou)), width, fr.size or size, "official"
            )
        except ValueError as e:
            raise ValueError(f"{name} frame {i}: {e}") from None
        p_ids = _ids(fr.pred_ids, r.n_pred, "predicted", i)
        t_ids = _ids(fr.target_ids, r.n_gt, "annotated", i)
        frame_counts.append(r.counts)
        frame_mious.append(frame_miou(r))
        m = {}
        for p, g in enumerate(r.pred_to_gt.tolist()):
            if g >= 0 and r.matched_iou[p] > match_iou:
                m[t_ids[g]] = p_ids[p]
        matched.append(m)
        present.append(set(t_ids))
    switches = switch_chances = flickers = flicker_chances = 0
    for t in range(1, len(frames)):
        for g, p in matched[t].items():
            if g in matched[t - 1]:
                switch_chances += 1
                switches += matched[t - 1][g] != p
    for t in range(1, len(frames) - 1):
        for g in present[t]:
            if g in matched[t - 1] and g in matched[t + 1] and g in present[t - 1] and g in present[t + 1]:
                flicker_chances += 1
                flickers += g not in matched[t]
    sums = count_update([(0, 0, 0)] * len(thresholds), frame_counts, thresholds)
    return SequenceResult(
        name=name,
        frames=len(frames),
        miou=sequence_miou(frame_mious),
        counts=dict(zip(thresholds, sums, strict=True)),
        id_switches=switches,
        switch_chances=switch_chances,
        flickers=flickers,
        flicker_chances=flicker_chances,
        frame_miou=frame_mious,
    )


def evaluate(
    sequences: Mapping[str, Sequence[Frame]],
    iou_thresholds: Sequence[float] = VIDEO_IOU_THRESHOLDS,
    match_iou: float = MATCH_IOU,
    width: int = culane.LANE_WIDTH,
    size: tuple[int, int] = culane.CULANE_SIZE,
    progress: bool = False,
    jobs: int = 1,
) -> VideoResult:
    """Score sequences and combine them (mIoU: mean over sequences; F and stability: summed counts).

    Args:
        sequences: name -> frames in time order.
        iou_thresholds, match_iou, width, size: as :func:`evaluate_sequence`.
        progress: show a tqdm progress bar over the frames (when tqdm is installed).
        jobs: worker processes the sequences are spread over (1: this process; 0: one per core); the numbers
            do not depend on it.

    Returns:
        Dataset numbers and the per-sequence results (in the mapping's order).
    """
    if not sequences:
        raise ValueError("no sequence to evaluate")
    score = functools.partial(
        evaluate_sequence, iou_thresholds=iou_thresholds, match_iou=match_iou, width=width, size=size
    )
    per = map_sequences(score, sequences, jobs, progress, "video")
    thresholds = tuple(float(t) for t in iou_thresholds)
    sums = count_update([(0, 0, 0)] * len(thresholds), (s.counts for s in per), thresholds)
    totals = {t: culane.counts_to_prf(*c) for t, c in zip(thresholds, sums, strict=True)}
    mious = [s.miou for s in per if s.miou is not None]
    switches, chances = sum(s.id_switches for s in per), sum(s.switch_chances for s in per)
    flickers, f_chances = sum(s.flickers for s in per), sum(s.flicker_chances for s in per)
    return VideoResult(
        miou=dataset_miou(mious),
        totals=totals,
        id_switches=switches,
        switch_rate=switches / chances if chances else 0.0,
        flickers=flickers,
        flicker_rate=flickers / f_chances if f_chances else 0.0,
        sequences=len(per),
        frames=sum(s.frames for s in per),
        per_sequence=per,
    )
