"""``stamlane predict``: lanes of a dataset split, a folder of frames or a video file, written to disk.

`LanePredictionWriter` (a Lightning prediction-writer callback) writes, under ``output_dir``:

- ``predictions.json`` — TuSimple json-lines (one line per key frame with ``h_samples``), scored as is by
  ``stamlane-eval tusimple predictions.json <gt.json>``;
- ``lines/<raw_file stem>.lines.txt`` — CULane text, one per key frame without ``h_samples`` (CULane,
  ApolloScape, VIL-100, folders, videos), scored by ``stamlane-eval culane <output_dir>/lines <gt_dir>``;
- ``overlays/<raw_file stem>.jpg`` — the original key frame with the predicted lanes (and the annotated
  ones in white when the split has labels), at most ``max_overlays`` of them.

With several processes (DDP) every rank writes ``predictions.rank<r>.json``.

The data of ``stamlane predict --source FOLDER|VIDEO`` is ``stamlane.data.datamodule.FramesDataModule``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import lightning.pytorch as pl
import numpy as np
from lightning.pytorch.callbacks import BasePredictionWriter
from stamlane_eval.io import culane_lines_path

from stamlane.predict.overlay import draw_lanes
from stamlane.predict.writers import TusimpleWriter, output_path, write_culane_lines
from stamlane.safety.images import read_image

__all__ = ["LanePredictionWriter"]

_FORMATS = ("auto", "tusimple", "culane")


class LanePredictionWriter(BasePredictionWriter):
    """Write ``predict_step`` outputs as benchmark files and overlay pictures (see the module docstring).

    Args:
        output_dir: the output folder.
        format: ``"auto"`` (TuSimple json for frames with ``h_samples``, CULane text otherwise),
            ``"tusimple"`` (frames without ``h_samples`` are an error) or ``"culane"`` (always text).
        overlays: write overlay pictures.
        max_overlays: write at most this many overlays (``None``: all).
        verbose: print what was written when prediction ends (the experiment engine turns it off).
    """

    def __init__(
        self,
        output_dir: str = "outputs/predictions",
        format: str = "auto",
        overlays: bool = True,
        max_overlays: int | None = None,
        verbose: bool = True,
    ) -> None:
        super().__init__(write_interval="batch")
        self.verbose = verbose
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
        image = read_image(key_path) if key_path is not None else None  # a FIFO or a bomb: no overlay, no hang
        if image is None:
            return
        path = culane_lines_path(self.output_dir / "overlays", str(meta["raw_file"])).with_suffix("")
        path = path.with_suffix(".jpg")  # <stem>.lines -> <stem>.jpg
        path.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(output_path(self.output_dir, path)), draw_lanes(image, lanes, gt_lanes))
        self.written["overlays"] += 1

    def on_predict_end(self, trainer: pl.Trainer, pl_module: pl.LightningModule) -> None:
        if self._json is not None:
            self._json.close()
            self._json = None
        if trainer.is_global_zero and self.verbose:
            parts = [f"{n} {k}" for k, n in self.written.items() if n]
            print(f"stamlane predict: wrote {', '.join(parts) or 'nothing'} under {self.output_dir}")
