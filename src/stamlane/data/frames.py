"""Clips from a folder of frames or a video file, without labels (``stamlane predict --source``).

`FolderClips` serves every image of a folder (in name order, ``2.jpg`` before ``10.jpg``) as the key frame of a
clip of its predecessors, key frame last; the first frames of the sequence repeat the earliest available frame
as history. `decode_video` turns a video into such a folder (`video_rate` gives its frame rate).

A folder is not always one sequence: `check_sequence` says when its images differ in size or when their content
jumps from a frame to the one its history is read from (`SequenceCheck`), so that unrelated pictures are not
silently used as each other's history.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from tqdm import tqdm

from stamlane.data.clips import IMAGE_SUFFIXES, ClipDataset, ClipEntry
from stamlane.data.labels import DataError
from stamlane.data.options import ClipOptions
from stamlane.safety.budget import MAX_FPS
from stamlane.safety.guard import make_folder
from stamlane.safety.images import open_video, read_image

__all__ = [
    "JUMP_CORRELATION",
    "JUMP_SHARE",
    "VIDEO_SUFFIXES",
    "FolderClips",
    "SequenceCheck",
    "check_sequence",
    "decode_video",
    "frame_similarity",
    "video_rate",
]

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm")

THUMB_WIDTH = 64
"""px: frames are compared as grey thumbnails this wide (the height keeps the aspect ratio)."""
MAX_SHIFT = (4, 2)
"""(x, y) thumbnail pixels searched for the best match: the image motion of a camera between history frames
(6 % of the width sideways, 6 % of the height up or down)."""
JUMP_CORRELATION = 0.5
"""A frame pair whose gradient thumbnails correlate below this (`frame_similarity`) has jumped in content.
Measured (64-px thumbnails, shifts searched): consecutive frames of clean synthetic clips (train, val, test;
stride 1 and 2, 750 pairs) >= 0.60; a real 1280x720 frame zoomed 5 % a frame as driving forward >= 0.81; the
six unrelated real highway frames of ../shared/data/frames, every pair, <= 0.46; frames of two different
synthetic clips: half of the pairs below 0.53 (one generator: one layout). Synthetic clips made to be hard (a
flash, an occluder in the key frame, a truck at 5 fps) have single pairs down to 0.29: hence `JUMP_SHARE`."""
JUMP_SHARE = 1 / 3
"""A folder is "not one sequence" when at least this share of its frame pairs jump (`JUMP_CORRELATION`): a flash
or a truck in a real sequence moves single pairs (at most 27 % of the pairs of a hard synthetic clip at stride
1), unrelated pictures most of them (every pair of the six real frames; 69 % of 12-frame folders of shuffled
synthetic frames, 37 % of 4-frame ones: synthetic scenes look alike)."""


class FolderClips(ClipDataset):
    """Every image of one folder (in name order, numbers compared as numbers) as the key frame of a clip of its predecessors; no labels.

    ``raw_file`` is the image's name; ``h_samples`` is ``None`` (lanes are written as CULane text).
    """

    format = "frames"
    frame_lookup = "sorted"

    def __init__(self, root: str | Path, *, clip: ClipOptions = ClipOptions(), **kwargs: Any) -> None:
        # the first frames of the sequence have no predecessors: the earliest frame stands in for them
        kwargs.update(require_labels=False)
        super().__init__(root, clip=replace(clip, repeat_missing_history=True), **kwargs)

    def _index(self) -> list[ClipEntry | DataError]:
        names = self._sorted_listing(self.root)
        if not names:
            raise DataError(f"{self.root} holds no image ({', '.join(IMAGE_SUFFIXES)})")
        source = str(self.root)
        return [ClipEntry(name, self._clip_paths(name, source), [], None, source) for name in names]

    def read_frames(self, entry: ClipEntry) -> list[np.ndarray]:
        """The clip's frames; with ``history_source="key"`` the key frame alone, read once and repeated (its
        predecessors, which may be of another size, are never read)."""
        if self.history_source != "key":
            return super().read_frames(entry)
        return super().read_frames(replace(entry, frame_paths=entry.frame_paths[-1:])) * len(entry.frame_paths)


def video_rate(video: str | Path) -> float | None:
    """The frame rate a video declares, or None when it declares none or an absurd one (not in ``(0, MAX_FPS]``)."""
    capture = open_video(video, DataError)
    fps = float(capture.get(cv2.CAP_PROP_FPS) or 0.0)
    capture.release()
    return fps if math.isfinite(fps) and 0 < fps <= MAX_FPS else None


def decode_video(video: str | Path, out_dir: str | Path, every: int = 1, progress: bool = True) -> Path:
    """Decode a video into ``out_dir/000000.jpg, 000001.jpg, ...`` (every ``every``-th frame); returns ``out_dir``.

    ``progress``: show a progress bar of the frames decoded (False: none, as ``stamlane adapt --no-progress``)."""
    capture = open_video(video, DataError)
    out = make_folder(out_dir)
    total = int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) or None
    index = written = 0
    with tqdm(total=total, desc=f"decoding {Path(video).name}", unit="frame", disable=not progress) as bar:
        while True:
            ok, frame = capture.read()
            if not ok:
                break
            if index % every == 0:
                if not cv2.imwrite(str(out / f"{written:06d}.jpg"), frame, [cv2.IMWRITE_JPEG_QUALITY, 95]):
                    raise OSError(f"cannot write frame {written} of {video} into {out} (a full disk?)")
                written += 1
            index += 1
            bar.update(1)
    capture.release()
    if written == 0:
        raise DataError(f"no frame could be decoded from {video}")
    return out


def _thumbnail(image: np.ndarray) -> np.ndarray:
    """The gradient magnitude of a grey `THUMB_WIDTH`-px thumbnail, float64 ``(h, THUMB_WIDTH)``: edges (lane marks,
    cars, trees, the horizon) rather than brightness, which every road picture shares (sky above, road below)."""
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    height = max(2 * MAX_SHIFT[1] + 2, round(THUMB_WIDTH * grey.shape[0] / grey.shape[1]))
    small = cv2.resize(grey, (THUMB_WIDTH, height), interpolation=cv2.INTER_AREA).astype(np.float64)
    return np.hypot(cv2.Sobel(small, cv2.CV_64F, 1, 0), cv2.Sobel(small, cv2.CV_64F, 0, 1))


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    norm = math.sqrt(float((a * a).sum() * (b * b).sum()))
    return float((a * b).sum() / norm) if norm > 0 else float(np.array_equal(a, b))


def frame_similarity(earlier: np.ndarray, later: np.ndarray) -> float:
    """How much two frames look like one scene a moment apart: the highest Pearson correlation of their gradient
    thumbnails over the shifts of `MAX_SHIFT` (in [-1, 1]; 1 for identical frames).

    Args:
        earlier: a frame, uint8 ``(H, W, 3)`` BGR or ``(H, W)`` grey.
        later: another frame; its size may differ (both are thumbnailed to the same width).
    """
    return _similarity(_thumbnail(earlier), _thumbnail(later))


def _similarity(a: np.ndarray, b: np.ndarray) -> float:
    h = min(len(a), len(b))
    a, b = a[:h], b[:h]
    best = -1.0
    for dy in range(-MAX_SHIFT[1], MAX_SHIFT[1] + 1):
        for dx in range(-MAX_SHIFT[0], MAX_SHIFT[0] + 1):
            ys, yo = slice(max(0, dy), h + min(0, dy)), slice(max(0, -dy), h + min(0, -dy))
            xs, xo = slice(max(0, dx), THUMB_WIDTH + min(0, dx)), slice(max(0, -dx), THUMB_WIDTH + min(0, -dx))
            best = max(best, _correlation(a[ys, xs], b[yo, xo]))
    return best


@dataclass(frozen=True)
class SequenceCheck:
    """Whether the images of a folder read as one sequence (`check_sequence`).

    Attributes:
        names: the images, in the order they are read.
        sizes: how many images have each ``(H, W)``.
        jumps: ``(earlier, later, similarity)`` of each pair whose similarity is below `JUMP_CORRELATION`.
        pairs: the pairs compared (each image with the one its history is read from).
        stride: positions between the two images of a pair.
    """

    names: tuple[str, ...]
    sizes: dict[tuple[int, int], int]
    jumps: tuple[tuple[str, str, float], ...]
    pairs: int
    stride: int

    @property
    def one_size(self) -> bool:
        return len(self.sizes) <= 1

    @property
    def jumping(self) -> bool:
        """At least `JUMP_SHARE` of the pairs (and one) jump in content."""
        return bool(self.jumps) and len(self.jumps) >= JUMP_SHARE * self.pairs

    @property
    def one_sequence(self) -> bool:
        return self.one_size and not self.jumping

    def problem(self) -> str | None:
        """What makes the folder not one sequence, in a few words (None when it is one)."""
        said = []
        if not self.one_size:
            common = ", ".join(f"{n} of {w}x{h}" for (h, w), n in Counter(self.sizes).most_common(3))
            said.append(f"{len(self.sizes)} image sizes ({common}{', ...' if len(self.sizes) > 3 else ''})")
        if self.jumping:
            a, b, value = self.jumps[0]
            apart = "" if self.stride == 1 else f" {self.stride} apart"
            said.append(
                f"the content jumps between {len(self.jumps)} of {self.pairs} frame pairs{apart} (first {a} -> {b}, "
                f"similarity {value:.2f} < {JUMP_CORRELATION})"
            )
        return "; ".join(said) or None


def check_sequence(root: str | Path, names: list[str], stride: int = 1) -> SequenceCheck:
    """Compare every image of ``root`` with the one ``stride`` positions before it (where its history comes from).

    Args:
        root: the folder.
        names: its images, in the order they are read (`FolderClips`'s).
        stride: `ClipOptions.stride`.

    Returns:
        the sizes and the pairs whose content jumps (`frame_similarity` below `JUMP_CORRELATION`).

    Raises:
        DataError: an image that cannot be read.
    """
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    thumbs: dict[int, np.ndarray] = {}  # the last stride + 1 thumbnails
    sizes: Counter[tuple[int, int]] = Counter()
    jumps = []
    for i, name in enumerate(names):
        image = read_image(Path(root) / name)
        if image is None:
            raise DataError(f"cannot read image {Path(root) / name}")
        sizes[(image.shape[0], image.shape[1])] += 1
        thumbs[i] = _thumbnail(image)
        thumbs.pop(i - stride - 1, None)
        if i >= stride:
            value = _similarity(thumbs[i - stride], thumbs[i])
            if value < JUMP_CORRELATION:
                jumps.append((names[i - stride], name, value))
    return SequenceCheck(tuple(names), dict(sizes), tuple(jumps), max(0, len(names) - stride), stride)
