"""Write a synthetic clip set: `generate_dataset` renders every split's clips (in parallel when asked), writes each
clip (`stamlane.synth.writer`), the label files of the splits, factors and kinds, the visibility files and, last,
``dataset.json`` with the settings and statistics. The layout is `stamlane.synth.layout`'s.

Every clip is a function of ``(seed, split, index)`` alone, so the files do not depend on the order the clips are
rendered in nor on the number of workers; every file is written atomically, and ``dataset.json`` is removed first
and written last, so a set that has it is complete.
"""

from __future__ import annotations

import json
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path, PurePosixPath
from typing import Any

import cv2
import numpy as np
from tqdm import tqdm

from stamlane.safety.guard import make_folder, write_atomic
from stamlane.synth.clip import generate_clip
from stamlane.synth.config import FACTORS, REVEAL, REVEAL_TRAFFIC, TRAIN_MOTION, SynthConfig, clip_kinds
from stamlane.synth.layout import (
    EVAL_KEY_STEP,
    FIRST_KEY,
    FORMAT_VERSION,
    KIND_SPLITS,
    REVEAL_FRAMES,
    SPLITS,
    TEMPORAL_CLIPS_PER_FACTOR,
    TEMPORAL_LABELS,
    TRAIN_KEY_STEP,
    VISIBILITY_DIR,
    SplitCounts,
    key_frames,
)
from stamlane.synth.statistics import clip_statistics, key_frame_visibility, visibility_shares
from stamlane.synth.tusimple_layout import LAYOUTS, clip_folder, label_file, split_label_files, tusimple_rows
from stamlane.synth.writer import write_clip, write_json_lines

__all__ = ["generate_dataset", "write_temporal_labels"]


def write_temporal_labels(root: Path, challenging: int) -> Path | None:
    """Write `TEMPORAL_LABELS`: every frame from the ``FIRST_KEY + 1``-th of the challenging clips ``0 ..
    TEMPORAL_CLIPS_PER_FACTOR * len(FACTORS) - 1`` (as many of each factor), from their ``frame_labels``; None (and
    no file) for a set without challenging clips or with clips of fewer than ``FIRST_KEY + 2`` frames."""
    clips = min(challenging, TEMPORAL_CLIPS_PER_FACTOR * len(FACTORS))
    if clips == 0:
        return None
    records = []
    for i in range(clips):
        frames = json.loads((Path(root) / "frame_labels" / f"challenging-{i:04d}.json").read_text())
        records += [{k: f[k] for k in ("raw_file", "lanes", "h_samples")} for f in frames[FIRST_KEY:]]
    if len(records) < 2 * clips:  # clips too short for two frames with a full history each: nothing to follow
        return None
    path = Path(root) / TEMPORAL_LABELS
    write_json_lines(path, records)
    return path


@dataclass(frozen=True)
class _ClipJob:
    """What a worker of `generate_dataset` renders: clip ``index`` of ``split`` with ``config``."""

    root: Path
    split: str
    config: SynthConfig
    seed: int
    code: int
    index: int
    key_step: int
    visibility: bool
    reach: int = FIRST_KEY
    """History frames the visibility masks look back over (`key_frame_visibility`)."""
    layout: str = "stamlane"
    """Where the clip's frames go and the rows its lanes are labelled at (`stamlane.synth.tusimple_layout`)."""


def _make_clip(job: _ClipJob) -> tuple[list[dict[str, Any]], dict[str, float], list[dict[str, Any]]]:
    """Render and write one clip (a worker of `generate_dataset`): its key-frame records, `clip_statistics` and,
    when asked, the visibility records of its key frames (`key_frame_visibility`)."""
    cv2.setNumThreads(1)  # the pool already runs one clip per core
    rows = tusimple_rows(job.config.height) if job.layout == "tusimple" else None
    rng = np.random.default_rng([job.seed, job.code, job.index])
    clip = generate_clip(job.config, rng, paint_contrast=job.visibility, label_rows=rows)
    folder = clip_folder(job.layout, job.split, job.index)
    clip_id = f"{job.split}-{job.index:04d}"
    records = write_clip(clip, job.root, clip_id, job.config.jpeg_quality, job.key_step, folder)
    visibility = []
    if job.visibility:
        keys = key_frames(len(clip.frames), job.key_step)
        visibility = [
            {"raw_file": r["raw_file"], "visibility": key_frame_visibility(clip, k, job.reach)}
            for r, k in zip(records, keys)
        ]
    return records, clip_statistics(clip), visibility


def generate_dataset(
    root: str | Path,
    splits: SplitCounts,
    *,
    seed: int = 0,
    config: SynthConfig | None = None,
    progress: bool = True,
    train_key_step: int | None = None,
    eval_key_step: int | None = None,
    workers: int = 1,
    visibility: bool = True,
    layout: str = "stamlane",
) -> dict[str, Any]:
    """Write a synthetic clip set (the layout of `stamlane.synth.layout`).

    Args:
        root: output folder (created; existing clips of the same ids are overwritten).
        splits: clips per split (`SplitCounts`). ``challenging``: clip ``i`` has the factor
            ``challenging_factor(i)`` on top of ``config`` (`FACTORS`); each factor's key frames also go to
            ``challenging-<factor>.json``. ``train_factors``, ``val_factors``: clips with a challenging factor added
            to the train and val splits after their clean clips (ids ``train-<train + i>``: factor
            ``challenging_factor(i)``), so that training has a reason to read the history; they come from their own
            seeds (their split and index), never the test or challenging clips', and leave the clean clips as they
            were. With them, ``train-clean.json`` / ``val-clean.json`` list the clean clips' key frames alone.
            ``reveal``, ``reveal_traffic``: clips of the ``reveal`` and ``reveal-traffic`` splits (`REVEAL`,
            `REVEAL_TRAFFIC`, kinds cycled; the key frame alone labelled; visibility over every history frame).
            ``train_motion``: `TRAIN_MOTION` clips added to the train split after its factor clips (the reveal
            splits' ego motion, key frames as ``train_key_step``), named ``motion`` in ``clip_factors``.
        seed: master seed; clip ``i`` of a split depends only on ``(seed, split, i)``.
        config: settings of the normal splits (default ``SynthConfig()``); every factor and kind overrides it.
        progress: show a tqdm progress bar.
        train_key_step: key frames of the train clips (`key_frames`: 0 = the last frame only, 1 = every frame
            from ``FIRST_KEY`` on); None: `TRAIN_KEY_STEP` (0 in TuSimple's layout, the only step it takes).
        eval_key_step: key frames of the val, test and challenging clips (e.g. 3: frames 8, 11, 14, 17, 20 of
            20-frame clips, five fairly different views of each clip); None: `EVAL_KEY_STEP` (TuSimple: 0).
        workers: processes rendering clips in parallel (the files do not depend on it).
        visibility: write ``visibility/<split>.json`` for every split but train: for every labelled key-frame
            point, where its paint is visible (`key_frame_visibility`).
        layout: ``"stamlane"`` (the generator's, `stamlane.synth.layout`) or ``"tusimple"`` (TuSimple's own:
            ``clips/<date>/<id>/``, its label file names, its ``h_samples`` scaled to the frame height, the last
            frame alone labelled; `stamlane.synth.tusimple_layout`). The frames are the same in both.

    Returns:
        the content of ``dataset.json``: settings, counts, key frames and statistics per split.
    """
    root = Path(root)
    cfg = config or SynthConfig()
    counts = {split: getattr(splits, split.replace("-", "_")) for split in SPLITS}
    extra = {"train": splits.train_factors + splits.train_motion, "val": splits.val_factors}
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    tusimple = layout == "tusimple"
    if tusimple and (train_key_step or eval_key_step):
        raise ValueError(
            f"TuSimple's layout labels the last frame of a clip alone: key steps must be 0, got train_key_step "
            f"{train_key_step} and eval_key_step {eval_key_step}"
        )
    train_key_step = (0 if tusimple else TRAIN_KEY_STEP) if train_key_step is None else train_key_step
    eval_key_step = (0 if tusimple else EVAL_KEY_STEP) if eval_key_step is None else eval_key_step
    steps = {split: train_key_step if split == "train" else eval_key_step for split in SPLITS}
    steps |= {"reveal": 0, "reveal-traffic": 0}
    keys = {split: key_frames(cfg.num_frames, steps[split]) for split in SPLITS}  # checks the steps
    reach_of = {split: REVEAL_FRAMES - 1 if split in ("reveal", "reveal-traffic") else FIRST_KEY for split in SPLITS}
    make_folder(root, "--out")
    (root / "dataset.json").unlink(missing_ok=True)  # the old set's record first: incomplete until written, last
    stats: dict[str, dict[str, float | dict[str, float]]] = {}
    clip_factors: dict[str, str] = {}
    by_kind: dict[tuple[str, str], list[dict[str, Any]]] = {}
    total = sum(counts.values()) + sum(extra.values())
    bar = tqdm(total=total, desc=f"synthetic clips -> {root}", unit="clip", disable=not progress)
    pool = ProcessPoolExecutor(workers) if workers > 1 else None
    try:
        for code, split in enumerate(SPLITS):
            jobs, kinds = [], []
            for i in range(counts[split] + extra.get(split, 0)):
                kind = clip_kinds(split, i, counts[split])
                if split == "train" and i >= splits.train + splits.train_factors:
                    kind = ("motion", TRAIN_MOTION)
                split_cfg = cfg if kind is None else cfg.overridden(kind[1].overrides)
                if kind is not None:
                    clip_factors[f"{split}-{i:04d}"] = kind[0]
                kinds.append(None if kind is None else kind[0])
                see = visibility and split != "train"
                job = _ClipJob(root, split, split_cfg, seed, code, i, steps[split], see, reach_of[split], layout)
                jobs.append(job)
            records: list[dict[str, Any]] = []
            by_file: dict[str, list[dict[str, Any]]] = {name: [] for name in split_label_files(layout, split)}
            seen: list[dict[str, Any]] = []
            totals = {"key_points": 0, "hidden": 0, "revealed": 0, "unaligned_shift": 0.0}
            for index, kind_name, (clip_records, clip_stats, clip_seen) in zip(
                range(len(jobs)), kinds, pool.map(_make_clip, jobs) if pool else map(_make_clip, jobs)
            ):
                records += clip_records
                by_file[label_file(layout, split, index)] += clip_records
                seen += clip_seen
                if split in KIND_SPLITS and kind_name is not None:
                    by_kind.setdefault((split, kind_name), []).extend(clip_records)
                for k, v in clip_stats.items():
                    totals[k] += v
                bar.update(1)
            if records or split not in ("reveal", "reveal-traffic"):  # a set without them: no empty label files
                for name, file_records in by_file.items():
                    write_json_lines(root / name, file_records)
            if extra.get(split):  # the clean clips alone too: the set as it was before factor clips
                clean = [r for r in records if PurePosixPath(r["raw_file"]).parent.name not in clip_factors]
                write_json_lines(root / f"{split}-clean.json", clean)
            n = max(len(jobs), 1)
            stats[split] = {
                "clips": len(jobs),
                "key_frames": len(records),
                "hidden_fraction": totals["hidden"] / max(totals["key_points"], 1),
                "revealed_fraction_of_hidden": totals["revealed"] / max(totals["hidden"], 1),
                "unaligned_shift_px": totals["unaligned_shift"] / n,
            }
            if seen:
                write_json_lines(root / VISIBILITY_DIR / f"{split}.json", seen)
                stats[split]["paint_visibility_4_frames"] = visibility_shares(seen)
        for split in KIND_SPLITS:  # every factor of the challenging split has its file, even an empty one
            for name in {"challenging": FACTORS, "reveal": REVEAL, "reveal-traffic": REVEAL_TRAFFIC}[split]:
                if split == "challenging" or counts[split]:
                    write_json_lines(root / f"{split}-{name}.json", by_kind.get((split, name), []))
        write_temporal_labels(root, splits.challenging)
    finally:
        if pool:
            pool.shutdown()
        bar.close()
    info = {
        "generator": "stamlane.synth.generator",  # the name every format has recorded (the module still loads)
        "format_version": FORMAT_VERSION,
        "seed": seed,
        "config": asdict(cfg),
        "factors": {name: asdict(factor) for name, factor in FACTORS.items()},
        "reveal_kinds": {name: asdict(kind) for name, kind in (REVEAL | REVEAL_TRAFFIC).items()},
        "clip_factors": clip_factors,
        "visibility_reach": {split: reach_of[split] for split in SPLITS if split != "train" and visibility},
        "splits": splits.as_dict(),
        "key_frames": {split: [k + 1 for k in keys[split]] for split in SPLITS[:4]}
        | {split: [REVEAL_FRAMES] for split in ("reveal", "reveal-traffic") if counts[split]},
        "statistics": stats,
    }
    if tusimple:  # a set in the generator's own layout keeps the record it always had, byte for byte
        info |= {"layout": layout, "label_files": {split: split_label_files(layout, split) for split in SPLITS[:3]}}
    write_atomic(root / "dataset.json", json.dumps(info, indent=2))
    return info
