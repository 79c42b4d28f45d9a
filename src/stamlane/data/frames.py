"""Clips from a folder of frames or a video file, without labels (``stamlane predict --source``).

`FolderClips` serves every image of a folder (in name order, ``2.jpg`` before ``10.jpg``) as the key frame of a
clip of its predecessors, key frame last; the first frames of the sequence repeat the earliest available frame
as history. `decode_video` turns a video into such a folder.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
from tqdm import tqdm

from stamlane.data.clips import IMAGE_SUFFIXES, ClipDataset, ClipEntry
from stamlane.data.labels import DataError
from stamlane.data.options import ClipOptions
from stamlane.safety.images import open_video

__all__ = ["VIDEO_SUFFIXES", "FolderClips", "decode_video"]

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm")


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


def decode_video(video: str | Path, out_dir: str | Path, every: int = 1) -> Path:
    """Decode a video into ``out_dir/000000.jpg, 000001.jpg, ...`` (every ``every``-th frame); returns ``out_dir``."""
    capture = open_video(video, DataError)
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
