"""``ClipDataModule``: the clip datasets behind Lightning's fit/validate/test/predict."""

from __future__ import annotations

import json
import os
import warnings
from dataclasses import asdict
from pathlib import Path
from typing import Any

from lightning import LightningDataModule
from torch.utils.data import DataLoader

from stamlane.data.alignment import WARP_MODES
from stamlane.data.clips import FORMATS, HISTORY_SOURCES, ClipDataset, make_clips
from stamlane.data.collate import collate_clips
from stamlane.data.corruption import DEFAULT_KINDS, KeyFrameCorruption
from stamlane.data.frames import VIDEO_SUFFIXES, FolderClips, decode_video
from stamlane.data.labels import DataError
from stamlane.data.transforms import ClipTransform
from stamlane.synth.generator import (
    DEFAULT_SYNTHETIC_ROOT,
    EVAL_KEY_STEP,
    FORMAT_VERSION,
    TRAIN_KEY_STEP,
    SynthConfig,
    generate_dataset,
)

__all__ = ["DEFAULT_SYNTHETIC_ROOT", "FORMATS", "ClipDataModule", "FramesDataModule"]

SYNTH_TRAIN_FACTORS = 120
"""Factor clips (15 per factor) beside the 120 clean train clips of the default synthetic set (docs/training.md:
what makes the fusion read its history)."""
SYNTH_VAL_FACTORS = 32
"""Factor clips (4 per factor) beside the 20 clean val clips of the default synthetic set."""

_DEFAULT_LABELS = {"train": ["train.json"], "val": ["val.json"], "test": ["test.json"], "predict": ["test.json"]}


class ClipDataModule(LightningDataModule):
    """Clips of T frames (key frame last) with key-frame targets, for every stage.

    Args:
        root: data root. ``None``: the synthetic set at ``DEFAULT_SYNTHETIC_ROOT`` (``data/synthetic-v<format>``),
            generated when missing (with a progress bar) from the ``synth_*`` options; the default label files are then
            ``train.json``/``val.json``/``test.json`` (``predict`` uses ``test.json``).
        format: ``"tusimple"`` (also the synthetic sets and custom data), ``"culane"``, ``"apollo"``,
            ``"vil100"``.
        num_frames: frames per clip T (the paper: 4 on TuSimple, 2 on ApolloScape).
        stride: distance between clip frames (frame numbers; 30 for CULane's stored frames).
        image_size: network input ``(H, W)``.
        crop_top: fraction of the frame height cut off at the top (sky) before resizing to ``image_size``, in
            every split (see ``ClipTransform``); prediction from a folder or a video and ``stamlane stream`` read
            it from the run's config or checkpoint.
        align: ``"fly"`` (default: the paper's ORB pre-alignment, estimated per clip and memoised),
            ``"cache"`` (``stamlane align`` output in ``cache_dir``), ``"none"`` (no alignment), or
            ``"true"`` (the synthetic generator's exact homographies, an oracle for experiments).
        warp: where that alignment is applied: ``"image"`` (default: history frames warped onto the key frame
            before the network, the paper's pre-alignment) or ``"feature"`` (frames unwarped, the homographies
            in network pixels in the batch as ``key_from_hist_net``; `stamlane.module.StamLaneModule` then warps
            the history FEATURES, as `stamlane.stream.StreamingPredictor` does: train with it for streaming).
        cache_dir: alignment cache folder for ``align="cache"``.
        batch_size: clips per batch.
        num_workers: DataLoader worker processes.
        train_labels, val_labels, test_labels, predict_labels: label files (TuSimple json-lines) or list
            files (CULane, ApolloScape, VIL-100) per split, relative to ``root``.
        thickness: lane width of the targets in network pixels.
        on_error: ``"raise"`` or ``"skip"`` (warn and drop) on bad data.
        crop_scale, flip_prob, brightness, contrast, saturation, hue: training augmentation, one draw per
            clip (see ``ClipTransform``); validation/test/predict only resize.
        label_dir: ApolloScape only: folder mirroring the images with ``.lines.txt`` labels.
        repeat_missing_history: reuse the nearest later frame when a history frame does not exist.
        horizon_row: first ground row for ``align="fly"`` (None: ``stamlane.align``'s default).
        align_strategy: ``"chain"`` (default) or ``"direct"`` matching for ``align="fly"``.
        history_source: what fills the history slots of the val, test and predict samples
            (`stamlane.data.clips.HISTORY_SOURCES`): ``"real"`` (default), ``"key"`` (copies of the key frame) or
            ``"other_clip"`` (another clip's history): scoring one model three ways measures whether it reads its
            history (docs/training.md).
        key_corruption: chance that a training sample's key frame alone is corrupted, history intact
            (`stamlane.data.corruption.KeyFrameCorruption`: dropped regions, glare, occluders); 0 = never.
        key_corruption_kinds: the kinds drawn from (`stamlane.data.corruption.CORRUPTIONS`).
        synth_train, synth_val, synth_test, synth_challenging: clips per split of a generated set.
        synth_train_factors, synth_val_factors: clips with a challenging factor added to the train and val splits
            of a generated set (`stamlane.synth.generate_dataset`'s ``train_factors`` / ``val_factors``).
        synth_train_key_step, synth_eval_key_step: labelled key frames per clip of the train split and of the
            others (``stamlane.synth.generator.key_frames``: 1 = every frame from the 8th, 3 = frames 8, 11, .., 20).
        synth_seed: seed of a generated set.
        synth_size: ``(H, W)`` frame size of a generated set.
    """

    def __init__(
        self,
        root: str | None = None,
        format: str = "tusimple",
        num_frames: int = 4,
        stride: int = 1,
        image_size: tuple[int, int] = (128, 256),
        crop_top: float = 0.0,
        align: str = "fly",
        warp: str = "image",
        cache_dir: str | None = None,
        batch_size: int = 4,
        num_workers: int = 0,
        train_labels: list[str] | None = None,
        val_labels: list[str] | None = None,
        test_labels: list[str] | None = None,
        predict_labels: list[str] | None = None,
        thickness: int = 3,
        on_error: str = "raise",
        crop_scale: tuple[float, float] = (0.85, 1.0),
        flip_prob: float = 0.5,
        brightness: float = 0.2,
        contrast: float = 0.2,
        saturation: float = 0.2,
        hue: float = 0.0,
        label_dir: str | None = None,
        repeat_missing_history: bool = False,
        horizon_row: int | None = None,
        align_strategy: str = "chain",
        history_source: str = "real",
        key_corruption: float = 0.0,
        key_corruption_kinds: tuple[str, ...] = DEFAULT_KINDS,
        synth_train: int = 120,
        synth_val: int = 20,
        synth_test: int = 100,
        synth_challenging: int = 128,
        synth_train_factors: int = SYNTH_TRAIN_FACTORS,
        synth_val_factors: int = SYNTH_VAL_FACTORS,
        synth_train_key_step: int = TRAIN_KEY_STEP,
        synth_eval_key_step: int = EVAL_KEY_STEP,
        synth_seed: int = 0,
        synth_size: tuple[int, int] = (360, 640),
    ) -> None:
        super().__init__()
        if format not in FORMATS:
            raise ValueError(f"format must be one of {FORMATS}, got {format!r}")
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        if num_workers < 0:
            raise ValueError(f"num_workers must be >= 0, got {num_workers}")
        if warp not in WARP_MODES:
            raise ValueError(f"warp must be one of {WARP_MODES}, got {warp!r}")
        if align_strategy not in ("chain", "direct"):
            raise ValueError(f"align_strategy must be 'chain' or 'direct', got {align_strategy!r}")
        if history_source not in HISTORY_SOURCES:
            raise ValueError(f"history_source must be one of {HISTORY_SOURCES}, got {history_source!r}")
        corrupt = KeyFrameCorruption(key_corruption, tuple(key_corruption_kinds))  # checked even when unused
        self.key_corruption = corrupt if key_corruption > 0 else None
        self.save_hyperparameters()
        self.synthetic = root is None
        self.root = Path(root if root is not None else DEFAULT_SYNTHETIC_ROOT)
        self.format = format
        self.labels = {"train": train_labels, "val": val_labels, "test": test_labels, "predict": predict_labels}
        self.datasets: dict[str, ClipDataset] = {}
        # checked now, so a bad option fails at construction, not in the first epoch
        self.train_transform = ClipTransform(
            image_size,
            crop_top=crop_top,
            crop_scale=crop_scale,
            flip_prob=flip_prob,
            brightness=brightness,
            contrast=contrast,
            saturation=saturation,
            hue=hue,
        )
        self.eval_transform = ClipTransform(image_size, crop_top=crop_top)

    def prepare_data(self) -> None:
        """Generate the default synthetic set when ``root`` is None and it is missing.

        An existing set is never overwritten; when it was made by another generator version or other
        settings, a warning says so (delete the folder to regenerate).
        """
        if not self.synthetic:
            return
        info_path = self.root / "dataset.json"
        if info_path.is_file():
            info = json.loads(info_path.read_text())
            hp = self.hparams
            wanted = json.loads(json.dumps(asdict(self._synth_config())))
            counts = {"train": hp.synth_train, "val": hp.synth_val, "test": hp.synth_test}
            counts["challenging"] = hp.synth_challenging
            counts |= {"train_factors": hp.synth_train_factors, "val_factors": hp.synth_val_factors}
            if (
                info.get("format_version") != FORMAT_VERSION
                or info.get("config") != wanted
                or info.get("splits") != counts
                or info.get("seed") != hp.synth_seed
            ):
                warnings.warn(
                    f"the synthetic set in {self.root} was generated with other settings or another generator "
                    f"version; using it as it is (delete the folder to regenerate)",
                    stacklevel=2,
                )
            return
        self.generate_synthetic(self.root)

    def generate_synthetic(self, root: str | Path) -> None:
        """Write a synthetic set with this module's ``synth_*`` settings (with a progress bar).

        ``prepare_data`` calls it for the default set; it writes whether or not a set is already there.

        Args:
            root: the folder to write the set in.
        """
        hp = self.hparams
        generate_dataset(
            root,
            train=hp.synth_train,
            val=hp.synth_val,
            test=hp.synth_test,
            challenging=hp.synth_challenging,
            train_factors=hp.synth_train_factors,
            val_factors=hp.synth_val_factors,
            seed=hp.synth_seed,
            config=self._synth_config(),
            train_key_step=hp.synth_train_key_step,
            eval_key_step=hp.synth_eval_key_step,
            workers=max(1, min(4, os.cpu_count() or 1)),
        )

    def _synth_config(self) -> SynthConfig:
        h, w = self.hparams.synth_size
        return SynthConfig(width=int(w), height=int(h))

    def split_labels(self, split: str) -> list[str]:
        """Label/list files of a split (the defaults apply to TuSimple-layout sets)."""
        files = self.labels[split]
        if files is None:
            if self.format != "tusimple":
                raise ValueError(f"{split}_labels must be given for format {self.format!r}")
            files = _DEFAULT_LABELS[split]
        return [files] if isinstance(files, str) else list(files)

    def make_dataset(self, split: str) -> ClipDataset:
        """Build the dataset of one split (``train`` augments; the others only resize)."""
        hp = self.hparams
        common: dict[str, Any] = {
            "num_frames": hp.num_frames,
            "stride": hp.stride,
            "image_size": tuple(hp.image_size),
            "align": hp.align,
            "warp": hp.warp,
            "cache_dir": hp.cache_dir,
            "transform": self.train_transform if split == "train" else self.eval_transform,
            "thickness": hp.thickness,
            "on_error": hp.on_error,
            "repeat_missing_history": hp.repeat_missing_history,
            "require_labels": split != "predict",
            "horizon_row": hp.horizon_row,
            "align_strategy": hp.align_strategy,
            "history_source": "real" if split == "train" else hp.history_source,
            "key_corruption": self.key_corruption if split == "train" else None,
        }
        label_dir = hp.label_dir if self.format == "apollo" else None
        return make_clips(self.format, self.root, self.split_labels(split), label_dir, **common)

    def setup(self, stage: str | None = None) -> None:
        wanted = {
            "fit": ("train", "val"),
            "validate": ("val",),
            "test": ("test",),
            "predict": ("predict",),
            None: ("train", "val", "test"),
        }.get(stage, ())
        for split in wanted:
            if split not in self.datasets:
                self.datasets[split] = dataset = self.make_dataset(split)
                if dataset.skipped:  # on_error: skip; every one was also warned about when it was read
                    total = len(dataset) + len(dataset.skipped)
                    warnings.warn(
                        f"{split}: skipped {len(dataset.skipped)} of {total} samples with bad data "
                        f"(on_error: skip); the first: {dataset.skipped[0]}",
                        stacklevel=2,
                    )

    def _loader(self, split: str) -> DataLoader:
        if split not in self.datasets:
            self.datasets[split] = self.make_dataset(split)
        return DataLoader(
            self.datasets[split],
            batch_size=self.hparams.batch_size,
            shuffle=split == "train",
            num_workers=self.hparams.num_workers,
            collate_fn=collate_clips,
            persistent_workers=self.hparams.num_workers > 0,
        )

    def train_dataloader(self) -> DataLoader:
        return self._loader("train")

    def val_dataloader(self) -> DataLoader:
        return self._loader("val")

    def test_dataloader(self) -> DataLoader:
        return self._loader("test")

    def predict_dataloader(self) -> DataLoader:
        return self._loader("predict")


class FramesDataModule(LightningDataModule):
    """Prediction data from a folder of frames or a video file (``stamlane.data.frames``): clips of consecutive frames, key frame last.

    Args:
        source: a folder of images or a video file.
        num_frames: frames per clip T, key frame last.
        stride: distance between clip frames, in positions of the sorted listing.
        image_size: network input ``(H, W)``.
        crop_top: fraction of the frame height cut off at the top, as the model was trained (``ClipTransform``).
        align: ``"fly"`` (the paper's pre-alignment) or ``"none"``.
        warp: ``"image"`` (history frames warped before the network) or ``"feature"`` (unwarped frames and
            ``key_from_hist_net``, for a model trained with ``warp="feature"``; see `stamlane.data.clips`).
        batch_size: clips per batch.
        num_workers: DataLoader workers.
        frames_dir: where a video is decoded (default: ``<video>.frames`` beside the video).
        horizon_row: first ground row for ``align="fly"`` (None: ``stamlane.align``'s default).
    """

    def __init__(
        self,
        source: str,
        num_frames: int = 4,
        stride: int = 1,
        image_size: tuple[int, int] = (128, 256),
        crop_top: float = 0.0,
        align: str = "fly",
        warp: str = "image",
        batch_size: int = 4,
        num_workers: int = 0,
        frames_dir: str | None = None,
        horizon_row: int | None = None,
    ) -> None:
        super().__init__()
        path = Path(source)
        if not path.exists():
            raise DataError(f"prediction source {path} does not exist")
        if align not in ("fly", "none"):
            raise ValueError(f"align must be 'fly' or 'none' for a folder or video, got {align!r}")
        if warp not in WARP_MODES:
            raise ValueError(f"warp must be one of {WARP_MODES}, got {warp!r}")
        self.source = path
        self.is_video = path.is_file() and path.suffix.lower() in VIDEO_SUFFIXES
        if path.is_file() and not self.is_video:
            raise DataError(f"{path} is neither a folder of frames nor a video ({', '.join(VIDEO_SUFFIXES)})")
        self.root = Path(frames_dir) if frames_dir else (path.with_suffix(".frames") if self.is_video else path)
        self.options = {
            "num_frames": num_frames,
            "stride": stride,
            "image_size": tuple(image_size),
            "align": align,
            "warp": warp,
            "horizon_row": horizon_row,
        }
        self.crop_top = crop_top
        self.batch_size = batch_size
        self.num_workers = num_workers
        self.dataset: FolderClips | None = None

    def prepare_data(self) -> None:
        if self.is_video and not any(self.root.glob("*.jpg")):
            decode_video(self.source, self.root)

    def setup(self, stage: str | None = None) -> None:
        if self.dataset is None:
            size = self.options["image_size"]
            transform = ClipTransform(size, crop_top=self.crop_top)
            self.dataset = FolderClips(self.root, transform=transform, **self.options)

    def predict_dataloader(self) -> DataLoader:
        self.setup("predict")
        return DataLoader(
            self.dataset, batch_size=self.batch_size, num_workers=self.num_workers, collate_fn=collate_clips
        )
