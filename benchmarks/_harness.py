"""What the benchmark scripts share: their options and inputs checked by stamlane's contract for a command (one line
on stderr naming the file or option and the problem, exit status 2, nothing written), the machine a result came
from, the result files written atomically, and timings of variants run side by side.

A script runs as ``python benchmarks/<name>.py`` (Python puts the script's folder on ``sys.path``) and imports it::

    from _harness import BenchInputError, fail, guard_out, machine, write_result

The tests load a script through ``tests/benchmarks/scripts.py``, which finds this module and the script's siblings
the same way.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, TypeVar

from stamlane.safety.guard import GuardError, atomic_path, check_outputs, read_input, temporary_name, write_atomic

__all__ = [
    "MAX_JSON_BYTES",
    "BenchInputError",
    "Within",
    "check_out_file",
    "check_out_folder",
    "clips_of",
    "fail",
    "guard_out",
    "in_turn",
    "load_1min",
    "machine",
    "medians",
    "option_problem",
    "ratio",
    "read_json_object",
    "timed",
    "write_figure",
    "write_image",
    "write_result",
]

MAX_JSON_BYTES = 64 << 20
"""Largest JSON file a benchmark reads back (its own results, a run's file): 64 MiB."""

T = TypeVar("T")


class BenchInputError(ValueError):
    """A benchmark's input or option that cannot be used: one line, exit status 2."""


def fail(prog: str, err: object) -> int:
    """Print ``prog: error: err`` as one line on stderr; returns 2, the exit status of a bad input."""
    line = " ".join(str(err).split())  # one line whatever the message held
    print(f"{prog}: error: {line}", file=sys.stderr)
    return 2


# --- options ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Within:
    """The values an integer option may take: ``low`` to ``high`` (both included), or ``low`` and above where
    ``high`` is None; ``why`` follows the range in the message (``" (the intervals resample clips)"``)."""

    low: int
    high: int | None = None
    why: str = ""

    def problem(self, option: str, value: int | None) -> str | None:
        """The one-line message for ``value`` of ``option`` out of range; None where it is inside (or not given)."""
        if value is None:
            return None
        if self.high is None:
            return None if value >= self.low else f"{option} must be >= {self.low}{self.why}, got {value}"
        inside = self.low <= value <= self.high
        return None if inside else f"{option} must be in {self.low}..{self.high}{self.why}, got {value}"


def option_problem(
    values: Mapping[str, Any],
    choices: Mapping[str, Sequence[str]] | None = None,
    ranges: Mapping[str, Within] | None = None,
) -> str | None:
    """The first problem of a script's parsed options (``vars(args)``), in the order given: a value of a list option
    not among its ``choices`` (``--kinds: x not of a b``), then an integer option outside its range; None where
    every option can be used. An option is named by its destination (``--resamples`` for ``resamples``)."""
    for dest, allowed in (choices or {}).items():
        unknown = [v for v in values[dest] if v not in allowed]
        if unknown:
            return f"{_flag(dest)}: {' '.join(unknown)} not of {' '.join(allowed)}"
    for dest, within in (ranges or {}).items():
        if (problem := within.problem(_flag(dest), values[dest])) is not None:
            return problem
    return None


def _flag(dest: str) -> str:
    return "--" + dest.replace("_", "-")


# --- inputs and outputs ----------------------------------------------------------------------------------------


def read_json_object(path: Path, what: str, keys: Sequence[str] = ()) -> dict:
    """The JSON object in ``path`` (a regular file of at most `MAX_JSON_BYTES`), with ``keys``.

    Raises:
        BenchInputError: naming ``what`` and the file: missing, not a file, not JSON, not an object, a key missing.
    """
    try:
        value = json.loads(read_input(path, MAX_JSON_BYTES, what))
    except GuardError as err:
        raise BenchInputError(str(err)) from None
    except (ValueError, RecursionError) as err:  # JSON's errors (UnicodeDecodeError included) are ValueErrors
        raise BenchInputError(f"{what} {path} is not JSON ({str(err)[:80]})") from None
    if not isinstance(value, dict):
        raise BenchInputError(f"{what} {path} holds a JSON {type(value).__name__}, not an object")
    missing = [k for k in keys if k not in value]
    if missing:
        raise BenchInputError(f"{what} {path} has no {', '.join(map(repr, missing))}")
    return value


def check_out_file(
    out: Path, side: Iterable[str] = (), reads: Iterable[Path] = (), protected: Iterable[Path] = ()
) -> None:
    """Refuse, before any work, an output file (and the files written beside it, ``out`` with each suffix of
    ``side``, and their temporary names) that is a folder, lies under a file, cannot be written, or would replace
    or land inside an input (`stamlane.safety.guard.check_outputs`).

    Raises:
        GuardError: one line naming the output.
    """
    files = [out, *(out.with_suffix(s) for s in side)]
    check_outputs([*files, *map(temporary_name, files)], reads, protected=protected)


def check_out_folder(out: Path, protected: Iterable[Path] = ()) -> None:
    """Refuse an output folder that is a file, cannot be created or written, or lies inside an input.

    Raises:
        GuardError: one line naming the folder.
    """
    check_outputs(folders=[out], protected=protected)


def clips_of(names: Sequence[str], labels: Path) -> list[str]:
    """The clip of each image (the folder of its ``raw_file``), refusing a split of fewer than two clips: a
    clip bootstrap resamples whole clips and has no interval with one.

    Raises:
        BenchInputError: naming the label file.
    """
    clips = [str(PurePosixPath(name).parent) for name in names]
    if len(set(clips)) < 2:
        raise BenchInputError(
            f"{labels}: {len(names)} images in {len(set(clips))} clip: the clip bootstrap needs at least 2 clips"
        )
    return clips


def guard_out(prog: str, out: str | Path | None, *, folder: bool = False, side: Iterable[str] = ()) -> int | None:
    """The check of a script's ``--out`` before any work (`check_out_file`, or `check_out_folder` with ``folder``):
    None where it can be written (or none is given), else the exit status 2 after its one line (`fail`)."""
    if out is None:
        return None
    try:
        if folder:
            check_out_folder(Path(out))
        else:
            check_out_file(Path(out), side=side)
    except GuardError as err:
        return fail(prog, err)
    return None


def write_result(path: Path, result: object, *, indent: int = 1, allow_nan: bool = True, quiet: bool = False) -> None:
    """Write a script's results as JSON to ``path`` (its folder made), atomically (`stamlane.safety.guard`'s one
    writer: a reader never sees half a file, an interrupted run leaves the earlier one), then say so on stdout
    unless ``quiet``."""
    write_atomic(path, json.dumps(result, indent=indent, allow_nan=allow_nan) + "\n")
    if not quiet:
        print(f"wrote {path}")


def write_image(path: Path, image: Any, params: Sequence[int] = ()) -> None:
    """Write a picture (an OpenCV BGR array; the format by the suffix of ``path``, ``params`` OpenCV's
    ``IMWRITE_*`` pairs) atomically, its folder made.

    Raises:
        OSError: OpenCV could not encode or write it (nothing is left at ``path``).
    """
    import cv2  # only the scripts that draw pay for it

    with atomic_path(path) as tmp:  # the temporary name keeps the suffix: OpenCV picks the format by it
        try:
            written = cv2.imwrite(str(tmp), image, list(params))
        except cv2.error as err:  # no encoder for the suffix, an image it cannot encode
            raise OSError(f"could not write the picture {path}: {str(err).strip().splitlines()[-1]}") from None
        if not written:
            raise OSError(f"could not write the picture {path}")


def write_figure(figure: Any, path: Path, dpi: int) -> None:
    """Save a matplotlib figure (the format by the suffix of ``path``) atomically, its folder made, and close it."""
    import matplotlib.pyplot as plt

    with atomic_path(path) as tmp:  # the same suffix: matplotlib picks the format by it
        figure.savefig(tmp, dpi=dpi)
    plt.close(figure)


# --- the machine -----------------------------------------------------------------------------------------------


def load_1min() -> float:
    """The machine's load average over the last minute, rounded to 0.1: what a timing on a shared machine shared."""
    return round(os.getloadavg()[0], 1)


def machine() -> dict[str, Any]:
    """What a result says it came from: ``cpu``, the CPU's model name (`stamlane.training.hardware.cpu_name`, what a
    run record says too), and ``cores``. A script that times on a shared machine adds the load (`load_1min`) at the
    start and the end.

    It imports torch: a script that times code without torch calls it after its timings.
    """
    from stamlane.training.hardware import cpu_name

    return {"cpu": cpu_name(), "cores": os.cpu_count()}


# --- side-by-side timing ---------------------------------------------------------------------------------------


def timed(run: Callable[[], T]) -> tuple[float, T]:
    """``run()``'s wall time in seconds (``time.perf_counter``) and its value."""
    start = time.perf_counter()
    value = run()
    return time.perf_counter() - start, value


def in_turn(
    measure: Callable[[str, int], float], variants: Sequence[str], repeats: int, *, alternate: bool = False
) -> dict[str, list[float]]:
    """Every variant measured ``repeats`` times, the variants taking turns (repeat 0 of each, then repeat 1, ..) so
    that the load of a shared machine falls on all of them alike; ``measure(variant, repeat)`` returns one timing.
    With ``alternate`` every other repeat runs them in reverse order (ABBA: a load that rises or falls evens out).

    Returns:
        each variant's timings in the order measured.
    """
    times: dict[str, list[float]] = {v: [] for v in variants}
    for r in range(repeats):
        for variant in reversed(variants) if alternate and r % 2 else variants:
            times[variant].append(measure(variant, r))
    return times


def medians(times: Mapping[str, Sequence[float]]) -> dict[str, float]:
    """The median of each variant's timings."""
    return {k: statistics.median(v) for k, v in times.items()}


def ratio(times: Mapping[str, Sequence[float]], slow: str, fast: str, digits: int | None = 3) -> float:
    """How many times ``fast`` is faster than ``slow``: the ratio of their medians, rounded to ``digits`` (None: not
    rounded)."""
    med = medians({k: times[k] for k in (slow, fast)})
    value = med[slow] / med[fast]
    return value if digits is None else round(value, digits)
