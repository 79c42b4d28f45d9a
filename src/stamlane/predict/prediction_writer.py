"""``stamlane predict``: lanes of a dataset split, a folder of frames or a video file, written to disk.

`LanePredictionWriter` (a Lightning prediction-writer callback) writes, under ``output_dir``:

- ``predictions.json`` — TuSimple json-lines (one line per key frame with ``h_samples``), scored as is by
  ``stamlane-eval tusimple predictions.json <gt.json>``;
- ``lines/<raw_file stem>.lines.txt`` — CULane text, one per key frame without ``h_samples`` (CULane,
  ApolloScape, VIL-100, folders, videos), scored by ``stamlane-eval culane <output_dir>/lines <gt_dir>``;
- ``overlays/<raw_file stem>.jpg`` — the original key frame with the predicted lanes and a legend (the model's
  name; where the split has labels, the annotated lanes and the image's score: `stamlane.predict.image_score`), at most
  ``max_overlays`` of them;
- ``overlay.mp4`` — for a video source, every frame with its lanes and legend, at the video's frame rate (mp4v),
  written under a temporary name and renamed when prediction ends.

``stamlane predict`` chooses ``output_dir`` when it is not given: one folder per model and source
(`default_output_dir`), so that a split's json and a video's lines never mix. With several processes (DDP) each
writes the lines and overlays of its share of the frames; the json lines are gathered on rank 0, which writes one
``predictions.json`` in the order of the split, as one process does (no overlay video: the frames are split between
the ranks; one process writes it).

The data of ``stamlane predict --source FOLDER|VIDEO`` is ``stamlane.data.datamodule.FramesDataModule``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import lightning.pytorch as pl
import numpy as np
import torch
from lightning.pytorch.callbacks import BasePredictionWriter
from stamlane_eval.integrations.distributed import gather_records
from stamlane_eval.io import culane_lines_path

from stamlane.predict.image_score import image_score
from stamlane.predict.overlay import draw_lanes, draw_legend
from stamlane.predict.writers import TusimpleWriter, output_path, write_culane_lines
from stamlane.safety.guard import atomic_path, make_folder, temporary_name
from stamlane.safety.images import read_image
from stamlane.safety.owner import mark
from stamlane.types import Lanes

__all__ = ["DEFAULT_ROOT", "VIDEO_NAME", "LanePredictionWriter", "default_output_dir", "folder_name"]

_FORMATS = ("auto", "tusimple", "culane")
DEFAULT_ROOT = Path("outputs/predict")
"""Where ``stamlane predict`` writes when no ``--predictions.output_dir`` is given (`default_output_dir`)."""
VIDEO_NAME = "overlay.mp4"
"""The overlay video of a video source, in the output folder."""
FALLBACK_FPS = 10.0
"""Frame rate of the overlay video of a video that declares none (as ``stamlane stream``)."""


def folder_name(text: str) -> str:
    """``text`` as one folder name: every character but letters, digits, ``.``, ``_``, ``-`` and ``+`` becomes
    ``_``, leading dots are dropped (never ``..`` nor a hidden folder), at most 100 characters."""
    name = re.sub(r"[^A-Za-z0-9._+-]", "_", text).lstrip(".")[:100]
    return name or "_"


def default_output_dir(model: str, source: str) -> Path:
    """``outputs/predict/<model>/<source>``: one folder per model and per source (`folder_name` of each)."""
    return DEFAULT_ROOT / folder_name(model) / folder_name(source)


class LanePredictionWriter(BasePredictionWriter):
    """Write ``predict_step`` outputs as benchmark files, overlay pictures and, for a video, an overlay video (see
    the module docstring).

    Args:
        output_dir: the output folder; None: ``stamlane predict`` chooses one per model and source
            (`default_output_dir`), ``outputs/predict/predictions`` when the callback is used alone.
        format: ``"auto"`` (TuSimple json for frames with ``h_samples``, CULane text otherwise),
            ``"tusimple"`` (frames without ``h_samples`` are an error) or ``"culane"`` (always text).
        overlays: write overlay pictures (and the overlay video).
        max_overlays: write at most this many overlay pictures (``None``: all); the overlay video has every frame.
        video: write ``overlay.mp4`` when the source is a video (the data module says so with ``is_video`` and
            ``video_fps``, as `stamlane.data.datamodule.FramesDataModule` does).
        model_name: the name in the overlays' legend (None: ``stamlane predict`` names the checkpoint's run).
        verbose: print what was written when prediction ends (the experiment engine turns it off).
    """

    def __init__(
        self,
        output_dir: str | None = None,
        format: str = "auto",
        overlays: bool = True,
        max_overlays: int | None = None,
        video: bool = True,
        model_name: str | None = None,
        verbose: bool = True,
    ) -> None:
        super().__init__(write_interval="batch")
        self.verbose = verbose
        if format not in _FORMATS:
            raise ValueError(f"format must be one of {_FORMATS}, got {format!r}")
        if max_overlays is not None and max_overlays < 0:
            raise ValueError(f"max_overlays must be >= 0 or None, got {max_overlays}")
        self.given_output_dir = output_dir is not None  # stamlane predict chooses one otherwise
        self.output_dir = Path(output_dir) if output_dir is not None else DEFAULT_ROOT / "predictions"
        self.format = format
        self.overlays = overlays
        self.max_overlays = max_overlays
        self.video = video
        self.model_name = model_name
        self.owner: dict[str, Any] | None = None  # what the folder holds the results of (stamlane.safety.owner)
        self._json: TusimpleWriter | None = None
        # several processes: (image key, json line's values: raw_file, lanes, h_samples, run_time), for rank 0
        self._rows: list[tuple[Any, tuple[str, Lanes, Sequence[int], float]]] = []
        self._video: cv2.VideoWriter | None = None
        self._video_fps: float | None = None
        self.written = {"tusimple": 0, "culane": 0, "overlays": 0, "video frames": 0}
        self._done = False  # on_predict_end was reached: teardown says what was written

    def use_output_dir(self, output_dir: str | Path) -> None:
        """Write under ``output_dir`` (``stamlane predict``'s choice when none was given)."""
        self.output_dir = Path(output_dir)

    @property
    def video_path(self) -> Path:
        return self.output_dir / VIDEO_NAME

    def on_predict_start(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        self.written = dict.fromkeys(self.written, 0)
        self._done = False
        self._json = None
        self._rows = []
        datamodule = getattr(trainer, "datamodule", None)  # set by Lightning's data connector, not declared
        self._data_root = Path(getattr(datamodule, "root", ".") or ".")
        is_video = bool(getattr(datamodule, "is_video", False))
        fps = getattr(datamodule, "video_fps", None) or FALLBACK_FPS
        self._video_fps = fps if is_video and trainer.world_size == 1 else None
        if self.owner is not None and trainer.is_global_zero:  # the folder holds this source's results from now on
            mark(self.output_dir, self.owner)

    def _json_writer(self) -> TusimpleWriter:
        if self._json is None:
            self._json = TusimpleWriter(self.output_dir / "predictions.json")
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
                line = (raw_file, lanes, h_samples, item["run_time"])
                if trainer.world_size == 1:
                    self._json_writer().write(*line)
                else:  # rank 0 writes every process's lines when prediction ends, in the split's order
                    key = meta.get("index", (len(self._rows), trainer.global_rank))
                    self._rows.append((key, line))
                self.written["tusimple"] += 1
            else:
                write_culane_lines(self.output_dir / "lines", raw_file, lanes)
                self.written["culane"] += 1
            picture = self.overlays and (self.max_overlays is None or self.written["overlays"] < self.max_overlays)
            frame = self.overlays and self.video and self._video_fps is not None
            if picture or frame:
                overlay = self._overlay(meta, lanes, gts[i] if gts is not None else None)
                if overlay is not None and picture:
                    self._write_picture(raw_file, overlay)
                if overlay is not None and frame:
                    self._write_frame(overlay)

    def _overlay(
        self, meta: dict[str, Any], lanes: list[np.ndarray], gt_lanes: list[np.ndarray] | None
    ) -> np.ndarray | None:
        """The key frame with its lanes and legend; None when the frame cannot be read."""
        key_path = self._data_root / meta["frame_paths"][-1] if meta.get("frame_paths") else None
        image = read_image(key_path) if key_path is not None else None  # a FIFO or a bomb: no overlay, no hang
        if image is None:
            return None
        # a folder or a video has no labels; a split's frame without h_samples and without lanes may have none
        labelled = (
            gt_lanes is not None
            and meta.get("format") != "frames"
            and (meta.get("h_samples") is not None or len(gt_lanes) > 0)
        )
        shown = gt_lanes if labelled else None
        picture = draw_lanes(image, lanes, shown)
        score = image_score(lanes, shown, meta.get("h_samples"), image.shape[:2]) if shown is not None else None
        return draw_legend(picture, model=self.model_name, score=score, ground_truth=labelled)

    def _write_picture(self, raw_file: str, overlay: np.ndarray) -> None:
        path = culane_lines_path(self.output_dir / "overlays", raw_file).with_suffix("")
        path = path.with_suffix(".jpg")  # <stem>.lines -> <stem>.jpg
        make_folder(path.parent)
        with atomic_path(output_path(self.output_dir, path)) as tmp:  # whole or not at all; a full disk said
            if not cv2.imwrite(str(tmp), overlay):
                raise OSError(f"cannot write the overlay {path} (a full disk?)")
        self.written["overlays"] += 1

    def _write_frame(self, overlay: np.ndarray) -> None:
        if self._video is None:
            assert self._video_fps is not None  # frames are written for a video only (on_predict_batch_end)
            make_folder(self.output_dir, "predictions.output_dir")
            tmp = output_path(self.output_dir, temporary_name(self.video_path))
            size = (overlay.shape[1], overlay.shape[0])  # OpenCV's (W, H)
            self._video = cv2.VideoWriter(str(tmp), cv2.VideoWriter.fourcc(*"mp4v"), self._video_fps, size)
            self._video_size = size
        if (overlay.shape[1], overlay.shape[0]) != self._video_size:  # a video's frames share one size
            overlay = cv2.resize(overlay, self._video_size, interpolation=cv2.INTER_AREA)
        self._video.write(overlay)
        self.written["video frames"] += 1

    def _close_video(self, keep: bool) -> None:
        if self._video is None:
            return
        self._video.release()
        self._video = None
        tmp = temporary_name(self.video_path)
        if keep and tmp.is_file():
            os.replace(tmp, output_path(self.output_dir, self.video_path))
        elif os.path.lexists(tmp):
            tmp.unlink()

    def on_exception(self, trainer: pl.Trainer, pl_module: pl.LightningModule, exception: BaseException) -> None:
        self._close_video(keep=False)  # a failed run leaves the previous overlay video whole

    def on_predict_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if trainer.world_size > 1:
            rows = gather_records(self._rows, "predictions")
            self._rows = []
            counts = trainer.strategy.all_gather(torch.tensor(list(self.written.values()), device=pl_module.device))
            self.written = dict(zip(self.written, counts.reshape(-1, len(self.written)).sum(0).tolist(), strict=True))
            if trainer.is_global_zero:
                for _, line in rows:
                    self._json_writer().write(*line)
        if self._json is not None:
            self._json.close()
            self._json = None
        self._close_video(keep=True)
        self._done = True

    def teardown(self, trainer: pl.Trainer, pl_module: pl.LightningModule, stage: str) -> None:
        """Say what was written, after the progress bar has closed its line (a failed run says nothing)."""
        if stage != "predict" or not self._done:
            return
        self._done = False
        if trainer.is_global_zero and self.verbose:
            parts = [f"{n} {k}" for k, n in self.written.items() if n and k != "video frames"]
            if self.written["video frames"]:
                parts.append(f"{self.video_path.name} ({self.written['video frames']} frames)")
            print(f"stamlane predict: wrote {', '.join(parts) or 'nothing'} under {self.output_dir}", flush=True)
