"""The dataset layouts: TuSimple, CULane, ApolloScape and VIL-100 (`ClipDataset` subclasses, one per format), and
`make_clips`, the dataset of a format by its name (`FORMATS`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
from stamlane_eval.io import LaneFileError, duplicate_raw_file, read_text

from stamlane.data.clips import IMAGE_SUFFIXES, ClipDataset, ClipEntry
from stamlane.data.labels import (
    DataError,
    read_culane_lines,
    read_tusimple_labels,
    read_vil100_json,
    resolve_inside,
    tusimple_lanes,
)

__all__ = [
    "DATASETS",
    "FORMATS",
    "ApolloClips",
    "CULaneClips",
    "TuSimpleClips",
    "VIL100Clips",
    "make_clips",
]


def _image_token(line: str) -> str:
    """The image path of a list-file line: tokens up to the first one with an image suffix (paths such as
    ApolloScape's ``Camera 5/...`` contain spaces), else the first token."""
    tokens = line.split()
    for i, tok in enumerate(tokens):
        if tok.lower().endswith(IMAGE_SUFFIXES):
            return " ".join(tokens[: i + 1])
    return tokens[0]


class TuSimpleClips(ClipDataset):
    """TuSimple: label json-lines (``raw_file`` = ``clips/<date>/<id>/20.jpg``, ``lanes``, ``h_samples``);
    history frames by number in the same folder (T = 4, stride 1 gives frames 17..20).

    Args:
        root: data root.
        labels: label files relative to the root (e.g. ``["label_data_0313.json"]``).
        **kwargs: see ``ClipDataset``.
    """

    format = "tusimple"

    def __init__(self, root: str | Path, labels: list[str] | str, **kwargs: Any) -> None:
        self.labels = [labels] if isinstance(labels, str) else list(labels)
        if not self.labels:
            raise ValueError("labels must name at least one label file")
        super().__init__(root, **kwargs)

    def _index(self) -> list[ClipEntry | DataError]:
        out: list[ClipEntry | DataError] = []
        seen: dict[str, str] = {}
        for name in self.labels:
            path = resolve_inside(self.root, name, "labels")
            for number, rec in read_tusimple_labels(path):
                if isinstance(rec, DataError):
                    out.append(rec)
                    continue
                source = f"{path}:{number}"
                if rec["raw_file"] in seen:  # two labels for one image: the evaluator's check, the same message
                    out.append(DataError(f"{source}: {duplicate_raw_file(rec['raw_file'], seen[rec['raw_file']])}"))
                    continue
                seen[rec["raw_file"]] = source
                try:
                    frames = self._clip_paths(rec["raw_file"], source)
                except DataError as err:
                    out.append(err)
                    continue
                out.append(ClipEntry(rec["raw_file"], frames, tusimple_lanes(rec), list(rec["h_samples"]), source))
        return out


class _ListClips(ClipDataset):
    """Datasets indexed by list files of image paths (first token per line, relative to the root)."""

    def __init__(self, root: str | Path, lists: list[str] | str, **kwargs: Any) -> None:
        self.lists = [lists] if isinstance(lists, str) else list(lists)
        if not self.lists:
            raise ValueError("lists must name at least one list file")
        super().__init__(root, **kwargs)

    def _label_path(self, image_rel: str) -> Path:
        raise NotImplementedError

    def _read_lanes(self, path: Path) -> list[np.ndarray]:
        raise NotImplementedError

    def _index(self) -> list[ClipEntry | DataError]:
        out: list[ClipEntry | DataError] = []
        seen: dict[str, str] = {}
        for name in self.lists:
            path = resolve_inside(self.root, name, "lists")
            try:  # a FIFO or a device is never read; gzip bytes or a NUL are the list file's problem, named
                text = read_text(path, universal_newlines=False)
            except OSError as err:
                raise DataError(f"cannot read list file {path}: {err.strerror}") from None
            except LaneFileError as err:  # names the file: not UTF-8 (gzip bytes?), a FIFO, over the size limit
                raise DataError(f"list file {err}") from None
            if "\x00" in text:
                raise DataError(
                    f"list file {path}: holds a NUL byte at character {text.index(chr(0))} (not a text list)"
                )
            lines = text.splitlines()
            for number, line in enumerate(lines, start=1):
                if not line.strip():
                    continue
                source = f"{path}:{number}"
                image_rel = _image_token(line)
                if image_rel in seen:
                    out.append(DataError(f"{source}: duplicate entry {image_rel!r} (first at {seen[image_rel]})"))
                    continue
                seen[image_rel] = source
                try:
                    frames = self._clip_paths(image_rel, source)
                    label = self._label_path(frames[-1])
                    if label.is_file() or self.require_labels:
                        lanes = self._read_lanes(label)
                    else:
                        lanes = []
                except DataError as err:
                    out.append(DataError(f"{source}: {err}") if source not in str(err) else err)
                    continue
                out.append(ClipEntry(frames[-1], frames, lanes, None, str(label)))
        return out


class CULaneClips(_ListClips):
    """CULane: list files of image paths (``/driver_xx/<video>.MP4/00030.jpg ...``), one ``.lines.txt``
    beside each image (``00030.lines.txt``: one lane a line, ``x1 y1 x2 y2 ...``).

    CULane keeps every 30th frame of its videos, so history frames come by name with ``stride=30`` where
    they exist; use ``clip.num_frames=1`` for the single-frame protocol, or ``clip.repeat_missing_history=True``.
    """

    format = "culane"

    def _label_path(self, image_rel: str) -> Path:
        return (self.root / image_rel).with_suffix(".lines.txt")

    def _read_lanes(self, path: Path) -> list[np.ndarray]:
        return read_culane_lines(path)


class ApolloClips(_ListClips):
    """ApolloScape lane sequences with per-frame lane points in the CULane text form.

    The paper's ApolloScape point labels were never published, so this loader reads the ApolloScape
    image sequences (e.g. ``ColorImage_road02/ColorImage/Record001/Camera 5/<stamp>_Camera_5.jpg``)
    with ``<frame>.lines.txt`` either beside each image or, with ``label_dir``, mirrored under
    ``<root>/<label_dir>/<same relative path>``. History frames are the previous images in the
    folder's sorted listing (``frame_lookup="sorted"``; the frame names are timestamps).

    Args:
        root: data root.
        lists: list files of key-frame image paths.
        label_dir: folder (relative to root) that mirrors the image tree with ``.lines.txt`` files.
        **kwargs: see ``ClipDataset``.
    """

    format = "apollo"
    frame_lookup = "sorted"

    def __init__(self, root: str | Path, lists: list[str] | str, label_dir: str | None = None, **kwargs: Any) -> None:
        self.label_dir = label_dir
        super().__init__(root, lists, **kwargs)

    def _label_path(self, image_rel: str) -> Path:
        rel = PurePosixPath(image_rel).with_suffix(".lines.txt")
        if self.label_dir:
            return resolve_inside(self.root, str(PurePosixPath(self.label_dir) / rel), "label_dir")
        return self.root / rel

    def _read_lanes(self, path: Path) -> list[np.ndarray]:
        return read_culane_lines(path)


class VIL100Clips(_ListClips):
    """VIL-100: ``JPEGImages/<video>/<frame>.jpg`` with ``Json/<video>/<frame>.jpg.json`` per frame (every
    frame labelled, so a clip can end on any frame). List files name key frames (e.g. VIL-100's
    ``data/train.txt``: ``/JPEGImages/<video>/00000.jpg ...``); history frames by number.
    """

    format = "vil100"

    def _label_path(self, image_rel: str) -> Path:
        parts = PurePosixPath(image_rel).parts
        if not parts or parts[0] != "JPEGImages":
            raise DataError(f"VIL-100 image path {image_rel!r} does not start with JPEGImages/")
        return self.root / "Json" / PurePosixPath(*parts[1:]).with_name(parts[-1] + ".json")

    def _read_lanes(self, path: Path) -> list[np.ndarray]:
        return read_vil100_json(path)


# each class is built as cls(root, its label or list files, **options): the base class's signature is not theirs
DATASETS: dict[str, Callable[..., ClipDataset]] = {
    cls.format: cls for cls in (TuSimpleClips, CULaneClips, ApolloClips, VIL100Clips)
}
"""The dataset of each format (each class names its own ``format``): the one list of formats."""
FORMATS = tuple(DATASETS)


def make_clips(
    format: str, root: str | Path, files: list[str] | str, label_dir: str | None = None, **kwargs: Any
) -> ClipDataset:
    """The dataset of ``format`` (`FORMATS`) over the label or list ``files``; ``label_dir`` is ApolloScape's.

    Raises:
        ValueError: an unknown format, or ``label_dir`` for another format than ApolloScape.
    """
    if format not in DATASETS:
        raise ValueError(f"format must be one of {FORMATS}, got {format!r}")
    if label_dir is not None and DATASETS[format] is not ApolloClips:
        raise ValueError(f"label_dir is ApolloScape's option, not {format!r}'s")
    extra = {"label_dir": label_dir} if DATASETS[format] is ApolloClips else {}
    return DATASETS[format](root, files, **extra, **kwargs)
