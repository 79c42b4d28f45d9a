"""``ClipDataModule``: the clip datasets behind Lightning's fit/validate/test/predict.

Under several processes (DDP) the validation, test and prediction splits are shared out without repeats
(`eval_sampler`) and every sample carries its index in the split (`Indexed`), so that scores and predictions are
gathered in the split's order, each image once (docs/distributed.md).
"""

from __future__ import annotations

import json
import os
import tempfile
import warnings
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch
from lightning import LightningDataModule
from lightning.pytorch.overrides.distributed import UnrepeatedDistributedSampler
from torch.utils.data import DataLoader, Dataset

from stamlane.data.clips import ClipDataset
from stamlane.data.collate import collate_clips
from stamlane.data.frame_store import FRAME_STORE
from stamlane.data.frames import VIDEO_SUFFIXES, FolderClips, SequenceCheck, check_sequence, decode_video, video_rate
from stamlane.data.labels import DataError
from stamlane.data.layouts import FORMATS, make_clips
from stamlane.data.options import DEMO_SYNTH, AugmentOptions, ClipOptions, LoaderOptions, SynthOptions
from stamlane.data.probes import FOLDER_HISTORIES, HISTORIES
from stamlane.synth.config import SynthConfig
from stamlane.synth.dataset import generate_dataset
from stamlane.synth.layout import DEFAULT_SYNTHETIC_ROOT, FORMAT_VERSION
from stamlane.training.lightning_compat import plain_hyperparameters

__all__ = [
    "DEFAULT_SYNTHETIC_ROOT",
    "FORMATS",
    "INDEX_KEY",
    "ClipDataModule",
    "FramesDataModule",
    "Indexed",
    "SequenceWarning",
    "eval_sampler",
]

INDEX_KEY = "index"
"""Meta entry of an evaluation or prediction sample: its index in the split (`Indexed`)."""


class Indexed(Dataset[dict[str, Any]]):
    """A split whose samples carry their index in it, ``meta[INDEX_KEY]``: the key by which the scores and the
    predictions of several processes are put back in the order of the split, each image once
    (`stamlane_eval.integrations.distributed.gather_records`).

    Args:
        dataset: a map-style dataset of sample dicts with a ``meta`` dict (`stamlane.data.clips.ClipDataset`).
    """

    def __init__(self, dataset: ClipDataset) -> None:
        self.dataset = dataset

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, index: int) -> dict[str, Any]:
        sample = self.dataset[index]
        sample["meta"] = {**sample["meta"], INDEX_KEY: int(index)}
        return sample


def eval_sampler(dataset: ClipDataset | Indexed, split: str) -> UnrepeatedDistributedSampler | None:
    """The sampler of an evaluation or prediction split under several processes: each process a strided share of
    the split (process r: images r, r + W, r + 2W, ...), no image repeated (PyTorch's ``DistributedSampler``, which
    Lightning puts in otherwise, pads the shards with repeats, scored twice); shares differ by one image at most.
    None with one process.

    Raises:
        DataError: fewer images than processes (a process without a batch would stall the others).
    """
    if not (torch.distributed.is_available() and torch.distributed.is_initialized()):
        return None
    world = torch.distributed.get_world_size()
    if world == 1:
        return None
    if len(dataset) < world:
        raise DataError(f"the {split} split has {len(dataset)} images, fewer than the {world} processes: use fewer")
    return UnrepeatedDistributedSampler(dataset, num_replicas=world, rank=torch.distributed.get_rank(), shuffle=False)


class SequenceWarning(UserWarning):
    """The frames of a ``--source`` folder or video are not one sequence, and the history is used anyway."""


_DEFAULT_LABELS = {"train": ["train.json"], "val": ["val.json"], "test": ["test.json"], "predict": ["test.json"]}


class ClipDataModule(LightningDataModule):
    """Clips of T frames (key frame last) with key-frame targets, for every stage.

    The options shared with other readers of clips come in groups (`stamlane.data.options`): ``clip`` (how a clip
    is read, also `FramesDataModule`'s and the model's), ``augment`` (training only), ``synth`` (the generated
    set) and ``loader``; on the command line ``--data.clip.num_frames 2``. What belongs to one labelled dataset is
    a plain argument.

    Args:
        root: data root. ``None``: the synthetic set at ``DEFAULT_SYNTHETIC_ROOT`` (``data/synthetic-v<format>``),
            generated when missing (with a progress bar) as ``synth`` says; the default label files are then
            ``train.json``/``val.json``/``test.json`` (``predict`` uses ``test.json``).
        format: ``"tusimple"`` (also the synthetic sets and custom data), ``"culane"``, ``"apollo"``,
            ``"vil100"`` (`stamlane.data.layouts.FORMATS`).
        clip: how a clip is read and resized (frames, stride, size, sky cut, alignment), in every split.
        augment: the training augmentation and key-frame corruption; validation/test/predict only resize.
        synth: the synthetic set generated when ``root`` is None (default the demo's, `DEMO_SYNTH`).
        loader: batch size and DataLoader workers.
        train_labels: label files (TuSimple json-lines) or list files (CULane, ApolloScape, VIL-100) of the train
            split, relative to ``root`` (None: ``train.json`` for TuSimple-layout sets).
        val_labels: the same for the val split (None: ``val.json``).
        test_labels: the same for the test split (None: ``test.json``).
        predict_labels: the same for ``stamlane predict`` (None: ``test.json``).
        label_dir: ApolloScape only: folder mirroring the images with ``.lines.txt`` labels.
        thickness: lane width of the targets in network pixels.
        on_error: ``"raise"`` or ``"skip"`` (warn and drop) on bad data.
        history_source: what fills the history slots of the val, test and predict samples
            (`stamlane.data.probes.HISTORIES`): ``"real"`` (default), ``"key"`` (copies of the key frame) or
            ``"other_clip"`` (another clip's history): scoring one model three ways measures whether it reads its
            history (docs/training.md).
    """

    def __init__(
        self,
        root: str | None = None,
        format: str = "tusimple",
        clip: ClipOptions = ClipOptions(),
        augment: AugmentOptions = AugmentOptions(),
        synth: SynthOptions = DEMO_SYNTH,
        loader: LoaderOptions = LoaderOptions(),
        train_labels: list[str] | None = None,
        val_labels: list[str] | None = None,
        test_labels: list[str] | None = None,
        predict_labels: list[str] | None = None,
        label_dir: str | None = None,
        thickness: int = 3,
        on_error: str = "raise",
        history_source: str = "real",
    ) -> None:
        super().__init__()
        if format not in FORMATS:
            raise ValueError(f"format must be one of {FORMATS}, got {format!r}")
        if history_source not in HISTORIES:
            raise ValueError(f"history_source must be one of {HISTORIES}, got {history_source!r}")
        self.save_hyperparameters()
        plain_hyperparameters(self)  # the groups as dicts: a weights_only checkpoint holds no dataclass
        self.clip, self.augment, self.synth, self.loader = clip, augment, synth, loader
        self.synthetic = root is None
        self.root = Path(root if root is not None else DEFAULT_SYNTHETIC_ROOT)
        self.format = format
        self.labels = {"train": train_labels, "val": val_labels, "test": test_labels, "predict": predict_labels}
        self.label_dir = label_dir if format == "apollo" else None
        self.thickness, self.on_error, self.history_source = thickness, on_error, history_source
        self.datasets: dict[str, ClipDataset] = {}
        self.train_transform = augment.transform(clip)
        self.eval_transform = clip.transform()
        self.key_corruption = augment.corruption()

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
            wanted = json.loads(json.dumps(asdict(self.synth.config())))
            recorded = info.get("config")
            if isinstance(recorded, dict):  # a setting added since the set was made had its default (label_lanes)
                recorded = json.loads(json.dumps(asdict(SynthConfig()))) | recorded
            if (
                info.get("format_version") != FORMAT_VERSION
                or recorded != wanted
                or info.get("splits") != self.synth.splits().as_dict()
                or info.get("seed") != self.synth.seed
            ):
                warnings.warn(
                    f"the synthetic set in {self.root} was generated with other settings or another generator "
                    f"version; using it as it is (delete the folder to regenerate)",
                    stacklevel=2,
                )
            return
        self.generate_synthetic(self.root)

    def generate_synthetic(self, root: str | Path) -> None:
        """Write a synthetic set as ``synth`` says (with a progress bar).

        ``prepare_data`` calls it for the default set; it writes whether or not a set is already there.

        Args:
            root: the folder to write the set in.
        """
        synth = self.synth
        generate_dataset(
            root,
            synth.splits(),
            seed=synth.seed,
            config=synth.config(),
            train_key_step=synth.train_key_step,
            eval_key_step=synth.eval_key_step,
            workers=max(1, min(4, os.cpu_count() or 1)),
        )

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
        train = split == "train"
        dataset = make_clips(
            self.format,
            self.root,
            self.split_labels(split),
            self.label_dir,
            clip=self.clip,
            transform=self.train_transform if train else self.eval_transform,
            thickness=self.thickness,
            on_error=self.on_error,
            require_labels=split != "predict",
            history_source="real" if train else self.history_source,
            key_corruption=self.key_corruption if train else None,
            strides=self.augment.strides if train else (),
        )
        if self.loader.memory_mb > 0:  # evaluation frames read once per process (training samples are never kept)
            FRAME_STORE.reserve(self.loader.memory_mb * 2**20)
            dataset.frame_store = FRAME_STORE
        return dataset

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

    def _loader(self, split: str) -> DataLoader[dict[str, Any]]:
        if split not in self.datasets:
            self.datasets[split] = self.make_dataset(split)
        dataset = self.datasets[split] if split == "train" else Indexed(self.datasets[split])
        sampler = None if split == "train" else eval_sampler(dataset, split)  # each image once under DDP
        if split in ("test", "predict") and sampler is None:
            self._materialise(self.datasets[split])
        return DataLoader(
            dataset,
            batch_size=self.loader.batch_size,
            shuffle=split == "train",
            sampler=sampler,
            num_workers=self.loader.num_workers,
            collate_fn=collate_clips,
            persistent_workers=self.loader.num_workers > 0,
        )

    def _materialise(self, dataset: ClipDataset) -> None:
        """A test or prediction split read whole: its frames into the process's store now, by ``min(4, cores)``
        threads, when they fit ``loader.memory_mb`` (`stamlane.data.frame_store`); the loader's workers, forked
        after, and every later pass on the same frames read them from memory. (Validation during training reads a
        part of its split: its worker keeps what it reads.)"""
        height, width = self.clip.image_size
        need = len(dataset) * self.clip.num_frames * height * width * 3
        if dataset.stores_frames and need <= self.loader.memory_mb * 2**20:
            dataset.materialise(threads=max(1, min(4, os.cpu_count() or 1)))

    def train_dataloader(self) -> DataLoader[dict[str, Any]]:
        return self._loader("train")

    def val_dataloader(self) -> DataLoader[dict[str, Any]]:
        return self._loader("val")

    def test_dataloader(self) -> DataLoader[dict[str, Any]]:
        return self._loader("test")

    def predict_dataloader(self) -> DataLoader[dict[str, Any]]:
        return self._loader("predict")


class FramesDataModule(LightningDataModule):
    """Prediction data from a folder of frames or a video file (``stamlane.data.frames``): clips of consecutive
    frames, key frame last, read as the model was trained (``stamlane predict --source`` passes the run's ``clip``
    and ``loader`` options).

    When the history is used (``clip.num_frames > 1`` and ``history_source="real"``), ``setup`` compares every
    frame with the one its history is read from (`stamlane.data.frames.check_sequence`, kept in ``sequence``):
    content that jumps between many frame pairs (unrelated pictures) is warned about (`SequenceWarning`), images of
    several sizes refused at once (`DataError`: a clip's frames must share one size; before, the first clip that
    mixed them stopped the prediction midway).

    Args:
        source: a folder of images or a video file.
        clip: how a clip is read and resized; ``stride`` counts positions of the sorted listing, ``align`` is
            ``"fly"`` or ``"none"`` (a folder has neither an alignment cache nor true homographies).
        loader: batch size and DataLoader workers.
        frames_dir: where a video is decoded (default: a fresh temporary folder, removed with the module: frames
            are never written beside the input, nor frames of an earlier decoding reused).
        history_source: ``"real"`` (each frame's predecessors) or ``"key"`` (each frame its own history: for
            pictures that are not one sequence).
        progress: show a progress bar while a video is decoded (`stamlane.data.frames.decode_video`).
    """

    def __init__(
        self,
        source: str,
        clip: ClipOptions = ClipOptions(),
        loader: LoaderOptions = LoaderOptions(),
        frames_dir: str | None = None,
        history_source: str = "real",
        progress: bool = True,
    ) -> None:
        super().__init__()
        path = Path(source)
        if not path.exists():
            raise DataError(f"prediction source {path} does not exist")
        if clip.align not in ("fly", "none"):
            raise ValueError(f"align must be 'fly' or 'none' for a folder or video, got {clip.align!r}")
        if history_source not in FOLDER_HISTORIES:
            raise ValueError(
                f"history_source must be one of {FOLDER_HISTORIES} for a folder or video, got {history_source!r}"
            )
        self.source = path
        self.is_video = path.is_file() and path.suffix.lower() in VIDEO_SUFFIXES
        if path.is_file() and not self.is_video:
            raise DataError(f"{path} is neither a folder of frames nor a video ({', '.join(VIDEO_SUFFIXES)})")
        self._decoded: tempfile.TemporaryDirectory[str] | None = None
        if self.is_video and not frames_dir:
            self._decoded = tempfile.TemporaryDirectory(prefix="stamlane-frames-")
            frames_dir = self._decoded.name
        self.root = Path(frames_dir) if frames_dir else path
        self.clip, self.loader, self.history_source, self.progress = clip, loader, history_source, progress
        self.video_fps: float | None = None
        """The video's frame rate (None for a folder, or a video that declares none): the overlay video's."""
        self.dataset: FolderClips | None = None
        self.sequence: SequenceCheck | None = None

    def prepare_data(self) -> None:
        if self.is_video:
            self.video_fps = video_rate(self.source)
            if not any(self.root.glob("*.jpg")):
                decode_video(self.source, self.root, progress=self.progress)

    def setup(self, stage: str | None = None) -> None:
        if self.dataset is not None:
            return
        self.dataset = FolderClips(self.root, clip=self.clip, history_source=self.history_source)
        if self.clip.num_frames > 1 and self.history_source == "real":
            names = [entry.raw_file for entry in self.dataset.entries]
            self.sequence = check_sequence(self.root, names, self.clip.stride)
            problem = self.sequence.problem()
            alone = "--data.history_source key: each frame alone"
            if not self.sequence.one_size:  # a clip of two sizes cannot be read: said now, not at its turn
                raise DataError(
                    f"{self.source} is not one sequence: {problem}; a clip's frames share one size ({alone})"
                )
            if problem is not None:
                n = self.clip.num_frames - 1
                before = "the frame" if n == 1 else f"the {n} frames"
                warnings.warn(
                    f"{self.source} is not one sequence: {problem}; every frame is read with {before} before it as "
                    f"history ({alone})",
                    SequenceWarning,
                    stacklevel=2,
                )

    def predict_dataloader(self) -> DataLoader[dict[str, Any]]:
        self.setup("predict")
        assert self.dataset is not None  # setup made it
        dataset = Indexed(self.dataset)
        return DataLoader(
            dataset,
            batch_size=self.loader.batch_size,
            sampler=eval_sampler(dataset, "predict"),
            num_workers=self.loader.num_workers,
            collate_fn=collate_clips,
        )
