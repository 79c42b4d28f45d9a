"""``stamlane predict``: lanes of a dataset split, a folder of frames or a video file, written to disk.

`LanePredictionWriter` (a Lightning prediction-writer callback) writes, under ``output_dir``:

- ``predictions.json`` — TuSimple json-lines (one line per key frame with ``h_samples``), scored as is by
  ``stamlane-eval tusimple predictions.json <gt.json>``;
- ``lines/<raw_file stem>.lines.txt`` — CULane text, one per key frame without ``h_samples`` (CULane,
  ApolloScape, VIL-100, folders, videos), scored by ``stamlane-eval culane <output_dir>/lines <gt_dir>``;
- ``overlays/<raw_file stem>.jpg`` — the original key frame with the predicted lanes (and the annotated
  ones in white when the split has labels), at most ``max_overlays`` of them.

With several processes (DDP) every rank writes ``predictions.rank<r>.json``.

`FramesDataModule` serves clips of consecutive frames from a folder of images (in name order, ``2.jpg`` before ``10.jpg``) or a video
file (decoded to JPEG files under ``frames_dir`` first), key frame last; the first frames of the sequence
repeat the earliest available frame as history.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import lightning.pytorch as pl
import numpy as np
from lightning.pytorch.callbacks import BasePredictionWriter
from torch.utils.data import DataLoader
from tqdm import tqdm

from stamlane.data.alignment import WARP_MODES
from stamlane.data.clips import IMAGE_SUFFIXES, ClipDataset, ClipEntry
from stamlane.data.collate import collate_clips
from stamlane.data.labels import DataError
from stamlane.data.transforms import ClipTransform
from stamlane.overlay import draw_lanes
from stamlane.writers import TusimpleWriter, culane_lines_path, write_culane_lines

__all__ = ["VIDEO_SUFFIXES", "FolderClips", "FramesDataModule", "LanePredictionWriter", "decode_video"]

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm")
"""File suffixes `FramesDataModule` treats as videos."""

_FORMATS = ("auto", "tusimple", "culane")


class LanePredictionWriter(BasePredictionWriter):
    """Write ``predict_step`` outputs as benchmark files and overlay pictures (see the module docstring).

    Args:
        output_dir: the output folder.
        format: ``"auto"`` (TuSimple json for frames with ``h_samples``, CULane text otherwise),
            ``"tusimple"`` (frames without ``h_samples`` are an error) or ``"culane"`` (always text).
        overlays: write overlay pictures.
        max_overlays: write at most this many overlays (``None``: all).
    """

    def __init__(
        self,
        output_dir: str = "outputs/predictions",
        format: str = "auto",
        overlays: bool = True,
        max_overlays: int | None = None,
    ) -> None:
        super().__init__(write_interval="batch")
        if format not in _FORMATS:
            raise ValueError(f"format must be one of {_FORMATS}, got {format!r}")
        if max_overlays is not None and max_overlays < 0:
            raise ValueError(f"max_overlays must be >= 0 or None, got {max_overlays}")
        self.output_dir = Path(output_dir)
        self.format = format
        self.overlays = overlays
        self.max_overlays = max_overlays
        self._json: TusimpleWriter | None = None
        self.written = {"tusimple": 0, "culane": 0, "overlays": 0}

    def on_predict_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self.written = {"tusimple": 0, "culane": 0, "overlays": 0}
        self._json = None
        self._data_root = Path(getattr(trainer.datamodule, "root", ".") or ".")

    def _json_writer(self, trainer: pl.Trainer) -> TusimpleWriter:
        if self._json is None:
            name = "predictions.json" if trainer.world_size == 1 else f"predictions.rank{trainer.global_rank}.json"
            self._json = TusimpleWriter(self.output_dir / name)
        return self._json

    def write_on_batch_end(
        self,
        trainer: pl.Trainer,
        pl_module: pl.LightningModule,
        prediction: Any,
        batch_indices: Any,
        batch: Any,
        batch_idx: int,
        dataloader_idx: int,
    ) -> None:
        gts = batch.get("lanes") if isinstance(batch, dict) else None
        for i, item in enumerate(prediction):
            meta, lanes = item["meta"], item["lanes"]
            raw_file = str(meta["raw_file"])
            h_samples = meta.get("h_samples")
            use_json = self.format == "tusimple" or (self.format == "auto" and h_samples is not None)
            if use_json:
                if h_samples is None:
                    raise ValueError(f"format 'tusimple' needs h_samples, {raw_file!r} has none")
                self._json_writer(trainer).write(raw_file, lanes, h_samples, item["run_time"])
                self.written["tusimple"] += 1
            else:
                write_culane_lines(self.output_dir / "lines", raw_file, lanes)
                self.written["culane"] += 1
            if self.overlays and (self.max_overlays is None or self.written["overlays"] < self.max_overlays):
                self._write_overlay(meta, lanes, gts[i] if gts is not None else None)

    def _write_overlay(self, meta: dict, lanes: list[np.ndarray], gt_lanes: list[np.ndarray] | None) -> None:
        key_path = self._data_root / meta["frame_paths"][-1] if meta.get("frame_paths") else None
        image = cv2.imread(str(key_path)) if key_path is not None else None
        if image is None:
            return
        path = culane_lines_path(self.output_dir / "overlays", str(meta["raw_file"])).with_suffix("")
        path = path.with_suffix(".jpg")  # <stem>.lines -> <stem>.jpg
        path.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(path), draw_lanes(image, lanes, gt_lanes))
        self.written["overlays"] += 1

    def on_predict_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if self._json is not None:
            self._json.close()
            self._json = None
        if trainer.is_global_zero:
            parts = [f"{n} {k}" for k, n in self.written.items() if n]
            print(f"stamlane predict: wrote {', '.join(parts) or 'nothing'} under {self.output_dir}")


class FolderClips(ClipDataset):
    """Every image of one folder (in name order, numbers compared as numbers) as the key frame of a clip of its predecessors; no labels.

    ``raw_file`` is the image's name; ``h_samples`` is ``None`` (lanes are written as CULane text).
    """

    format = "frames"

    def __init__(self, root: str | Path, **kwargs: Any) -> None:
        kwargs.update(history="sorted", repeat_missing_history=True, require_labels=False)
        super().__init__(root, **kwargs)

    def _index(self) -> list[ClipEntry | DataError]:
        names = self._sorted_listing(self.root)
        if not names:
            raise DataError(f"{self.root} holds no image ({', '.join(IMAGE_SUFFIXES)})")
        source = str(self.root)
        return [ClipEntry(name, self._clip_paths(name, source), [], None, source) for name in names]


def decode_video(video: str | Path, out_dir: str | Path, every: int = 1) -> Path:
    """Decode a video into ``out_dir/000000.jpg, 000001.jpg, ...`` (every ``every``-th frame); returns ``out_dir``."""
    capture = cv2.VideoCapture(str(video))
    if not capture.isOpened():
        raise DataError(f"cannot open video {video}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    total = int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) or None
    index = written = 0
    with tqdm(total=total, desc=f"decoding {Path(video).name}", unit="frame") as bar:
        while True:
            ok, frame = capture.read()
            if not ok:
                break
            if index % every == 0:
                cv2.imwrite(str(out / f"{written:06d}.jpg"), frame, [cv2.IMWRITE_JPEG_QUALITY, 95])
                written += 1
            index += 1
            bar.update(1)
    capture.release()
    if written == 0:
        raise DataError(f"no frame could be decoded from {video}")
    return out


class FramesDataModule(pl.LightningDataModule):
    """Prediction data from a folder of frames or a video file (see the module docstring).

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
