"""The clip dataset every layout shares (docs/method.md §6); the TuSimple, ApolloScape, CULane and VIL-100 layouts
are `stamlane.data.layouts`.

Every dataset indexes its label/list files once, finds each key frame's history frames (by frame
number, or by order within the folder), and returns samples as ``stamlane.types`` describes:
``frames`` (T, 3, H, W) float32 RGB in [0, 1] key last (history pre-aligned when asked),
``binary``/``instance`` (H, W) int64 at the network size, ``key_from_hist`` (T, 3, 3) float32 in
ORIGINAL pixels, ``lanes`` (key frame, original pixels, sorted left to right) and ``meta``.

With ``warp="feature"`` the history frames are NOT warped (every frame gets the key frame's crop, scale and
flip) and the sample also carries ``key_from_hist_net``: float32 (T, 3, 3), history -> key frame in NETWORK
pixels (``net_from_orig @ key_from_hist @ inv(net_from_orig)``, identity for the key frame), which the model
applies to the history FEATURES (`stamlane.models.forward_feature_aligned`).

Bad data (missing or unreadable frame, a path outside the root, malformed labels, mismatched lane
lengths) raises ``DataError`` naming the file with ``on_error="raise"``; with ``on_error="skip"`` the
entry is dropped at indexing time (or replaced by the next good sample when an image turns out
unreadable at load time) with a warning. A sample is never silently wrong.
"""

from __future__ import annotations

import hashlib
import re
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

import cv2
import numpy as np
import torch
from torch.utils.data import Dataset

from stamlane.data.alignment import ClipAligner
from stamlane.data.corruption import KeyFrameCorruption
from stamlane.data.frame_store import FrameStore, StoredSlots
from stamlane.data.labels import (
    DataError,
    history_name,
    resolve_inside,
)
from stamlane.data.options import ClipOptions, checked_strides
from stamlane.data.probes import HISTORIES
from stamlane.data.targets import draw_lane_targets, left_to_right
from stamlane.data.transforms import ClipTransform, net_homographies
from stamlane.safety.images import read_image
from stamlane.types import NET_HOMOGRAPHIES

__all__ = [
    "FRAME_LOOKUPS",
    "IMAGE_SUFFIXES",
    "NET_HOMOGRAPHIES",
    "ClipDataset",
    "ClipEntry",
    "frame_order",
    "mixed_stride",
    "warped_key",
]

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp")


def frame_order(name: str) -> tuple[str | int, ...]:
    """Sort key of frame file names: runs of digits compare as numbers, so ``2.jpg`` comes before ``10.jpg``
    (TuSimple numbers a clip's frames ``1.jpg`` .. ``20.jpg``; plain ``sorted`` would put ``10.jpg`` second).

    ``re.split`` with a capturing group puts text at even and digits at odd positions, so two keys never
    compare a string with a number.
    """
    return tuple(int(part) if i % 2 else part for i, part in enumerate(re.split(r"(\d+)", name)))


@dataclass
class ClipEntry:
    """One indexed sample: key frame name, frame paths (relative to the root, oldest first), labels."""

    raw_file: str
    frame_paths: list[str]
    lanes: list[np.ndarray]
    h_samples: list[int] | None
    label_file: str


FRAME_LOOKUPS = ("number", "sorted")
"""How a dataset finds a key frame's history frames: by frame number in the same folder (``19.jpg`` before
``20.jpg``), or by position in the folder's sorted listing (timestamps: ApolloScape, a folder of frames)."""


def mixed_stride(key_rel: str, strides: tuple[int, ...]) -> int:
    """The stride of a training key frame under a spacing mix (`AugmentOptions.strides`): one of ``strides`` chosen
    by a BLAKE2 digest of its path relative to the root, so the same in every epoch, loader worker and process
    (Python's ``hash`` of a string differs between processes; a CRC, linear in the bits, gives every clip one of
    two patterns over its frame numbers)."""
    digest = hashlib.blake2b(key_rel.encode(), digest_size=8).digest()
    return strides[int.from_bytes(digest, "little") % len(strides)]


class ClipDataset(Dataset[dict[str, Any]]):
    """Shared machinery of the clip datasets; subclasses implement ``_index``.

    Args:
        root: data root; every path in label and list files is relative to it.
        clip: how a clip is read (`stamlane.data.options.ClipOptions`: frames, stride, size, sky cut, alignment),
            declared, defaulted and checked there alone.
        transform: resize/augmentation; default: ``clip.transform()`` (the sky cut and the resize to the clip's
            ``image_size``, no augmentation).
        thickness: lane line width of the targets, network pixels.
        on_error: ``"raise"`` or ``"skip"`` (warn and drop) on bad data.
        frame_lookup: how history frames are found (`FRAME_LOOKUPS`): ``"number"`` (previous frame numbers in the
            same folder) or ``"sorted"`` (previous images in the folder's sorted listing); None: the layout's own
            (the class attribute ``frame_lookup``). ``clip.stride`` counts in frame numbers or in positions.
        require_labels: when False, a missing label file gives an unlabelled sample (prediction).
        history_source: what fills the history slots (`stamlane.data.probes.HISTORIES`), to measure whether a model reads its
            history: ``"real"`` (default) the clip's own frames; ``"key"`` copies of the key frame (no temporal
            information; alignment the identity); ``"warped_key"`` the key frame warped out through the inverse
            of each history frame's ``key_from_hist`` and then aligned as a real history frame is (the matched
            null: the same blur, black wedges and misplacement as real history, no new content; with
            ``align="none"`` the same as ``"key"``); ``"reversed"`` the clip's own history frames in reverse
            order, each with its own alignment (time reversed, content the same); ``"other_clip"`` the history
            frames of another clip of the split (`partner`), pre-aligned to that clip's own key frame (wrong
            history). Evaluation only.
        key_corruption: corrupts the key frame alone of some samples, history intact
            (`stamlane.data.corruption.KeyFrameCorruption`); training only.
        strides: a spacing mix (`AugmentOptions.strides`): each key frame read at one of these strides
            (`mixed_stride`) instead of ``clip.stride``; empty: ``clip.stride``. Training only.
    """

    format = ""
    frame_lookup = "number"
    """How this layout finds history frames (`FRAME_LOOKUPS`) unless the constructor is told otherwise."""

    def __init__(
        self,
        root: str | Path,
        *,
        clip: ClipOptions = ClipOptions(),
        transform: ClipTransform | None = None,
        thickness: int = 3,
        on_error: str = "raise",
        frame_lookup: str | None = None,
        require_labels: bool = True,
        history_source: str = "real",
        key_corruption: KeyFrameCorruption | None = None,
        strides: tuple[int, ...] = (),
    ) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise DataError(f"data root {self.root} is not a folder")
        if not isinstance(clip, ClipOptions):
            raise TypeError(f"clip must be a ClipOptions, got {type(clip).__name__}")
        if on_error not in ("raise", "skip"):
            raise ValueError(f"on_error must be 'raise' or 'skip', got {on_error!r}")
        frame_lookup = self.frame_lookup if frame_lookup is None else frame_lookup
        if frame_lookup not in FRAME_LOOKUPS:
            raise ValueError(f"frame_lookup must be one of {FRAME_LOOKUPS}, got {frame_lookup!r}")
        if thickness < 1:
            raise ValueError(f"thickness must be >= 1, got {thickness}")
        if history_source not in HISTORIES:
            raise ValueError(f"history_source must be one of {HISTORIES}, got {history_source!r}")
        self.clip = clip
        self.history_source = history_source
        self.key_corruption = key_corruption
        self.strides = checked_strides(strides)
        self.transform = transform or clip.transform()
        if self.transform.image_size != clip.image_size:
            raise ValueError(f"transform.image_size {self.transform.image_size} != image_size {clip.image_size}")
        self.thickness = thickness
        self.on_error = on_error
        self.frame_lookup = frame_lookup
        self.require_labels = require_labels
        self.aligner = ClipAligner(
            clip.align, self.root, clip.cache_dir, clip.horizon_row, clip.align_strategy, preset=clip.align_preset
        )
        self.frame_store: FrameStore | None = None
        """Where evaluation samples' frames are kept decoded and resized (`stamlane.data.frame_store`); None: none."""
        self._listing: dict[Path, list[str]] = {}
        self.skipped: list[str] = []
        self.entries: list[ClipEntry] = []
        for item in self._index():
            if isinstance(item, DataError):
                self._bad(item)
                continue
            try:
                self._check_frames(item)
            except DataError as err:
                self._bad(err)
                continue
            self.entries.append(item)

    @property
    def num_frames(self) -> int:
        """Frames per clip T (``clip.num_frames``), key frame last."""
        return self.clip.num_frames

    @property
    def image_size(self) -> tuple[int, int]:
        """The network input ``(H, W)`` (``clip.image_size``)."""
        return self.clip.image_size

    # --- subclass interface ---------------------------------------------------------------------------
    def _index(self) -> list[ClipEntry | DataError]:
        """Every sample of the label/list files, or a ``DataError`` for a bad one."""
        raise NotImplementedError

    # --- indexing helpers --------------------------------------------------------------------------------
    def _bad(self, err: DataError) -> None:
        if self.on_error == "raise":
            raise err
        self.skipped.append(str(err))
        warnings.warn(f"skipped: {err}", stacklevel=3)

    def _clip_paths(self, key_rel: str, source: str) -> list[str]:
        """Frame paths of the clip ending at ``key_rel`` (relative to root), oldest first."""
        key_path = resolve_inside(self.root, key_rel, source)
        rel = key_path.relative_to(self.root.resolve()).as_posix()
        paths: list[str | None] = []
        stride = mixed_stride(rel, self.strides) if self.strides else self.clip.stride
        for k in range(self.num_frames - 1, 0, -1):
            back = k * stride
            if self.frame_lookup == "number":
                name = history_name(rel, back)
            else:
                listing = self._sorted_listing(key_path.parent)
                pos = listing.index(key_path.name) if key_path.name in listing else -1
                name = str(PurePosixPath(rel).with_name(listing[pos - back])) if pos - back >= 0 else None
            paths.append(name)
        paths.append(rel)
        if self.clip.repeat_missing_history:
            for i in range(len(paths) - 2, -1, -1):
                path = paths[i]
                if path is None or not (self.root / path).is_file():
                    paths[i] = paths[i + 1]
        found = [p for p in paths if p is not None]
        if len(found) < len(paths):
            raise DataError(f"{source}: {rel} has no history frame {stride * (self.num_frames - 1)} frames back")
        return found

    def _sorted_listing(self, folder: Path) -> list[str]:
        if folder not in self._listing:
            self._listing[folder] = (
                sorted((p.name for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES), key=frame_order)
                if folder.is_dir()
                else []
            )
        return self._listing[folder]

    def _check_frames(self, entry: ClipEntry) -> None:
        for p in entry.frame_paths:
            if not (self.root / p).is_file():
                raise DataError(f"{entry.label_file}: frame {self.root / p} is missing")

    # --- samples --------------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.entries)

    def __getitem__(self, index: int) -> dict[str, Any]:
        if not 0 <= index < len(self.entries):
            raise IndexError(f"index {index} out of range for {len(self.entries)} samples")
        for attempt in range(len(self.entries)):
            position = (index + attempt) % len(self.entries)
            entry = self.entries[position]
            try:
                if self.history_source == "other_clip":
                    return self.load(entry, history_of=self.entries[self.partner(position)])
                return self.load(entry)
            except DataError as err:
                if self.on_error == "raise":
                    raise
                self.skipped.append(str(err))
                warnings.warn(f"skipped: {err}; using the next sample", stacklevel=2)
        raise DataError(f"no loadable sample in {self.root} (all {len(self.entries)} failed)")

    def read_frames(self, entry: ClipEntry) -> list[np.ndarray]:
        """The clip's BGR uint8 frames in original size; raises ``DataError`` on a missing/unreadable one."""
        frames: list[np.ndarray] = []
        for p in entry.frame_paths:
            path = self.root / p
            img = read_image(path)
            if img is None:
                raise DataError(f"{entry.label_file}: cannot read image {path} (missing, truncated or not an image)")
            if frames and img.shape != frames[0].shape:
                raise DataError(
                    f"{entry.label_file}: {path} is {img.shape[1]}x{img.shape[0]}, other frames "
                    f"{frames[0].shape[1]}x{frames[0].shape[0]}"
                )
            frames.append(img)
        return frames

    @property
    def stores_frames(self) -> bool:
        """Whether samples go through ``frame_store`` (`stamlane.data.frame_store`): one is set and the samples are
        the same every time (no augmentation, no key-frame corruption, history not synthesised)."""
        return (
            self.frame_store is not None
            and not self.transform.augments
            and self.key_corruption is None
            and self.history_source != "warped_key"
        )

    def materialise(self, threads: int = 1) -> int:
        """Put every sample's frames into ``frame_store`` now (the clips of one folder in one thread; nothing of
        torch's random state is used), so that loader workers forked later, and later passes, read them from
        memory; a sample with bad data is left to the pass that reads it. Returns the samples stored (0 when the
        dataset does not `stores_frames`)."""
        if not self.stores_frames:
            return 0
        folders: dict[str, list[int]] = {}
        for i, entry in enumerate(self.entries):
            folders.setdefault(str(PurePosixPath(entry.raw_file).parent), []).append(i)
        if self.history_source == "other_clip":  # a partner's pairs may be another thread's clip: one thread
            folders, threads = {"": list(range(len(self.entries)))}, 1

        def fill(indices: list[int]) -> int:
            done = 0
            for i in indices:
                try:
                    other = self.entries[self.partner(i)] if self.history_source == "other_clip" else None
                    slots = StoredSlots(self, self.entries[i], other)
                    params = self.transform.draw(slots.size)
                    feature = self.clip.warp == "feature"
                    eye = np.repeat(np.eye(3)[None], len(slots.key_from_hist), axis=0)
                    slots.network_frames(eye if feature else slots.key_from_hist, params)
                    done += 1
                except DataError:
                    continue
            return done

        if threads <= 1 or len(folders) == 1:
            return sum(fill(indices) for indices in folders.values())
        with ThreadPoolExecutor(threads) as pool:
            return sum(pool.map(fill, folders.values()))

    def partner(self, index: int) -> int:
        """The sample whose history ``history_source="other_clip"`` gives sample ``index``: the first sample of
        ANOTHER clip (another folder) from half the split away on, so every sample gets a fixed, distant clip."""
        clip = PurePosixPath(self.entries[index].raw_file).parent
        count = len(self.entries)
        for step in range(count // 2, count // 2 + count):
            other = (index + step) % count
            if PurePosixPath(self.entries[other].raw_file).parent != clip:
                return other
        raise DataError(f"history_source 'other_clip' needs samples of two clips, {self.root} has one ({clip})")

    def _history(self, entry: ClipEntry, history_of: ClipEntry | None) -> tuple[list[np.ndarray], np.ndarray]:
        """The clip's frames (original size, key last) and ``key_from_hist`` as ``history_source`` asks."""
        frames = self.read_frames(entry)
        if self.history_source == "key":
            return [frames[-1]] * len(frames), np.repeat(np.eye(3)[None], len(frames), axis=0)
        key_from_hist, _ok = self.aligner(entry.frame_paths, frames)
        if self.history_source == "warped_key":
            return warped_key(frames[-1], key_from_hist), key_from_hist
        if self.history_source == "reversed":
            order = [*range(len(frames) - 2, -1, -1), len(frames) - 1]
            return [frames[i] for i in order], key_from_hist[order]
        if history_of is None or len(frames) == 1:
            return frames, key_from_hist
        other = self.read_frames(history_of)
        if other[0].shape != frames[0].shape:
            raise DataError(f"{history_of.label_file}: its frames are not the size of {entry.raw_file}'s")
        other_from_hist, _ok = self.aligner(history_of.frame_paths, other)
        return [*other[:-1], frames[-1]], np.concatenate([other_from_hist[:-1], key_from_hist[-1:]])

    def load(
        self, entry: ClipEntry, rng: np.random.Generator | None = None, history_of: ClipEntry | None = None
    ) -> dict[str, Any]:
        """Build the sample of one entry (see the module docstring); ``rng`` drives the augmentation;
        ``history_of``: the entry whose history frames replace the entry's own (``history_source="other_clip"``)."""
        stored = self.stores_frames
        if stored:
            slots = StoredSlots(self, entry, history_of)
            key_from_hist, (h0, w0) = slots.key_from_hist, slots.size
        else:
            frames, key_from_hist = self._history(entry, history_of)
            h0, w0 = frames[0].shape[:2]
        _check_inside(entry, w0, h0)
        if rng is None:
            rng = np.random.default_rng(int(torch.randint(0, 2**31 - 1, ()).item()))
        params = self.transform.draw((h0, w0), rng)
        feature = self.clip.warp == "feature"
        applied = np.repeat(np.eye(3)[None], len(key_from_hist), axis=0) if feature else key_from_hist
        clip = slots.network_frames(applied, params) if stored else self.transform.apply_frames(frames, applied, params)
        if self.key_corruption is not None:
            clip = self.key_corruption(clip, rng)
        lanes_net = ClipTransform.map_lanes(entry.lanes, params.net_from_orig)
        binary, instance = draw_lane_targets(lanes_net, self.image_size, self.thickness, source=entry.label_file)
        usable = [lane for lane in entry.lanes if len(lane) >= 2]
        lanes = [usable[i].astype(np.float64) for i in left_to_right(usable)]
        sample = {
            "frames": torch.from_numpy(clip),
            "binary": torch.from_numpy(binary),
            "instance": torch.from_numpy(instance),
            "key_from_hist": torch.from_numpy(key_from_hist.astype(np.float32)),
            "lanes": lanes,
            "meta": {
                "raw_file": entry.raw_file,
                "orig_size": (h0, w0),
                "net_from_orig": params.net_from_orig.tolist(),
                "h_samples": entry.h_samples,
                "frame_paths": list(entry.frame_paths),
                "history_source": self.history_source,
                "format": self.format,
            },
        }
        if feature:
            sample[NET_HOMOGRAPHIES] = torch.from_numpy(
                net_homographies(key_from_hist, params.net_from_orig).astype(np.float32)
            )
        return sample


def _check_inside(entry: ClipEntry, width: int, height: int) -> None:
    """Refuse lane points more than one image size outside the ``width`` x ``height`` frame: drawn as a target,
    such a lane would cross the image on a line the annotation never meant (points just outside, as CULane's
    lanes that run off the border, are fine)."""
    for k, lane in enumerate(entry.lanes):
        if len(lane) and (
            np.abs(lane[:, 0] - width / 2).max() > 1.5 * width or np.abs(lane[:, 1] - height / 2).max() > 1.5 * height
        ):
            far = lane[np.argmax(np.abs(lane[:, 0] - width / 2) / width + np.abs(lane[:, 1] - height / 2) / height)]
            raise DataError(
                f"{entry.label_file}: lane {k} has the point ({far[0]:g}, {far[1]:g}), far outside the "
                f"{width}x{height} image"
            )


def warped_key(key: np.ndarray, key_from_hist: np.ndarray) -> list[np.ndarray]:
    """The matched null of a clip's history: the key frame as each history frame's view would show it.

    Args:
        key: the key frame, (H, W, 3) uint8.
        key_from_hist: (T, 3, 3), history frame ``j`` pixels -> key frame pixels (the last the identity).

    Returns:
        T frames, the key frame last (the same array) and before it the key frame warped by
        ``inverse(key_from_hist[j])`` (black where the key frame has no content), so that aligning frame ``j`` by
        ``key_from_hist[j]`` brings the key frame's own pixels back, blurred and with the black wedges real history
        frames have.
    """
    h, w = key.shape[:2]
    out = [
        cv2.warpPerspective(key, np.linalg.inv(m), (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        for m in key_from_hist[:-1]
    ]
    return [*out, key]
