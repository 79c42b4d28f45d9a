"""`StreamingPredictor`: lanes of a video frame by frame, every frame encoded once.

The clip model (`stamlane.models.LaneNet.forward`) encodes all T frames of a clip; run on a video it
encodes each frame T times (once as key frame, T-1 times as history), after warping the history IMAGES
onto the key frame. The streaming predictor keeps the deepest-stage encoder features of the last T-1
frames, warps those FEATURE maps onto each new key frame with the same ground-plane homography
(`stamlane.models.feature_warp`) and runs only the fusion and the decoder again:

1. the new frame is resized to the network input (``stamlane.data.transforms.ClipTransform``, as in
   training) and encoded once; its deepest stage is cached, its shallower stages are the decoder's skips;
2. ``key_from_hist`` of every cached frame to the new frame is estimated in ORIGINAL pixels the way
   ``stamlane.align.align_clip`` recommends (``strategy="chain"``): the new frame is matched with the
   previous one only, and each cached frame's homography is the product of consecutive steps; a frame
   whose chain breaks (a failed or implausible step) is matched directly with the new frame instead, and
   failing that is used unaligned (identity), as the data pipeline does;
3. the cached features are warped (zeros where a history frame has no source), stacked with the key
   frame's, oldest first, key last, and fused and decoded (``LaneNet.fuse_and_decode``);
4. ``stamlane.predict.postprocess.decode_lanes`` turns the two heads into lanes in original pixels.

Warm-up: while fewer than T-1 frames have been seen, the earliest frame seen fills the missing history
slots (with its own alignment), exactly as ``stamlane predict`` builds clips at the start of a sequence
(``repeat_missing_history``); the very first frame is its own history.

Difference from the clip model with image pre-alignment: warping features instead of images changes the
result. Convolutions commute with translations by whole cells only; forward ego-motion is mostly a zoom about
the vanishing point, and the features of a zoomed image are not the zoomed (bilinearly interpolated 16-pixel
cells of the) features; borders with no source are zero features instead of the features of black pixels.
With identity alignment the two are the same computation. Weights trained on image-aligned clips lose some
accuracy when run this way; training or fine-tuning with feature-space alignment (``--data.clip.warp feature``,
`stamlane.models.forward_feature_aligned`) recovers it (``benchmarks/stream.py``).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import Tensor

from stamlane.align import AlignConfig, Alignment
from stamlane.align.homography import FramePrep, check_image, estimate_prepared, resolve_horizon_row
from stamlane.align.warp import chain_link
from stamlane.data.transforms import ClipTransform
from stamlane.models import LaneNet
from stamlane.models.feature_aligned import fuse_feature_aligned
from stamlane.predict.postprocess import PostprocessConfig, decode_lanes
from stamlane.safety.budget import check_stream_buffers
from stamlane.types import Lanes

if TYPE_CHECKING:
    from stamlane.training.stored import StoredModel

__all__ = ["READ_AHEAD", "StreamOutput", "StreamingPredictor", "fuse_feature_aligned"]


@dataclass
class StreamOutput:
    """What `StreamingPredictor` returns for one frame.

    Attributes:
        index: the frame's position in the stream, from 0.
        lanes: the frame's lanes, left to right, ``(N, 2)`` ``(x, y)`` in original pixels.
        logits: ``(1, 2, H, W)`` lane / background logits at network resolution (float32, CPU).
        embedding: ``(1, E, H, W)`` pixel embeddings at network resolution.
        alignments: the alignment of each history slot to this frame, oldest first (``T - 1`` entries,
            warm-up slots repeated), ``key_from_hist`` in ORIGINAL pixels; empty when alignment is off.
        net_from_orig: ``(3, 3)`` original -> network pixels.
        timings: milliseconds spent in ``preprocess`` (resize), ``align`` (homography estimation),
            ``network`` (encoder on the new frame, feature warp, fusion, decoder) and ``decode`` (post-processing).
    """

    index: int
    lanes: Lanes
    logits: Tensor
    embedding: Tensor
    alignments: list[Alignment] = field(default_factory=list)
    net_from_orig: np.ndarray = field(default_factory=lambda: np.eye(3))
    timings: dict[str, float] = field(default_factory=dict)


@dataclass
class _Cached:
    """One cached history frame: its deepest features and its alignment to the newest frame."""

    feats: Tensor  # (1, C, h, w)
    prep: FramePrep | None = None  # for direct matching when a chain breaks
    key_from_hist: np.ndarray = field(default_factory=lambda: np.eye(3))  # to the newest frame, original px
    alignment: Alignment = field(default_factory=lambda: Alignment(np.eye(3), 0, 0, True, ""))


@dataclass
class _Prepared:
    """A frame ready for the network (`StreamingPredictor._prepare`)."""

    size: tuple[int, int]  # (H0, W0)
    frame: Tensor  # (3, H, W) at the network size
    prep: FramePrep | None  # the alignment features, None without alignment
    timings: dict[str, float]


@dataclass
class _Fused:
    """A frame after the network, before its lanes are decoded (`StreamingPredictor._fused`)."""

    index: int
    size: tuple[int, int]
    logits: Tensor
    embedding: Tensor
    alignments: list[Alignment]
    net_from_orig: np.ndarray
    timings: dict[str, float]


READ_AHEAD = 2
"""Frames `StreamingPredictor.run` prepares ahead of the network."""


class StreamingPredictor:
    """Frame-by-frame lane detection that encodes each frame once (see the module docstring).

    Args:
        net: the trained network; put in eval mode here. Fusion runs on ``encoder.strides[-1]``.
        num_frames: T, frames the fusion sees (key frame included), as trained.
        image_size: network input ``(H, W)``, multiples of the deepest stride.
        align: estimate ``key_from_hist`` and warp the cached features (False: history unaligned).
        horizon_row: first ground row (ORIGINAL pixels) for the alignment; ``None`` = ``stamlane.align``'s
            default fraction of the frame height.
        align_config: settings of ``stamlane.align`` (``None``: defaults).
        postprocess: lane decoding options (``None``: defaults).
        y_samples: original rows to sample lanes at (e.g. TuSimple ``h_samples``); ``None``: every
            ``postprocess.y_step`` px.
        bf16: run the network under ``torch.autocast(bfloat16)`` (as a model trained with ``bf16: true``).
        crop_top: fraction of the frame height cut off at the top, as the model was trained (``ClipTransform``).

    Use ``predictor(image)`` per frame, in order; `reset` before a new video.
    """

    def __init__(
        self,
        net: LaneNet,
        num_frames: int,
        image_size: tuple[int, int],
        *,
        align: bool = True,
        horizon_row: int | None = None,
        align_config: AlignConfig | None = None,
        postprocess: PostprocessConfig | None = None,
        y_samples: Sequence[float] | None = None,
        bf16: bool = False,
        crop_top: float = 0.0,
    ) -> None:
        if not isinstance(num_frames, int) or isinstance(num_frames, bool) or num_frames < 1:
            raise ValueError(f"num_frames must be an int >= 1, got {num_frames!r}")
        strides = getattr(net.encoder, "strides", None)
        if not strides:
            raise ValueError(f"net.encoder must have a strides attribute, got {type(net.encoder).__name__}")
        self.stride = int(strides[-1])
        if len(image_size) != 2 or any(int(s) < self.stride or int(s) % self.stride for s in image_size):
            raise ValueError(f"image_size must be (H, W), positive multiples of {self.stride}, got {image_size!r}")
        self.num_frames = num_frames
        self.image_size = (int(image_size[0]), int(image_size[1]))
        check_stream_buffers(  # before a buffer is made: a checkpoint's recorded image_size is a stranger's
            num_frames,
            self.image_size,
            list(getattr(net.encoder, "out_channels", [])),
            list(strides),
            int(getattr(net.decoder, "embed_dim", 4)),
            "the streaming predictor",
        )
        self.net = net.eval()
        self.align = align
        self.horizon_row = horizon_row
        self.align_config = align_config or AlignConfig()
        self.postprocess = postprocess or PostprocessConfig()
        self.y_samples = None if y_samples is None else list(y_samples)
        self.bf16 = bf16
        self.transform = ClipTransform(self.image_size, crop_top=crop_top)
        self.reset()

    @classmethod
    def from_stored(cls, model: StoredModel, **overrides: Any) -> StreamingPredictor:
        """A predictor for a stored model (`stamlane.training.stored.StoredModel`), with every setting it was trained
        with (`ModelSettings`): T, the input size, the crop, the alignment (on or off, its ORB preset, the horizon
        row), the decoding and bfloat16. The one way a stored model becomes a predictor (``stamlane stream``, the
        benchmarks, the README's example).

        Args:
            model: the opened model; its network runs where its parameters are (move ``model.module`` first).
            overrides: keyword arguments of the constructor that replace the stored settings (``align=False``,
                ``align_config=ALIGN_PRESETS["fast"]``, ``horizon_row=300``, ``y_samples=...``, ``bf16=False``).
        """
        from stamlane.align.homography import align_preset

        settings = model.settings
        options: dict[str, Any] = {
            "num_frames": settings.num_frames,
            "image_size": settings.image_size,
            "align": settings.aligns,
            "horizon_row": settings.horizon_row,
            "align_config": align_preset(settings.align_preset),
            "postprocess": settings.postprocess,
            "bf16": settings.bf16,
            "crop_top": settings.crop_top,
        }
        options.update(overrides)
        num_frames, image_size = int(options.pop("num_frames")), tuple(options.pop("image_size"))
        return cls(model.module.net, num_frames, image_size, **options)

    @classmethod
    def from_module(cls, module: Any, **kwargs: Any) -> StreamingPredictor:
        """A predictor for a ``StamLaneModule`` in memory (one just trained, say): its net, ``num_frames``,
        ``image_size``, ``crop_top``, decoding, bf16. A module knows nothing of the data options it was trained with
        (alignment preset, horizon row, ``align: none``): for a STORED model use `from_stored`, which has them.

        Keyword arguments override (e.g. ``num_frames``, ``image_size`` when the module lacks them).
        """
        hparams = getattr(module, "hparams", {})
        options: dict[str, Any] = {
            "num_frames": getattr(module, "num_frames", None),
            "image_size": hparams.get("image_size"),
            "postprocess": getattr(module, "postprocess", None),
            "bf16": bool(getattr(module, "bf16", False)),
            "crop_top": float(getattr(module, "crop_top", 0.0)),
        }
        options.update(kwargs)
        missing = [k for k in ("num_frames", "image_size") if options.get(k) is None]
        if missing:
            raise ValueError(f"the module does not record {', '.join(missing)}; pass them explicitly")
        num_frames, image_size = int(options.pop("num_frames")), tuple(options.pop("image_size"))
        return cls(module.net, num_frames, image_size, **options)

    def reset(self) -> None:
        """Forget the history (start of a new video)."""
        self._cache: deque[_Cached] = deque(maxlen=max(self.num_frames - 1, 1))
        self._index = 0
        self._shape: tuple[int, int] | None = None
        self._net_from_orig = np.eye(3)

    @property
    def history_size(self) -> int:
        """Frames currently cached as history (at most ``num_frames - 1``)."""
        return len(self._cache) if self.num_frames > 1 else 0

    @property
    def device(self) -> torch.device:
        """Where the network runs (its parameters' device); frames are moved there, outputs come back to the CPU."""
        return next(self.net.parameters()).device

    def _autocast(self) -> Any:
        return torch.autocast(self.device.type, dtype=torch.bfloat16) if self.bf16 else nullcontext()

    @torch.inference_mode()
    def step(
        self, frame: Tensor, key_from_hist: np.ndarray | None = None, net_from_orig: np.ndarray | None = None
    ) -> tuple[Tensor, Tensor]:
        """Tensor core: encode one network-sized frame, fuse it with the cached history, cache it.

        Args:
            frame: ``(3, H, W)`` or ``(1, 3, H, W)`` float RGB in [0, 1] at the network size.
            key_from_hist: ``(history_size, 3, 3)``: each CACHED frame (oldest first) -> this frame, in network
                pixels (original pixels with ``net_from_orig``); ``None`` = identity (no alignment).
            net_from_orig: ``(3, 3)`` original -> network pixels when ``key_from_hist`` is in original pixels.

        Returns:
            ``(logits (1, 2, H, W), embedding (1, E, H, W))``, float32.
        """
        if frame.ndim == 3:
            frame = frame[None]
        frame = frame.to(self.device)
        if frame.ndim != 4 or frame.shape[0] != 1 or tuple(frame.shape[-2:]) != self.image_size:
            raise ValueError(
                f"expected a frame of shape (3, {self.image_size[0]}, {self.image_size[1]}), got {tuple(frame.shape)}"
            )
        cached = list(self._cache) if self.num_frames > 1 else []
        if key_from_hist is not None:
            key_from_hist = np.asarray(key_from_hist, dtype=np.float64)
            if key_from_hist.shape != (len(cached), 3, 3):
                raise ValueError(
                    f"expected key_from_hist of shape ({len(cached)}, 3, 3) for the cached frames, "
                    f"got {key_from_hist.shape}"
                )
        with self._autocast():
            feats = self.net.encode(frame)
            key_last = feats[-1]
            num_hist = self.num_frames - 1
            if num_hist == 0:
                hist, mats = key_last[:, None][:, :0], None
            elif not cached:  # the very first frame is its own history
                hist, mats = key_last[:, None].expand(-1, num_hist, -1, -1, -1), None
            else:
                pad = num_hist - len(cached)  # warm-up: repeat the earliest cached frame
                slots = [0] * pad + list(range(len(cached)))
                hist = torch.stack([cached[i].feats[0] for i in slots])[None]
                mats = None if key_from_hist is None else key_from_hist[slots][None]
            logits, embedding = fuse_feature_aligned(self.net, feats, hist, mats, self.stride, net_from_orig)
        if num_hist:
            self._cache.append(_Cached(key_last.detach()))
        return logits.float(), embedding.float()

    def __call__(self, image: np.ndarray) -> StreamOutput:
        """Lanes of the next frame of the stream.

        Args:
            image: the frame, ``(H0, W0, 3)`` uint8 BGR in original size; every frame of a stream the same size.

        Returns:
            the frame's `StreamOutput`.

        Raises:
            ValueError: on a non-uint8 / wrongly shaped image or a size change within the stream.
        """
        return self._decoded(self._fused(self._prepare(image)))

    def run(self, images: Iterable[np.ndarray]) -> Iterator[StreamOutput]:
        """Lanes of every frame of ``images``, in order: the same outputs as ``predictor(image)`` frame after frame,
        with the work that does not wait for the network done beside it (threads: CPU decoding, resizing and ORB
        features of frame t+1, and the lane decoding of frame t, run while the network runs on frame t; OpenCV,
        numpy and torch release the interpreter lock).

        Args:
            images: the frames in order (each as `__call__` takes it), read (a video decoded) and prepared ahead
                by one thread, up to `READ_AHEAD` frames.

        Yields:
            each frame's `StreamOutput` (``timings`` measure each stage where it ran).
        """
        source = iter(images)

        def read() -> _Prepared | None:  # in the reader thread, in order: a video's frames are decoded there too
            image = next(source, None)
            return None if image is None else self._prepare(image)

        with ThreadPoolExecutor(1) as reader, ThreadPoolExecutor(1) as decoder:
            ahead = deque(reader.submit(read) for _ in range(READ_AHEAD))
            pending: Future[StreamOutput] | None = None
            while ahead:
                prepared = ahead.popleft().result()
                if prepared is None:  # the end: the reads still in flight find it too
                    break
                ahead.append(reader.submit(read))
                fused = self._fused(prepared)
                if pending is not None:
                    yield pending.result()
                pending = decoder.submit(self._decoded, fused)
            if pending is not None:
                yield pending.result()

    def _prepare(self, image: np.ndarray) -> _Prepared:
        """What a frame needs before the network, none of it depending on the frames before: checks, the resize
        and the alignment features (``FramePrep``)."""
        check_image(image, "image")
        if image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"image must be (H, W, 3) uint8 BGR, got shape {image.shape}")
        if self._shape is None:
            self._shape = image.shape[:2]
            self._params = self.transform.draw(image.shape[:2])
            self._net_from_orig = self._params.net_from_orig
            self._row = resolve_horizon_row(self.horizon_row, image.shape[0]) if self.align else 0
        elif image.shape[:2] != self._shape:
            raise ValueError(
                f"frame size changed within the stream: {self._shape} then {image.shape[:2]}; call reset()"
            )
        timings: dict[str, float] = {}
        start = time.perf_counter()
        frame = torch.from_numpy(self.transform.apply_frames([image], np.eye(3)[None], self._params)[0])
        timings["preprocess"] = _ms(start)
        start = time.perf_counter()
        prep = FramePrep(image, self._row, self.align_config) if self.align and self.num_frames > 1 else None
        timings["align"] = _ms(start)
        return _Prepared(image.shape[:2], frame, prep, timings)

    def _fused(self, prepared: _Prepared) -> _Fused:
        """The frame's alignment to the cached history (in stream order) and the network."""
        timings = dict(prepared.timings)
        start = time.perf_counter()
        prep, mats, alignments = prepared.prep, None, []
        if prep is not None:
            self._align_cached(prep)
            if self._cache:
                mats = np.stack([c.key_from_hist for c in self._cache])
                pad = self.num_frames - 1 - len(self._cache)
                alignments = [self._cache[0].alignment] * pad + [c.alignment for c in self._cache]
            else:
                alignments = [Alignment(np.eye(3), 0, 0, True, "")] * (self.num_frames - 1)
        timings["align"] += _ms(start)

        start = time.perf_counter()
        logits, embedding = self.step(prepared.frame, mats, self._net_from_orig if mats is not None else None)
        logits, embedding = logits.cpu(), embedding.cpu()  # waits for an accelerator: its time counts here
        timings["network"] = _ms(start)
        if prep is not None:
            self._cache[-1].prep = prep
        fused = _Fused(self._index, prepared.size, logits, embedding, alignments, self._net_from_orig.copy(), timings)
        self._index += 1
        return fused

    @torch.inference_mode()
    def _decoded(self, fused: _Fused) -> StreamOutput:
        """The frame's lanes from its network outputs (`stamlane.predict.postprocess.decode_lanes`)."""
        start = time.perf_counter()
        prob = fused.logits.softmax(dim=1)[0, 1].numpy()
        lanes = decode_lanes(
            prob,
            fused.embedding[0].numpy(),
            np.linalg.inv(fused.net_from_orig),
            self.postprocess,
            y_samples=self.y_samples,
            orig_size=fused.size,
        )
        timings = {**fused.timings, "decode": _ms(start)}
        return StreamOutput(
            fused.index, lanes, fused.logits, fused.embedding, fused.alignments, fused.net_from_orig, timings
        )

    def _align_cached(self, prep: FramePrep) -> None:
        """Update every cached frame's ``key_from_hist`` to the new frame (chain, direct when the chain breaks)."""
        if not self._cache or self._shape is None:
            return
        cfg, shape, row = self.align_config, self._shape, self._row
        assert shape is not None  # set by _prepare with the stream's first frame, before any frame is cached

        def estimate(entry: _Cached) -> Alignment:
            if entry.prep is None:  # cached by `step` without its image
                return Alignment.failed("no image kept for this history frame (it was given to step())")
            return estimate_prepared(entry.prep, prep, cfg)

        step = estimate(self._cache[-1])
        for i, entry in enumerate(self._cache):
            if i == len(self._cache) - 1:
                entry.alignment, entry.key_from_hist = step, np.asarray(step.key_from_hist, np.float64)
                continue
            alignment = None
            if step.ok and entry.alignment.ok:
                alignment = chain_link(step, entry.alignment, shape, row, cfg, counts=step)
            if alignment is None or not alignment.ok:  # the chain broke: match this frame with the new one directly
                alignment = estimate(entry)
            entry.alignment = alignment
            entry.key_from_hist = np.asarray(alignment.key_from_hist, np.float64)


def _ms(start: float) -> float:
    return (time.perf_counter() - start) * 1000.0
