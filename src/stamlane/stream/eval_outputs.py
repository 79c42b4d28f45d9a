"""What ``stamlane stream --tusimple / --culane`` writes beside ``lanes.jsonl``: the files ``stamlane-eval`` scores.

Each frame is named like the frames of a benchmark: ``<sequence>/<frame name>``, the sequence being a folder of
frames' name or a video's stem (``--sequence``), a frame name its image's name, or for a video a number counted on
from ``--first-frame`` (``000000.jpg``, the names ``stamlane predict --source VIDEO`` decodes to; ``1.jpg`` for
TuSimple clips and the generator's ``clips/<id>/1.jpg``). Then:

``predictions.json`` (``--tusimple``)
    TuSimple json-lines, one record per frame, ``{"raw_file": "<sequence>/<frame>", "lanes", "h_samples",
    "run_time"}`` (`stamlane.predict.writers.TusimpleWriter`, the writer of ``stamlane predict``'s): read by
    ``stamlane-eval tusimple`` (give ``--h-samples`` the ground truth's rows) and ``stamlane-eval video``, where the
    folder of ``raw_file`` is the sequence.
``lines/<sequence>/<frame stem>.lines.txt`` (``--culane``)
    CULane text, one lane a line (`stamlane.predict.writers.write_culane_lines`): read by ``stamlane-eval culane`` and
    ``stamlane-eval video`` with ``lines/`` as the prediction folder.
"""

from __future__ import annotations

import os
import re
import shutil
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from stamlane.predict.writers import TusimpleWriter, write_culane_lines
from stamlane.safety.budget import MAX_SIDE
from stamlane.safety.guard import temporary_name

__all__ = [
    "DEFAULT_FIRST_FRAME",
    "EvalOutputs",
    "atomic_folder",
    "check_h_samples",
    "check_sequence",
    "folder_temporaries",
    "frame_namer",
]

DEFAULT_FIRST_FRAME = "000000.jpg"
"""A video's first frame, as `stamlane.data.frames.decode_video` names it for ``stamlane predict --source``."""

_FRAME_NAME = re.compile(r"([A-Za-z0-9_-]*?)([0-9]{1,12})(\.[A-Za-z0-9]{1,8})", re.ASCII)
_PART = re.compile(r"[^\x00-\x1f\x7f/\\]{1,255}")


def check_sequence(name: str, what: str = "--sequence") -> str:
    """A sequence name: a relative path of plain names (``clips/0531``), no ``.`` or ``..``, no control characters.

    Raises:
        ValueError: naming the flag and the value.
    """
    parts = name.split("/")
    if len(name) > 1024 or not all(_PART.fullmatch(p) and p not in (".", "..") for p in parts):
        raise ValueError(
            f"{what} must be a relative path of plain names (e.g. clips/0531), without . or .., got {name!r:.80}"
        )
    return name


def frame_namer(first: str) -> Callable[[int], str]:
    """The name of a video's ``i``-th frame (from 0), counted on from ``first``, the number's width kept:
    ``frame_namer("1.jpg")(19) == "20.jpg"``, ``frame_namer("00000.jpg")(30) == "00030.jpg"``.

    Raises:
        ValueError: ``first`` is not ``[prefix]<number>.<extension>`` (letters, digits, ``_`` and ``-``).
    """
    match = _FRAME_NAME.fullmatch(first)
    if match is None:
        raise ValueError(
            f"--first-frame must be a frame name such as 000000.jpg or 1.jpg (a number and an extension), "
            f"got {first!r:.80}"
        )
    prefix, number, suffix = match.groups()
    start, width = int(number), len(number)
    return lambda i: f"{prefix}{start + i:0{width}d}{suffix}"


def check_h_samples(rows: Sequence[int]) -> list[int]:
    """``--h-samples START STOP STEP`` as the rows ``range(START, STOP, STEP)``: 0 <= START < STOP <= the largest
    image side, STEP >= 1.

    Raises:
        ValueError: naming the values.
    """
    start, stop, step = rows
    if not (0 <= start < stop <= MAX_SIDE and step >= 1):
        raise ValueError(
            f"--h-samples START STOP STEP must give rows 0 <= START < STOP <= {MAX_SIDE}, STEP >= 1, "
            f"got {start} {stop} {step}"
        )
    return list(range(start, stop, step))


def folder_temporaries(path: Path) -> tuple[Path, Path]:
    """The names `atomic_folder` uses beside ``path``: the new folder while it is written, the old one while it
    is swapped out (for `stamlane.safety.guard.check_outputs`)."""
    tmp = temporary_name(path)
    return tmp, tmp.with_name(tmp.name + ".old")


@contextmanager
def atomic_folder(path: Path) -> Iterator[Path]:
    """A temporary folder beside ``path`` (`folder_temporaries`) that replaces ``path`` when the block ends without
    an error, and is removed when it fails: a failed run leaves the previous folder whole.
    (`stamlane.safety.guard.atomic_path` does this for files; a folder is swapped in two renames.)"""
    tmp, old = folder_temporaries(path)
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        yield tmp
        if os.path.lexists(path):
            path.rename(old)
        tmp.rename(path)
        shutil.rmtree(old, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


class EvalOutputs:
    """Writes each frame's lanes as TuSimple records and / or CULane text (see the module docstring).

    Args:
        sequence: the sequence the frames are named under.
        tusimple: the writer of the TuSimple records (`stamlane.predict.writers.TusimpleWriter`, the one
            ``stamlane predict`` writes its ``predictions.json`` with), or None.
        culane: the folder of the CULane files, or None.
        h_samples: the TuSimple rows; None: every ``y_step`` rows of the frame, from row 0.
        y_step: rows between the default ``h_samples``.
    """

    def __init__(
        self,
        sequence: str,
        tusimple: TusimpleWriter | None,
        culane: Path | None,
        h_samples: list[int] | None,
        y_step: int,
    ) -> None:
        self.sequence = check_sequence(sequence, "the sequence name")
        self.tusimple, self.culane = tusimple, culane
        self.h_samples, self.y_step = h_samples, y_step

    def write(self, frame: str, lanes: list[np.ndarray], run_time: float, height: int) -> None:
        """One frame: its name, its lanes ``(N, 2)`` ``(x, y)`` in frame pixels, milliseconds, the frame's rows."""
        raw_file = f"{self.sequence}/{frame}"
        if self.tusimple is not None:
            self.tusimple.write(raw_file, lanes, self.h_samples or list(range(0, height, self.y_step)), run_time)
        if self.culane is not None:
            write_culane_lines(self.culane, raw_file, lanes)  # <culane>/<sequence>/<frame stem>.lines.txt
