"""Vehicles that hide the lanes: what the aligned history shows of the hidden paint, what the networks make of it.

    python benchmarks/traffic_diagnosis.py [--clips 20] [--seed 57] [--kinds KIND ...] [--ckpt NAME_OR_FILE ...]
                                           [--resamples 2000] [--align-preset standard] [--any-stride]
                                           [--out outputs/bench/traffic]

Issue 57 asks why the 4-frame models barely read their history on ``reveal-traffic``. For each kind of vehicle
traffic (the two ``reveal-traffic`` kinds at 5 fps, `REVEAL_TRAFFIC`, and the challenging split's three traffic
factors at 20 fps, `TRAFFIC_FACTORS`), ``--clips`` clips are rendered in memory exactly as ``stamlane synth --seed
SEED`` renders that kind's clips of its split (clip ``i`` of the split from ``[seed, split code, i]``; the default
settings), their frames through the JPEG round trip the data loader reads, their key frames those of the split
(the last of a ``reveal-traffic`` clip; every third from frame 8 of a challenging clip). Three measurements:

(a) **what the history shows**: a key-frame label point is *vehicle-hidden* where the generator's vehicle mask
    covers it (`hidden_points`: ``SynthClip.occluded``, what ``frame_labels/<clip>.json`` stores). Each of the 3
    history frames of a 4-frame model *shows* it when the paint is visible there (`stamlane.synth.visibility`: the
    frame's paint contrast >= 20 grey levels within 2 px) at the point the alignment maps the key point to: the
    generator's exact homography, or ORB/RANSAC as the models align on the fly (``estimate_clip``, chain, the
    standard preset, as the shipped checkpoints record);
(b) **what the networks do there**: each checkpoint on every key frame with its real history aligned by ORB (as it
    runs), aligned exactly, and with the key frame copied into every history slot; lane.py's F1 and the recall of
    label points (`stamlane.experiments.split_scores.point_hits`: the lane's best-matching prediction within
    lane.py's 20 px / cos(angle) there) of the vehicle-hidden points, those the exact history shows and those it
    does not, and of the points no vehicle hides; 95 % bootstrap intervals over clips, paired for history − copies;
(c) **where alignment fails**, at the last key frame of each clip: the ORB chain's corner error against the exact
    homography (`corner_error`: the key frame's ground corners sent back and forth, mean key pixels) per frames back
    and fps (each kind at 5 and at 20 fps), on the clip and on the same clip drawn without its vehicles (``occluder_prob=0``: the same road,
    texture and ego motion, the rest of the draws differ); for direct pairs, the share of the RANSAC support (the
    matches the final homography keeps within its 3 px threshold) on the vehicle masks, and the stage-1 fit's error
    with every match against the fit without the matches on vehicles (`fit_homography`).

``--align-preset NAME`` (of `ALIGN_PRESETS`; default ``standard``, the shipped models') aligns the ORB chain of (a)-(c);
another preset's (b) also runs the 4-frame models on the history ``standard`` aligns (the probe ``standard``, and
``real − standard`` paired over clips), and its (c) runs ``standard`` on each window right after it: its errors
(``standard_px``) and both chains' thread CPU time a window (``chain_ms``, ``standard_ms``); the support and stage-1
columns stay ``standard``'s.

``--any-stride`` also reads a checkpoint that records another frame stride, on the same consecutive frames: a
model fine-tuned at ``--data.clip.stride 4`` on 20 fps clips reads the 5 fps kinds at the spacing it was trained at
(and the 20 fps kinds at a quarter of it); ``diagnosis.json`` records each checkpoint's stride (``strides``).
Without it such a checkpoint is refused, since its spacing and the clips' differ.

Writes ``diagnosis.json`` and ``summary.md`` (the tables: `table`). Exit status 2 with one line on a bad option or a
checkpoint that cannot be read.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from _harness import Within, fail, option_problem, write_result
from synth_align import corner_error, jpeg  # a benchmark script beside this one

from stamlane.align.homography import ALIGN_PRESETS, align_preset
from stamlane.synth.clip import SynthClip, generate_clip
from stamlane.synth.config import FACTORS, REVEAL_TRAFFIC, SynthConfig
from stamlane.synth.layout import EVAL_KEY_STEP, SPLITS, key_frames
from stamlane.synth.visibility import paint_visibility

TRAFFIC_FACTORS = ("traffic_standing", "traffic_same_speed", "traffic_oncoming")
KINDS = (*REVEAL_TRAFFIC, *TRAFFIC_FACTORS)
DEFAULT_CKPTS = ("stam4-synthetic", "stam4-dashcam", "single-synthetic")
PROBES = ("real", "exact", "copies")  # ORB-aligned history (as the models run), exactly aligned, the key copied
HISTORY = 3  # history frames of the 4-frame models
FPS = (5.0, 20.0)
SUCCESS_PX = 2.0  # a corner error below it counts as aligned (benchmarks/synth_align.py's success)
VEHICLE_MARGIN_PX = 2  # a feature this close to a vehicle's pixels counts as on the vehicle (its corner, its edge)
MAX_CLIPS = 200
MAX_RESAMPLES = 20_000


class DiagnosisError(Exception):
    """A bad option or an unreadable checkpoint (one line, exit status 2)."""


# ------------------------------------------------------------------------------------------------ the clips
def kind_split(kind: str) -> tuple[str, int, int]:
    """The split a kind's clips belong to, the kind's position in its split's cycle and the cycle's length."""
    if kind in REVEAL_TRAFFIC:
        return "reveal-traffic", list(REVEAL_TRAFFIC).index(kind), len(REVEAL_TRAFFIC)
    return "challenging", list(FACTORS).index(kind), len(FACTORS)


def kind_config(kind: str, **overrides: Any) -> SynthConfig:
    """The settings of a kind's clips (the default settings with the kind's), with ``overrides`` after them."""
    factor = REVEAL_TRAFFIC[kind] if kind in REVEAL_TRAFFIC else FACTORS[kind]
    return SynthConfig().overridden(factor.overrides).overridden(overrides)


def split_index(kind: str, j: int) -> int:
    """The index in its split of the ``j``-th clip of ``kind`` (the split cycles its kinds)."""
    _, position, cycle = kind_split(kind)
    return position + j * cycle


def render(kind: str, seed: int, j: int, *, paint_contrast: bool = False, **overrides: Any) -> SynthClip:
    """The ``j``-th clip of ``kind`` as ``stamlane synth --seed SEED`` draws it (``overrides``: a variant of it)."""
    split = kind_split(kind)[0]
    rng = np.random.default_rng([seed, SPLITS.index(split), split_index(kind, j)])
    return generate_clip(kind_config(kind, **overrides), rng, paint_contrast=paint_contrast)


def clip_keys(kind: str, num_frames: int) -> list[int]:
    """The key frames (0-based) of a clip of ``kind``, as its split labels them."""
    return [num_frames - 1] if kind in REVEAL_TRAFFIC else key_frames(num_frames, EVAL_KEY_STEP)


# ---------------------------------------------------------------------------------------- (a) what it shows
def hidden_points(clip: SynthClip, key: int) -> list[tuple[int, int]]:
    """``(lane, row index)`` of every labelled key-frame point a vehicle hides (``SynthClip.occluded``)."""
    return [
        (n, r)
        for n, (lane, occ) in enumerate(zip(clip.labels[key], clip.occluded[key], strict=True))
        for r, (x, o) in enumerate(zip(lane, occ, strict=True))
        if x >= 0 and o
    ]


def history_shows(clip: SynthClip, key: int, key_from_hist: list[np.ndarray]) -> list[list[int]]:
    """`paint_visibility` of the key frame's points over it and the frames before it, through ``key_from_hist``
    (``key_from_hist[j]``: the frame ``j`` back -> the key frame; ``[0]`` the identity): bit ``j`` set where the
    paint is visible at the point the homography maps the key point to ``j`` frames back."""
    if clip.paint_contrast is None:
        raise ValueError("the clip was rendered without paint_contrast")
    contrasts = [clip.paint_contrast[key - j] for j in range(len(key_from_hist))]
    return paint_visibility(clip.labels[key], clip.h_samples, contrasts, key_from_hist)


def shown_counts(masks: list[list[int]], hidden: list[tuple[int, int]]) -> list[float]:
    """``[hidden points, shown by any history frame, shown 1, 2, 3 frames back]`` of one key frame."""
    bits = [masks[n][r] for n, r in hidden]
    any_shown = sum(any(b >> j & 1 for j in range(1, HISTORY + 1)) for b in bits)
    return [len(bits), any_shown, *(sum(b >> j & 1 for b in bits) for j in range(1, HISTORY + 1))]


# ---------------------------------------------------------------------------------------- (b) the networks
@dataclass
class Model:
    """A checkpoint opened for clips: its module, its clip options and the transform it reads frames with."""

    name: str
    module: Any
    clip: Any
    transform: Any

    @classmethod
    def open(cls, ckpt: str, any_stride: bool = False) -> Model:
        """``any_stride``: a checkpoint that records a stride other than 1 is read too, on consecutive frames."""
        from stamlane.data.transforms import ClipTransform
        from stamlane.safety.checkpoints import CheckpointError
        from stamlane.training.stored import StoredModel

        try:
            stored = StoredModel.open(ckpt)
            module, clip = stored.module, stored.settings.clip
        except (CheckpointError, OSError, ValueError) as err:
            raise DiagnosisError(f"--ckpt {ckpt}: {err}") from None
        if clip is None or (clip.stride != 1 and not any_stride) or module.num_frames not in (1, HISTORY + 1):
            of_stride = "" if any_stride else " of stride 1 (--any-stride reads other strides)"
            raise DiagnosisError(f"--ckpt {ckpt}: not a 1-frame or {HISTORY + 1}-frame model{of_stride}")
        return cls(Path(ckpt).stem, module, clip, ClipTransform(clip.image_size, crop_top=clip.crop_top))

    @property
    def frames(self) -> int:
        return int(self.module.num_frames)

    def lanes(self, frames: list[np.ndarray], key_from_hist: np.ndarray, h_samples: list[int]) -> list[list[float]]:
        """TuSimple x lists (at ``h_samples``) of the lanes found in a window (oldest first, key last) whose history
        ``key_from_hist`` (T, 3, 3) aligns onto the key frame, original pixels."""
        import torch
        from stamlane_eval.tusimple import lanes_to_xs

        frames, key_from_hist = frames[-self.frames :], key_from_hist[-self.frames :]
        params = self.transform.draw(frames[-1].shape[:2])
        clip = torch.from_numpy(self.transform.apply_frames(frames, key_from_hist, params))[None]
        with torch.inference_mode():
            logits, embedding = self.module(clip)
        meta = {"net_from_orig": params.net_from_orig, "orig_size": frames[-1].shape[:2], "h_samples": h_samples}
        return lanes_to_xs(self.module.decode(logits, embedding, [meta])[0], h_samples)


def point_counts(xs: list[list[float]], clip: SynthClip, key: int, hidden: list[tuple[int, int]], shown: set) -> list:
    """``[recalled, points]`` of the hidden points, the hidden ones the exact history shows, those it does not, and
    the points no vehicle hides (8 numbers) of one key frame's predictions ``xs``."""
    from stamlane.experiments.split_scores import point_hits

    hits = point_hits(xs, clip.labels[key], clip.h_samples)
    hidden_set = set(hidden)
    groups: list[list[bool]] = [[], [], [], []]
    for n, lane in enumerate(clip.labels[key]):
        for r, x in enumerate(lane):
            if x < 0:
                continue
            hit = hits[n][r]
            if (n, r) in hidden_set:
                groups[0].append(hit)
                groups[1 if (n, r) in shown else 2].append(hit)
            else:
                groups[3].append(hit)
    return [v for g in groups for v in (float(sum(g)), float(len(g)))]


POINT_GROUPS = ("hidden", "hidden_shown", "hidden_not_shown", "not_hidden")


# ----------------------------------------------------------------------------------------- (c) alignment
def on_mask(mask: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Whether each point ``(N, 2)`` lies within `VEHICLE_MARGIN_PX` of the mask's pixels, (N,) bool."""
    grown = cv2.dilate(mask, np.ones((2 * VEHICLE_MARGIN_PX + 1,) * 2, np.uint8))
    h, w = mask.shape
    cols = np.clip(np.round(points[:, 0]).astype(int), 0, w - 1)
    rows = np.clip(np.round(points[:, 1]).astype(int), 0, h - 1)
    return np.asarray(grown[rows, cols] > 0)


def support_on_vehicles(hist: np.ndarray, key: np.ndarray, masks: tuple[np.ndarray, np.ndarray], truth: np.ndarray):
    """One direct pair: ``(matches, matches on vehicles, inliers, inliers on vehicles)`` of the final estimate's
    support, and the stage-1 corner errors of the fit with every match and with those off the vehicles alone."""
    from stamlane.align.homography import (
        AlignConfig,
        FramePrep,
        default_horizon_row,
        estimate_prepared,
        fit_homography,
        match_features,
    )

    cfg, shape = AlignConfig(), key.shape[:2]
    row = default_horizon_row(shape[0])
    ph, pk = FramePrep(hist, row, cfg), FramePrep(key, row, cfg)
    src, dst = match_features(ph.features(), pk.features(cfg.key_scales), cfg)
    moving = on_mask(masks[0], src) | on_mask(masks[1], dst) if len(src) else np.zeros(0, bool)
    final = estimate_prepared(ph, pk, cfg)
    inliers = np.zeros(len(src), bool)
    if final.ok and len(src):
        mapped = cv2.perspectiveTransform(src.reshape(-1, 1, 2).astype(np.float64), final.key_from_hist)
        inliers = np.linalg.norm(mapped.reshape(-1, 2) - dst, axis=1) < cfg.ransac_threshold
    errors = []
    for keep in (np.ones(len(src), bool), ~moving):
        fit = fit_homography(src[keep], dst[keep], shape, row, cfg)
        errors.append(corner_error(fit.key_from_hist, truth, shape, row) if fit.ok else float("nan"))
    counts = [len(src), int(moving.sum()), int(inliers.sum()), int((inliers & moving).sum())]
    return counts, errors


def chain_errors(
    clip: SynthClip, frames: list[np.ndarray], key: int, preset: str = "standard"
) -> tuple[list, list, float]:
    """The ORB chain's corner error 1..3 frames back of a key frame (as the models align, with ``preset``), whether
    each was ok, and the window's thread CPU time in milliseconds."""
    from stamlane.align import estimate_clip
    from stamlane.align.homography import default_horizon_row

    shape = frames[key].shape[:2]
    row = default_horizon_row(shape[0])
    window = frames[key - HISTORY : key + 1]
    start = time.thread_time()
    alignments = estimate_clip(window, strategy="chain", config=align_preset(preset))
    ms = 1000 * (time.thread_time() - start)
    errors = [corner_error(alignments[HISTORY - j].key_from_hist, clip.key_from_hist(key, key - j), shape, row)
              for j in range(1, HISTORY + 1)]  # fmt: skip
    return errors, [alignments[HISTORY - j].ok for j in range(1, HISTORY + 1)], ms


def alignment_rows(kind: str, seed: int, j: int, preset: str = "standard") -> list[dict]:
    """(c) for the ``j``-th clip of ``kind``: a row per fps and vehicles (with / without), its last key frame."""
    rows = []
    for fps in FPS:
        clips = {"with": render(kind, seed, j, fps=fps), "without": render(kind, seed, j, fps=fps, occluder_prob=0.0)}
        for vehicles, clip in clips.items():
            frames = [jpeg(f, 92) for f in clip.frames]
            for key in clip_keys(kind, len(frames))[-1:]:  # the last key frame: one window a clip
                errors, oks, ms = chain_errors(clip, frames, key, preset)
                row: dict[str, Any] = {"clip": j, "fps": fps, "vehicles": vehicles, "key": key}
                row |= {"chain_px": errors, "chain_ok": oks}
                if preset != "standard":  # the plain chain on the same window, right after: a busy machine slows both
                    plain_errors, plain_oks, plain_ms = chain_errors(clip, frames, key)
                    row |= {"chain_ms": ms, "standard_px": plain_errors, "standard_ok": plain_oks,
                            "standard_ms": plain_ms}  # fmt: skip
                if vehicles == "with":
                    pairs = [
                        support_on_vehicles(
                            frames[key - b],
                            frames[key],
                            (clip.vehicle_masks[key - b], clip.vehicle_masks[key]),
                            clip.key_from_hist(key, key - b),
                        )
                        for b in range(1, HISTORY + 1)
                    ]
                    row |= {"support": [p[0] for p in pairs], "stage1_px": [p[1] for p in pairs]}
                rows.append(row)
    return rows


# ------------------------------------------------------------------------------------------------ the run
def chain_matrices(window: list[np.ndarray], preset: str) -> np.ndarray:
    """The key-from-history homographies of a window aligned as the models align on the fly (ORB, chain), with the
    alignment preset ``preset``."""
    from stamlane.align import estimate_clip

    return np.stack([a.key_from_hist for a in estimate_clip(window, strategy="chain", config=align_preset(preset))])


def key_frame_rows(kind: str, seed: int, j: int, models: list[Model], preset: str = "standard") -> list[dict]:
    """(a) and (b) for the ``j``-th clip of ``kind``: a row per key frame (another ``preset`` than ``standard``: the
    4-frame models also run on the history the ``standard`` chain aligns, the probe ``standard``)."""
    clip = render(kind, seed, j, paint_contrast=True)
    frames = [jpeg(f, 92) for f in clip.frames]
    rows = []
    for key in clip_keys(kind, len(frames)):
        window = frames[key - HISTORY : key + 1]
        chains = {name: chain_matrices(window, name) for name in dict.fromkeys((preset, "standard"))}
        orb, exact = chains[preset], np.stack([clip.key_from_hist(key, key - HISTORY + t) for t in range(HISTORY + 1)])
        hidden = hidden_points(clip, key)
        masks = {name: history_shows(clip, key, list(mats[::-1])) for name, mats in (("exact", exact), ("orb", orb))}
        shown = {(n, r) for n, r in hidden if any(masks["exact"][n][r] >> b & 1 for b in range(1, HISTORY + 1))}
        row: dict[str, Any] = {"clip": j, "key": key, "shown": {k: shown_counts(m, hidden) for k, m in masks.items()}}
        preds: dict[str, dict[str, Any]] = {}
        aligned = {
            "real": orb,
            "exact": exact,
            "copies": np.repeat(np.eye(3)[None], 4, 0),
            "standard": chains["standard"],
        }
        for model in models:
            probes = (*PROBES, *(("standard",) if preset != "standard" else ())) if model.frames > 1 else ("real",)
            for probe in probes:
                history = [window[-1]] * len(window) if probe == "copies" else window
                mats = aligned[probe]
                xs = model.lanes(history, mats, clip.h_samples)
                preds.setdefault(model.name, {})[probe] = {
                    "lanes": xs,
                    "points": point_counts(xs, clip, key, hidden, shown),
                }
        row["labels"] = {"lanes": clip.labels[key], "h_samples": clip.h_samples}
        row["models"] = preds
        rows.append(row)
    return rows


def run(kinds: list[str], clips: int, seed: int, ckpts: list[str], resamples: int, say: Any = print,
        preset: str = "standard", any_stride: bool = False) -> dict:  # fmt: skip
    """Every measurement on ``clips`` clips of each kind: the rows and their summary (`summarise`);
    ``any_stride``: see `Model.open`."""
    import torch

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    models = [Model.open(c, any_stride) for c in ckpts]
    names = [m.name for m in models]
    if len(set(names)) < len(names):
        raise DiagnosisError(f"--ckpt: two checkpoints of one name among {' '.join(names)}")
    out: dict[str, Any] = {"seed": seed, "clips": clips, "checkpoints": names, "kinds": {}}
    if preset != "standard":
        out["align_preset"] = preset
    if any_stride:
        out["strides"] = {m.name: m.clip.stride for m in models}
    start = time.perf_counter()
    for kind in kinds:
        key_rows = [r for j in range(clips) for r in key_frame_rows(kind, seed, j, models, preset)]
        align_rows = [r for j in range(clips) for r in alignment_rows(kind, seed, j, preset)]
        split, _, _ = kind_split(kind)
        out["kinds"][kind] = {
            "split": split,
            "fps": kind_config(kind).fps,
            "split_indices": [split_index(kind, j) for j in range(clips)],
            "summary": summarise(key_rows, align_rows, names, resamples),
        }
        say(f"{kind}: {len(key_rows)} key frames, {time.perf_counter() - start:.0f} s")
    return out


# ------------------------------------------------------------------------------------------------ summary
def _ratio(means: np.ndarray) -> float:
    return float(means[0] / means[1]) if means[1] > 0 else float("nan")


def _estimate(values: np.ndarray, groups: list[int], resamples: int, statistic: Any = _ratio) -> dict:
    from stamlane_eval.stats import bootstrap

    est = bootstrap(values, statistic, groups=groups, resamples=resamples)
    return {"value": est.value, "low": est.low, "high": est.high}


def _paired(a: np.ndarray, b: np.ndarray, groups: list[int], resamples: int, statistic: Any = _ratio) -> dict:
    from stamlane_eval.stats import paired_bootstrap

    est = paired_bootstrap(a, b, statistic, groups=groups, resamples=resamples)
    return {"value": est.value, "low": est.low, "high": est.high}


def summarise(key_rows: list[dict], align_rows: list[dict], names: list[str], resamples: int) -> dict:
    """(a), (b) and (c) of one kind: shares and recalls with their clip intervals, history − copies paired."""
    from stamlane_eval.stats import f1_of_rates, tusimple_rates
    from stamlane_eval.tusimple import evaluate

    groups = [r["clip"] for r in key_rows]
    out: dict[str, Any] = {
        "key_frames": len(key_rows),
        "hidden_points": int(sum(r["shown"]["exact"][0] for r in key_rows)),
    }
    for align in ("exact", "orb"):
        counts = np.array([r["shown"][align] for r in key_rows], float)
        out[f"shown_{align}"] = _estimate(counts[:, [1, 0]], groups, resamples)
        out[f"shown_{align}_back"] = [float(counts[:, 1 + b].sum() / max(counts[:, 0].sum(), 1)) for b in range(1, 4)]
    records = [{"raw_file": str(i), **r["labels"]} for i, r in enumerate(key_rows)]
    models: dict[str, Any] = {}
    for name in names:
        entry: dict[str, Any] = {}
        rates, points = {}, {}
        for probe in key_rows[0]["models"][name]:
            preds = [{"raw_file": str(i), "lanes": r["models"][name][probe]["lanes"], "run_time": 0} for i, r in
                     enumerate(key_rows)]  # fmt: skip
            rates[probe] = tusimple_rates(evaluate(preds, records, time_limit=False).per_image)
            points[probe] = np.array([r["models"][name][probe]["points"] for r in key_rows], float)
            row = {"f1": _estimate(rates[probe], groups, resamples, f1_of_rates)}
            for g, group in enumerate(POINT_GROUPS):
                row[group] = _estimate(points[probe][:, 2 * g : 2 * g + 2], groups, resamples)
            entry[probe] = row
        pairs = [(probe, "copies") for probe in ("real", "exact") if "copies" in rates]
        pairs += [("real", "standard")] if "standard" in rates else []
        for probe, base in pairs:
            use = {"f1": _paired(rates[probe], rates[base], groups, resamples, f1_of_rates)}
            for g, group in enumerate(POINT_GROUPS):
                cols = slice(2 * g, 2 * g + 2)
                use[group] = _paired(points[probe][:, cols], points[base][:, cols], groups, resamples)
            entry[f"{probe}_minus_{base}"] = use
        models[name] = entry
    out["models"] = models
    out["alignment"] = alignment_summary(align_rows, resamples)
    return out


def alignment_summary(rows: list[dict], resamples: int) -> dict:
    """Per fps, vehicles and frames back: pairs, the ORB chain's ok rate, median corner error and share within
    `SUCCESS_PX` (its clip interval); per fps with vehicles: the support on vehicles and the stage-1 errors."""
    out: dict[str, Any] = {}
    for fps in FPS:
        for vehicles in ("with", "without"):
            chosen = [r for r in rows if r["fps"] == fps and r["vehicles"] == vehicles]
            groups = [r["clip"] for r in chosen]
            for b in range(HISTORY):
                errors = np.array([r["chain_px"][b] for r in chosen])
                good = np.array([[float(r["chain_ok"][b] and r["chain_px"][b] < SUCCESS_PX), 1.0] for r in chosen])
                out[f"{fps:g}fps/{vehicles}/{b + 1}"] = {
                    "pairs": len(chosen),
                    "ok": float(np.mean([r["chain_ok"][b] for r in chosen])),
                    "median_px": float(np.median(errors)),
                    "p90_px": float(np.percentile(errors, 90)),
                    "success": _estimate(good, groups, resamples),
                }
                if chosen and "standard_px" in chosen[0]:  # another preset: standard's on the same windows, paired
                    plain = np.array([[float(r["standard_ok"][b] and r["standard_px"][b] < SUCCESS_PX), 1.0]
                                      for r in chosen])  # fmt: skip
                    out[f"{fps:g}fps/{vehicles}/{b + 1}"] |= {
                        "standard_median_px": float(np.median([r["standard_px"][b] for r in chosen])),
                        "standard_success": _estimate(plain, groups, resamples),
                        "success_minus_standard": _paired(good, plain, groups, resamples),
                    }
            if chosen and "chain_ms" in chosen[0]:
                out[f"{fps:g}fps/{vehicles}/ms"] = {"median_ms": float(np.median([r["chain_ms"] for r in chosen])),
                                                    "standard_median_ms": float(np.median([r["standard_ms"] for r in chosen]))}  # fmt: skip
        chosen = [r for r in rows if r["fps"] == fps and r["vehicles"] == "with"]
        for b in range(HISTORY):
            support = np.array([r["support"][b] for r in chosen], float)
            stage1 = np.array([r["stage1_px"][b] for r in chosen], float)
            both = np.isfinite(stage1).all(axis=1)
            out[f"{fps:g}fps/support/{b + 1}"] = {
                "matches_on_vehicles": float(support[:, 1].sum() / max(support[:, 0].sum(), 1)),
                "inliers_on_vehicles": float(support[:, 3].sum() / max(support[:, 2].sum(), 1)),
                "stage1_median_px_all": float(np.median(stage1[both, 0])) if both.any() else float("nan"),
                "stage1_median_px_off_vehicles": float(np.median(stage1[both, 1])) if both.any() else float("nan"),
                "stage1_fit_rate_all": float(np.isfinite(stage1[:, 0]).mean()),
                "stage1_fit_rate_off_vehicles": float(np.isfinite(stage1[:, 1]).mean()),
            }
    return out


def _pct(est: dict, sign: str = "") -> str:
    return f"{100 * est['value']:{sign}.1f} [{100 * est['low']:{sign}.1f}, {100 * est['high']:{sign}.1f}]"


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] + ["| " + " | ".join(r) + " |" for r in rows]


def table(out: dict) -> str:
    """The numbers as markdown: (a) shares shown, (b) per model and probe, (c) alignment."""
    kinds = out["kinds"]
    lines = [
        f"Seed {out['seed']}, {out['clips']} clips a kind; 95 % intervals over clips.",
        "",
        "(a) what the history shows",
    ]
    rows = []
    for kind, entry in kinds.items():
        s = entry["summary"]
        rows.append([kind, f"{entry['fps']:g}", str(s["key_frames"]), str(s["hidden_points"]), _pct(s["shown_exact"]),
                     _pct(s["shown_orb"]), " / ".join(f"{100 * v:.0f}" for v in s["shown_exact_back"]),
                     " / ".join(f"{100 * v:.0f}" for v in s["shown_orb_back"])])  # fmt: skip
    head = [
        "kind",
        "fps",
        "key frames",
        "hidden points",
        "shown, exact",
        "shown, ORB",
        "exact 1/2/3 back",
        "ORB 1/2/3 back",
    ]
    lines += [
        "",
        *_table(head, rows),
        "",
        "(b) the networks: F1 and recall of points, real (ORB) history / exact / copies",
    ]
    rows = []
    for kind, entry in kinds.items():
        for name, model in entry["summary"]["models"].items():
            for probe, row in model.items():
                if "_minus_" in probe:
                    cells = [_pct(row[k], "+") for k in ("f1", *POINT_GROUPS)]
                    rows.append([kind, name, probe.replace("_minus_", " − "), *cells])
                else:
                    rows.append([kind, name, probe, *(_pct(row[k]) for k in ("f1", *POINT_GROUPS))])
    head = ["kind", "checkpoint", "history", "F1", "hidden", "hidden, shown", "hidden, not shown", "not hidden"]
    lines += ["", *_table(head, rows), "", "(c) alignment: the ORB chain against the exact homography"]
    rows = []
    for kind, entry in kinds.items():
        a = entry["summary"]["alignment"]
        for fps in FPS:
            for b in range(1, HISTORY + 1):
                w, wo, sup = (a[f"{fps:g}fps/{v}/{b}"] for v in ("with", "without", "support"))
                rows.append([kind, f"{fps:g}", str(b), f"{w['median_px']:.2f} / {wo['median_px']:.2f}",
                             f"{w['p90_px']:.1f} / {wo['p90_px']:.1f}", _pct(w["success"]), _pct(wo["success"]),
                             f"{100 * sup['matches_on_vehicles']:.0f} / {100 * sup['inliers_on_vehicles']:.0f}",
                             f"{sup['stage1_median_px_all']:.2f} / {sup['stage1_median_px_off_vehicles']:.2f}"])  # fmt: skip
    head = ["kind", "fps", "back", "median px with / without vehicles", "p90 px", f"< {SUCCESS_PX:g} px, vehicles",
            f"< {SUCCESS_PX:g} px, none", "% matches / inliers on vehicles", "stage-1 px all / off vehicles"]  # fmt: skip
    lines += ["", *_table(head, rows)]
    if "align_preset" in out:
        lines += [*_preset_table(out), ""]
    return "\n".join(lines) + "\n"


def _preset_table(out: dict) -> list[str]:
    """(c) of another preset beside ``standard``'s on the same windows: < `SUCCESS_PX`, paired, median ms a window."""
    preset, rows = out["align_preset"], []
    for kind, entry in out["kinds"].items():
        a = entry["summary"]["alignment"]
        for fps in FPS:
            for vehicles in ("with", "without"):
                cells = [a[f"{fps:g}fps/{vehicles}/{b}"] for b in range(1, HISTORY + 1)]
                ms = a[f"{fps:g}fps/{vehicles}/ms"]
                rows.append([kind, f"{fps:g}", vehicles, " / ".join(f"{100 * c['standard_success']['value']:.0f}" for c in cells),
                             " / ".join(f"{100 * c['success']['value']:.0f}" for c in cells),
                             ", ".join(_pct(c["success_minus_standard"], "+") for c in cells),
                             f"{ms['standard_median_ms']:.0f} / {ms['median_ms']:.0f}"])  # fmt: skip
    head = ["kind", "fps", "vehicles", f"< {SUCCESS_PX:g} px 1/2/3 back, standard", f"{preset}",
            f"{preset} − standard, 1 / 2 / 3 back", f"ms a window, standard / {preset}"]  # fmt: skip
    return ["", f"(c') the ORB chain with the {preset} preset against standard's, the same windows", "", *_table(head, rows)]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=20, help=f"clips of each kind (2-{MAX_CLIPS})")
    parser.add_argument("--seed", type=int, default=57, help="generator seed (the demo's set is seed 0)")
    parser.add_argument("--kinds", nargs="+", default=list(KINDS), help=f"of {' '.join(KINDS)}")
    parser.add_argument("--ckpt", nargs="+", default=list(DEFAULT_CKPTS), help="shipped model names or checkpoints")
    parser.add_argument("--resamples", type=int, default=2000, help=f"bootstrap resamples (100-{MAX_RESAMPLES})")
    parser.add_argument("--align-preset", default="standard", help=f"of {' '.join(ALIGN_PRESETS)} (default: standard)")
    parser.add_argument("--any-stride", action="store_true", help="also read checkpoints of another frame stride")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/traffic"))
    args = parser.parse_args(argv)
    from stamlane.safety.guard import GuardError, check_outputs, write_atomic
    from stamlane.training.quiet import quiet_libraries

    quiet_libraries()
    ranges = {
        "clips": Within(2, MAX_CLIPS, " (the intervals resample clips)"),
        "resamples": Within(100, MAX_RESAMPLES),
        "seed": Within(0),
    }
    problem = option_problem(vars(args), choices={"kinds": KINDS}, ranges=ranges)
    if problem is None and args.align_preset not in ALIGN_PRESETS:
        problem = f"--align-preset must be one of {' '.join(ALIGN_PRESETS)}, got {args.align_preset!r}"
    if problem is None:
        inputs = [Path(c) for c in args.ckpt if Path(c).exists()]
        try:
            check_outputs(reads=inputs, folders=[args.out], protected=inputs)
        except GuardError as err:
            problem = str(err)
    if problem is None:
        try:
            out = run(list(dict.fromkeys(args.kinds)), args.clips, args.seed, args.ckpt, args.resamples,
                      preset=args.align_preset, any_stride=args.any_stride)  # fmt: skip
        except DiagnosisError as err:
            problem = str(err)
    if problem is not None:
        return fail("traffic_diagnosis", problem)
    write_result(args.out / "diagnosis.json", out, quiet=True)
    summary = table(out)
    write_atomic(args.out / "summary.md", summary)
    print(summary, end="")
    print(f"wrote {args.out}/: diagnosis.json, summary.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
