"""Where a dataset gets each history frame's ``key_from_hist`` (original pixels) from.

Modes:
    ``"none"``  identity for every frame (fusion without alignment).
    ``"fly"``   estimated now by ``stamlane.align.align_clip`` (the paper's pre-alignment) with
                ``strategy`` ``"chain"`` (default: consecutive frames matched and multiplied) or
                ``"direct"`` (each history frame against the key frame). On the synthetic clips (20 fps)
                the chain aligns 100 % of the history frames 1-3 back at stride 1, direct matching 55 % of
                those 3 back (``benchmarks/synth_align.py``, README). Each frame pair is estimated once
                for good: kept by content in the user's cache folder (``alignment/`` of
                `stamlane.align.user_cache`, ``~/.cache/stamlane`` by default, never inside the data;
                `stamlane.align.cache.PairCache`, keyed by both frames' pixel digests and the settings) and read by
                every later dataset, training run, prediction pass, probe, model and seed on the same frames,
                wherever they lie, in this process or another; a clip
                is memoised inside the dataset object too (alignment happens before augmentation, so it does not
                change per epoch). ``pair_cache=False``: estimated afresh by every dataset, as before the cache.
    ``"cache"`` read from ``stamlane align``'s cache (``stamlane.align.cache.load_alignment``); a frame
                pair missing from the cache is estimated on the fly (with one warning per dataset).
    ``"true"``  the synthetic generator's exact homographies (``<root>/homographies/<clip>.json``): an
                oracle for experiments, only for synthetic sets.
A failed estimate is the identity (``ok`` False), as ``stamlane.align`` returns it; the dataset never
crashes on it.

Every cache of alignments a dataset reads has one owner, the dataset's `ClipAligner`, and keys a frame by one of the
identities of `stamlane.align.identity` (which says why there are two):
    ``stamlane align``'s files  per clip folder, by frame name (``"cache"``; `stamlane.align.cache.load_alignment`).
    the pair cache              on disk, shared by every process, by both frames' pixel digests and the settings
                                (``"fly"`` and the pairs ``"cache"`` lacks; `stamlane.align.cache.PairCache`).
    the memo                    the aligner's clips by their paths and pairs by their keys (`ClipAligner.forget`).
    the frame store             the process's, a clip's alignment by its files' identities and the aligner's
                                `ClipAligner.settings` (`ClipAligner.kept`; `stamlane.data.frame_store`).

Where the alignment is applied is a separate choice (``WARP_MODES``, the datasets' ``warp`` option):
    ``"image"``   history IMAGES are warped onto the key frame before the network (the paper's pre-alignment).
    ``"feature"`` the frames stay unwarped and the homographies go with the sample in network pixels
                  (``key_from_hist_net``); the model warps the history FEATURES (as the streaming predictor).
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, Any

import numpy as np

from stamlane.data.labels import DataError

if TYPE_CHECKING:
    from stamlane.align.homography import Alignment
    from stamlane.align.warp import Strategy
    from stamlane.data.frame_store import FrameStore

__all__ = ["ALIGN_MODES", "ALIGN_STRATEGIES", "WARP_MODES", "ClipAligner"]

ALIGN_MODES = ("none", "fly", "cache", "true")

ALIGN_STRATEGIES: tuple[Strategy, ...] = ("chain", "direct")
"""How ``"fly"`` matches a clip: consecutive frames, the homographies multiplied, or each history frame directly
against the key frame."""

WARP_MODES = ("image", "feature")


class ClipAligner:
    """Compute ``key_from_hist`` (T, 3, 3) for a clip in one of ``ALIGN_MODES``.

    Args:
        mode: one of ``ALIGN_MODES``.
        root: data root.
        cache_dir: the alignment cache (mode ``"cache"``).
        horizon_row: first ground row for on-the-fly estimation (None: ``stamlane.align``'s default).
        strategy: ``"chain"`` or ``"direct"``, for on-the-fly estimation.
        preset: the `stamlane.align.homography.ALIGN_PRESETS` settings of on-the-fly estimation (``"standard"``
            or ``"fast"``); part of every frame pair's cache key.
        pair_cache: keep and read the on-the-fly frame-pair estimates in the user's cache folder (see the module
            docstring); False: this object's memo only.
    """

    MEMO_PAIRS = 50_000
    """Frame pairs this object keeps in memory (about 35 MB; a demo training run uses about 3,000) before it starts
    afresh (the disk cache stays)."""

    def __init__(
        self,
        mode: str,
        root: Path,
        cache_dir: str | Path | None = None,
        horizon_row: int | None = None,
        strategy: str = "chain",
        pair_cache: bool = True,
        preset: str = "standard",
    ) -> None:
        from stamlane.align.homography import align_preset

        if mode not in ALIGN_MODES:
            raise ValueError(f"align must be one of {ALIGN_MODES}, got {mode!r}")
        if mode == "cache" and cache_dir is None:
            raise ValueError("align='cache' needs cache_dir (the folder written by `stamlane align`)")
        if strategy not in ALIGN_STRATEGIES:
            raise ValueError(f"align strategy must be one of {ALIGN_STRATEGIES}, got {strategy!r}")
        self.mode = mode
        self.strategy = strategy
        self.preset = preset
        self.config = align_preset(preset)
        self.root = Path(root)
        self.cache_dir = Path(cache_dir) if cache_dir is not None else None
        self.horizon_row = horizon_row
        self._memo: dict[tuple[str, ...], tuple[np.ndarray, list[bool]]] = {}
        self._pairs: dict[str, Alignment] = {}  # pair key -> its alignment
        self.pair_cache = None
        if pair_cache and mode in ("fly", "cache"):
            from stamlane.align.cache import PairCache  # imported only when used

            self.pair_cache = PairCache(inputs=(self.root,))  # never a cache inside the data
        self._true: dict[str, dict[str, Any]] = {}
        self._warned_cache_miss = False
        self.failures = 0

    @property
    def reads_pixels(self) -> bool:
        """Whether the alignment is estimated from the frames' pixels (``"fly"``, ``"cache"``); the other modes need
        only the paths (``frames`` may then be None)."""
        return self.mode in ("fly", "cache")

    def __call__(self, frame_paths: list[str], frames: list[np.ndarray] | None) -> tuple[np.ndarray, list[bool]]:
        """Alignment of every frame to the last one.

        Args:
            frame_paths: the frames' paths relative to the root, oldest first, key last.
            frames: the BGR uint8 images (H, W, 3) in original size, same order (None where not `reads_pixels`).

        Returns:
            ``key_from_hist`` float64 (T, 3, 3) in original pixels (identity for the key frame) and
            ``ok`` per frame (True for the key frame and for ``"none"``).
        """
        t = len(frame_paths)
        if frames is None and self.reads_pixels and t > 1:
            raise ValueError(f"align {self.mode!r} estimates from the frames' pixels: frames must be given")
        eye = np.repeat(np.eye(3)[None], t, axis=0)
        if self.mode == "none" or t == 1:
            return eye, [True] * t
        key = tuple(frame_paths)
        if key in self._memo:
            return self._memo[key]
        if self.mode == "true":
            result = self._true_alignment(frame_paths)
        else:
            mats, oks = eye.copy(), [True] * t
            cached = [self._cached(frame_paths[-1], p) for p in frame_paths[:-1]] if self.mode == "cache" else []
            found: list[Alignment] = [al for al in cached if al is not None]
            if self.mode == "fly" or len(found) < len(cached):
                if frames is None:  # reads_pixels: refused above
                    raise ValueError(f"align {self.mode!r} estimates from the frames' pixels: frames must be given")
                estimated = self._estimate(frames)
                found = [c if c is not None else e for c, e in zip(cached, estimated)] if cached else estimated
            for i, al in enumerate(found):
                mats[i], oks[i] = np.asarray(al.key_from_hist, dtype=np.float64), bool(al.ok)
                self.failures += int(not al.ok)
            result = (mats, oks)
        self._memo[key] = result
        return result

    def forget(self) -> None:
        """Drop what this object keeps in memory (clips and frame pairs); the disk cache stays."""
        self._memo.clear()
        self._pairs.clear()

    @property
    def settings(self) -> tuple[object, ...]:
        """Everything a clip's alignment depends on besides its frames: what keys it outside this object (`kept`)."""
        return (
            self.mode,
            self.strategy,
            self.preset,
            self.horizon_row,
            self.root,
            self.cache_dir,
            self.pair_cache is not None,
        )

    def kept(
        self,
        store: FrameStore,
        identities: tuple[str | None, ...],
        frame_paths: list[str],
        frames: Callable[[], list[np.ndarray]],
    ) -> np.ndarray:
        """``key_from_hist`` (T, 3, 3) of a clip, as ``self(frame_paths, frames())[0]`` gives it, kept in ``store``
        (the process's frame store, `stamlane.data.frame_store`) under the frames' file identities
        (`stamlane.align.identity.file_identity`) and `settings`: a later dataset of the same settings on the same
        files reads it without decoding a frame (``frames`` is called only when the store lacks it).

        Returns:
            a read-only array (shared with the store).
        """
        if not self.reads_pixels:
            unread = self(frame_paths, None)[0]
            return unread
        key = ("align", self.settings, identities)
        mats: np.ndarray | None = store.get(key)
        if mats is None:
            mats = self(frame_paths, frames())[0].copy()
            mats.setflags(write=False)
            store.put(key, mats)
        return mats

    def _estimate(self, frames: list[np.ndarray]) -> list[Alignment]:  # T - 1
        from stamlane.align.cache import estimate_clip_cached  # imported only when used

        if len(self._pairs) > self.MEMO_PAIRS:
            self._pairs.clear()
        return estimate_clip_cached(
            frames,
            self.pair_cache,
            self._pairs,
            horizon_row=self.horizon_row,
            config=self.config,
            strategy=self.strategy,
        )[:-1]  # no warping

    def _cached(self, key_path: str, hist_path: str) -> Alignment | None:
        from stamlane.align.cache import load_alignment  # imported only when used

        assert self.cache_dir is not None  # mode "cache", which needs it
        al = load_alignment(self.cache_dir, self.root, key_path, hist_path)
        if al is None and not self._warned_cache_miss:
            self._warned_cache_miss = True
            warnings.warn(
                f"alignment cache {self.cache_dir} has no entry for {hist_path} -> {key_path}; "
                "estimating missing pairs on the fly (warned once)",
                stacklevel=3,
            )
        return al

    def _true_alignment(self, frame_paths: list[str]) -> tuple[np.ndarray, list[bool]]:
        folder = PurePosixPath(frame_paths[-1]).parent
        parts = folder.parts[1:] if folder.parts and folder.parts[0] == "clips" else folder.parts
        path = self.root / "homographies" / (str(PurePosixPath(*parts)) + ".json")
        if str(path) not in self._true:
            try:
                self._true[str(path)] = json.loads(path.read_text())
            except (OSError, json.JSONDecodeError) as err:
                raise DataError(
                    f"align='true' needs the synthetic generator's homographies; cannot read {path}: {err}"
                ) from err
        geo = self._true[str(path)]
        names = geo["frames"]
        hom = [np.asarray(h, dtype=np.float64) for h in geo["image_from_ground"]]
        try:
            idx = [names.index(PurePosixPath(p).name) for p in frame_paths]
        except ValueError as err:
            raise DataError(f"{path}: frame of {frame_paths} not listed ({err})") from err
        key = hom[idx[-1]]
        mats = np.stack([key @ np.linalg.inv(hom[i]) for i in idx])
        mats /= mats[:, 2:3, 2:3]
        return mats, [True] * len(idx)
