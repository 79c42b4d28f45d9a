"""Write predicted lanes in the benchmarks' own formats, so ``stamlane-eval`` scores them unconverted.

TuSimple (docs/method.md §6-7): one json object per line, ``{"raw_file", "lanes", "h_samples", "run_time"}``;
``lanes`` holds one list of x per lane, one x per row of ``h_samples``, ``-2`` where the lane is absent;
``run_time`` is in milliseconds (the official script gives an image zero accuracy above 200 ms).

CULane / ApolloScape (docs/method.md §6, §8): one ``<image stem>.lines.txt`` per image, mirroring the image's
relative path under the output folder, one lane a line: ``x1 y1 x2 y2 ...`` in original pixels.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, TextIO

import numpy as np

from stamlane.safety.guard import make_folder
from stamlane.types import Lanes

__all__ = [
    "TusimpleWriter",
    "format_culane_lines",
    "open_output",
    "output_path",
    "tusimple_record",
    "write_culane_lines",
]


def tusimple_record(raw_file: str, lanes: Lanes, h_samples: Sequence[int], run_time: float) -> dict[str, Any]:
    """One TuSimple prediction line.

    Args:
        raw_file: the benchmark's name of the key frame (``clips/<date>/<id>/20.jpg``).
        lanes: ``(N, 2)`` ``(x, y)`` lanes in original pixels; each is sampled at ``h_samples`` by
            ``stamlane_eval.tusimple.lanes_to_xs`` (-2 outside the rows the lane covers).
        h_samples: the ground truth's rows for this image.
        run_time: milliseconds spent on the image.

    Returns:
        the json object of the line.
    """
    from stamlane_eval.tusimple import lanes_to_xs

    if not h_samples:
        raise ValueError(f"h_samples of {raw_file!r} is empty; TuSimple predictions need the ground truth's rows")
    xs = lanes_to_xs(lanes, list(h_samples))
    xs = [[float(round(float(x), 2)) if x >= 0 else -2 for x in lane] for lane in xs]
    return {"raw_file": raw_file, "lanes": xs, "h_samples": [int(h) for h in h_samples], "run_time": float(run_time)}


class TusimpleWriter:
    """Append TuSimple prediction lines to a json-lines file.

    Example:
        >>> with TusimpleWriter(path) as writer:  # doctest: +SKIP
        ...     writer.write("clips/0/20.jpg", lanes, h_samples, run_time=12.0)
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        make_folder(self.path.parent)
        self._file = open_output(self.path.parent, self.path)
        self.count = 0

    def write(self, raw_file: str, lanes: Lanes, h_samples: Sequence[int], run_time: float) -> None:
        """Write one image's line; see :func:`tusimple_record`."""
        self._file.write(json.dumps(tusimple_record(raw_file, lanes, h_samples, run_time)) + "\n")
        self.count += 1

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> TusimpleWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def format_culane_lines(lanes: Lanes) -> str:
    """The text of a ``.lines.txt`` file: one lane a line, ``x1 y1 x2 y2 ...``; lanes with < 2 points skipped."""
    lines = []
    for lane in lanes:
        lane = np.asarray(lane, dtype=np.float64)
        if lane.ndim != 2 or lane.shape[1] != 2:
            raise ValueError(f"expected a lane of shape (N, 2), got {lane.shape}")
        if len(lane) < 2:
            continue
        lines.append(" ".join(f"{x:.2f} {y:.2f}" for x, y in lane))
    return "".join(line + "\n" for line in lines)


def write_culane_lines(out_dir: str | Path, raw_file: str, lanes: Lanes) -> Path:
    """Write one image's lanes to the path ``stamlane-eval culane`` reads (`stamlane_eval.io.culane_lines_path`:
    ``<out_dir>/<raw_file without its suffix>.lines.txt``; a ``raw_file`` that would leave ``out_dir`` is refused);
    returns the path written."""
    from stamlane_eval.io import culane_lines_path

    path = culane_lines_path(out_dir, raw_file)
    make_folder(path.parent)
    with open_output(out_dir, path) as f:
        f.write(format_culane_lines(lanes))
    return path


def output_path(out_dir: str | Path, path: Path) -> Path:
    """``path`` made safe to write as a new file of ``out_dir``: a link found in its place is removed (the file
    replaces the link; nothing is written through it, into an input it may point at), and a folder on the way
    that leads out of ``out_dir`` (a planted link) is refused.

    Raises:
        ValueError: the path would land outside ``out_dir``.
    """
    root = Path(out_dir).resolve()
    if not path.parent.resolve().is_relative_to(root):
        raise ValueError(f"{path}: a link on the way leads out of the output folder {out_dir}")
    if path.is_symlink():
        path.unlink()
    return path


def open_output(out_dir: str | Path, path: Path) -> TextIO:
    """``open(path, "w")`` after `output_path`."""
    return output_path(out_dir, path).open("w")
