"""Evaluation frames decoded, aligned and resized once per process (`FrameStore`).

A run scores the same key frames many times: every split with every history probe, each model and seed of
``stamlane demo`` in one process (about 35 prediction passes per multi-frame model). Without augmentation a frame's
network input depends only on the file, its alignment to the key frame and the clip's geometry, so the store keeps
each one as the transform made it (RGB uint8 at the network size, `stamlane.data.transforms.ClipTransform.warp_frame`)
under ``(file identity, key_from_hist, net_from_orig, network size)``, and each clip's alignment under its frames'
identities and the aligner's settings; a later read is the same bytes, and the sample the same tensors bit for bit
(the float conversion is `stamlane.data.transforms.to_network` either way).

A frame's identity here is the digest of its file's bytes (`stamlane.align.identity.file_identity`, where the
identities of a frame are explained): a frame written again with other pixels is another frame for the store,
never an old picture. A clip's alignment is kept by its owner, the dataset's aligner
(`stamlane.data.alignment.ClipAligner.kept`), under the same identities. The store holds at most its budget
(least recently used first out); it lives in the process, so `ClipDataModule` fills it in the main process before
a test or prediction loader's workers start (`ClipDataset.materialise`): forked workers read it, and the next pass
finds it filled. Training samples are augmented afresh every time and never stored.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable
from typing import Any

import numpy as np

from stamlane.align.identity import file_identity
from stamlane.data.labels import DataError
from stamlane.data.transforms import to_network

__all__ = ["DEFAULT_MEMORY_MB", "FRAME_STORE", "FrameStore", "StoredSlots"]

DEFAULT_MEMORY_MB = 1024
"""The store's default budget (`stamlane.data.options.LoaderOptions.memory_mb`): the demo's scored splits at 80x256
with 4 frames (about 2,700 key frames, 650 MB of warped frames for the aligned model), as uint8."""


class FrameStore:
    """A bounded in-memory map, least recently used out first; safe to use from several threads.

    Args:
        budget_bytes: the most the values' ``nbytes`` may add up to (0: nothing is kept).
    """

    def __init__(self, budget_bytes: int = 0) -> None:
        self.budget = int(budget_bytes)
        self.used = 0
        self.hits = 0
        self.misses = 0
        self._items: OrderedDict[Hashable, Any] = OrderedDict()
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, key: Hashable) -> bool:
        return key in self._items

    def get(self, key: Hashable) -> Any | None:
        """The value of ``key`` (marked as just used), or None."""
        with self._lock:
            value = self._items.get(key)
            if value is None:
                self.misses += 1
                return None
            self._items.move_to_end(key)
            self.hits += 1
            return value

    def put(self, key: Hashable, value: Any) -> None:
        """Keep ``value`` (an array, or a tuple of arrays and plain values) under ``key``; the least recently used
        entries leave to make room; a value larger than the whole budget is not kept."""
        size = _nbytes(value)
        with self._lock:
            if size > self.budget:
                return
            old = self._items.pop(key, None)
            if old is not None:
                self.used -= _nbytes(old)
            self._items[key] = value
            self.used += size
            while self.used > self.budget and self._items:
                _, gone = self._items.popitem(last=False)
                self.used -= _nbytes(gone)

    def reserve(self, budget_bytes: int) -> None:
        """Let the store hold at least ``budget_bytes`` (a larger budget asked before stays)."""
        with self._lock:
            self.budget = max(self.budget, int(budget_bytes))

    def clear(self) -> None:
        """Empty the store (the budget stays)."""
        with self._lock:
            self._items.clear()
            self.used = 0


def _nbytes(value: Any) -> int:
    if isinstance(value, np.ndarray):
        return value.nbytes
    if isinstance(value, tuple):
        return sum(_nbytes(v) for v in value)
    return 64


FRAME_STORE = FrameStore()
"""The process's store (budget 0 until a `ClipDataModule` reserves its ``loader.memory_mb``)."""


class _StoredClip:
    """One clip's frames as the store knows them: identities now, pixels only when something is missing."""

    def __init__(self, dataset: Any, entry: Any) -> None:  # a ClipDataset and its ClipEntry
        self.dataset, self.entry = dataset, entry
        self.ids = tuple(file_identity(dataset.root / p) for p in entry.frame_paths)
        self._frames: list[np.ndarray] | None = None
        if None in self.ids:
            self.frames()  # a missing or unreadable frame: the dataset's own error
            raise DataError(f"{entry.label_file}: a frame of {entry.raw_file} changed while it was read")

    def frames(self) -> list[np.ndarray]:
        """The decoded frames (`ClipDataset.read_frames`: its checks and errors), read once."""
        if self._frames is None:
            self._frames = self.dataset.read_frames(self.entry)
        return self._frames

    def size(self) -> tuple[int, int]:
        """The frames' ``(H, W)``."""
        store, key = self.dataset.frame_store, ("size", self.ids)
        size: tuple[int, int] | None = store.get(key)
        if size is None:
            height, width = self.frames()[-1].shape[:2]
            size = (int(height), int(width))
            store.put(key, size)
        return size

    def alignment(self) -> np.ndarray:
        """``key_from_hist`` (T, 3, 3) as the dataset's aligner gives it, kept in the store by the aligner."""
        mats: np.ndarray = self.dataset.aligner.kept(
            self.dataset.frame_store, self.ids, self.entry.frame_paths, self.frames
        )
        return mats


class StoredSlots:
    """What fills the T slots of one evaluation sample (`ClipDataset.load` with `ClipDataset.stores_frames`), read
    from the dataset's ``frame_store`` where it holds them: the same as `ClipDataset._history` gives, for the
    history sources ``real``, ``key``, ``reversed`` and ``other_clip``.

    Args:
        dataset: a `stamlane.data.clips.ClipDataset` with a ``frame_store``.
        entry: the sample's `stamlane.data.clips.ClipEntry`.
        history_of: the entry whose history replaces the sample's own (``other_clip``), or None.

    Attributes:
        key_from_hist: (T, 3, 3) float64, each slot's frame -> key frame, original pixels.
        size: the original ``(H, W)``.
    """

    def __init__(self, dataset: Any, entry: Any, history_of: Any = None) -> None:
        self.dataset = dataset
        own = _StoredClip(dataset, entry)
        t = len(entry.frame_paths)
        eye = np.repeat(np.eye(3)[None], t, axis=0)
        source = dataset.history_source
        if source == "key":
            self.size = own.size()
            self.key_from_hist = eye
            self.slots = [(own, t - 1)] * t
            return
        mats = own.alignment()
        self.size = own.size()
        if source == "reversed":
            order = [*range(t - 2, -1, -1), t - 1]
            self.key_from_hist, self.slots = mats[order], [(own, i) for i in order]
        elif source == "other_clip" and history_of is not None and t > 1:
            other = _StoredClip(dataset, history_of)
            if other.size() != self.size:
                raise DataError(f"{history_of.label_file}: its frames are not the size of {entry.raw_file}'s")
            self.key_from_hist = np.concatenate([other.alignment()[:-1], mats[-1:]])
            self.slots = [*((other, i) for i in range(t - 1)), (own, t - 1)]
        else:
            self.key_from_hist, self.slots = np.array(mats), [(own, i) for i in range(t)]

    def network_frames(self, applied: np.ndarray, params: Any) -> np.ndarray:
        """The sample's frames as `ClipTransform.apply_frames` makes them, each warped frame read from the store
        or made and kept there.

        Args:
            applied: (T, 3, 3) the homography applied to each slot's frame (``key_from_hist``, or the identity for
                ``warp="feature"``).
            params: the clip's `stamlane.data.transforms.ClipParams` (no jitter: the store is for evaluation).

        Returns:
            float32 (T, 3, H, W) RGB in [0, 1].
        """
        transform, store = self.dataset.transform, self.dataset.frame_store
        net_h, net_w = transform.image_size
        out = np.empty((len(self.slots), 3, net_h, net_w), np.float32)
        geometry = (params.net_from_orig.tobytes(), transform.image_size)
        for t, (clip, i) in enumerate(self.slots):
            key = ("net", clip.ids[i], np.asarray(applied[t], dtype=np.float64).tobytes(), geometry)
            rgb = store.get(key)
            if rgb is None:
                rgb = transform.warp_frame(clip.frames()[i], applied[t], params)
                rgb.setflags(write=False)
                store.put(key, rgb)
            out[t] = to_network(rgb)
        return out
