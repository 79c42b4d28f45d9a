"""Run the exported graphs (`stamlane.stream.export`) with onnxruntime on the CPU, numpy in and out."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["OnnxLaneNet"]


class OnnxLaneNet:
    """onnxruntime sessions of ``encoder.onnx``, ``fuse_decode.onnx`` and (if present) ``clip.onnx``.

    Args:
        model_dir: the folder `stamlane.stream.export.export_all` wrote.
        threads: intra-op threads of each session (0: onnxruntime's default, all cores).

    Raises:
        ImportError: when onnxruntime is not installed.
        FileNotFoundError: when ``encoder.onnx`` or ``fuse_decode.onnx`` is missing.
    """

    def __init__(self, model_dir: str | Path, threads: int = 0) -> None:
        import onnxruntime as ort  # optional dependency, imported on use

        folder = Path(model_dir)
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1

        def optional(name: str) -> ort.InferenceSession | None:
            path = folder / name
            if not path.is_file():
                return None
            return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])

        def required(name: str) -> ort.InferenceSession:
            found = optional(name)
            if found is None:
                raise FileNotFoundError(f"{folder / name} does not exist (export it with stamlane.stream.export)")
            return found

        self.encoder = required("encoder.onnx")
        self.fuse_decode_session = required("fuse_decode.onnx")
        self.clip_session = optional("clip.onnx")
        self.num_stages = len(self.encoder.get_outputs())
        self.takes_history = self.fuse_decode_session.get_inputs()[0].name == "history"

    def encode(self, frames: np.ndarray) -> list[np.ndarray]:
        """(N, 3, H, W) float32 in [0, 1] -> per-stage features, shallow first."""
        stages: list[np.ndarray] = self.encoder.run(None, {"frames": np.ascontiguousarray(frames, np.float32)})
        return stages

    def fuse_decode(
        self, key_stages: list[np.ndarray], history: np.ndarray | None = None, grid: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Warp ``history`` (B, T-1, C, h, w) with ``grid`` (B, T-1, h, w, 2), fuse with the key frame, decode.

        Returns:
            ``(logits (B, 2, H, W), embedding (B, E, H, W))``.
        """
        feeds = {f"key_stage{i}": np.ascontiguousarray(f, np.float32) for i, f in enumerate(key_stages)}
        if self.takes_history:
            if history is None or grid is None:
                raise ValueError("this fuse_decode graph fuses history frames: give history and grid")
            feeds["history"] = np.ascontiguousarray(history, np.float32)
            feeds["grid"] = np.ascontiguousarray(grid, np.float32)
        logits, embedding = self.fuse_decode_session.run(None, feeds)
        return logits, embedding

    def clip(self, clip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The whole clip model: (B, T, 3, H, W) pre-aligned -> ``(logits, embedding)``."""
        if self.clip_session is None:
            raise FileNotFoundError("clip.onnx was not exported into this folder")
        logits, embedding = self.clip_session.run(None, {"clip": np.ascontiguousarray(clip, np.float32)})
        return logits, embedding
