"""What the benchmark scripts share about their inputs and outputs: stamlane's contract for a command (one line on
stderr naming the file or option and the problem, exit status 2, nothing written), through stamlane's own guards
(`stamlane.safety.guard`: the output checks, bounded reading, the atomic writer).

A script imports it after putting its folder on ``sys.path`` (``python benchmarks/x.py`` does; a test loading the
script by its path does too, through the script's own line)::

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from _harness import BenchInputError, check_out_file, fail, read_json_object
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path, PurePosixPath

from stamlane.safety.guard import GuardError, check_outputs, read_input, temporary_name

__all__ = [
    "MAX_JSON_BYTES",
    "BenchInputError",
    "check_out_file",
    "check_out_folder",
    "clips_of",
    "fail",
    "guard_out",
    "read_json_object",
]

MAX_JSON_BYTES = 64 << 20
"""Largest JSON file a benchmark reads back (its own results, a run's file): 64 MiB."""


class BenchInputError(ValueError):
    """A benchmark's input or option that cannot be used: one line, exit status 2."""


def fail(prog: str, err: object) -> int:
    """Print ``prog: error: err`` as one line on stderr; returns 2, the exit status of a bad input."""
    line = " ".join(str(err).split())  # one line whatever the message held
    print(f"{prog}: error: {line}", file=sys.stderr)
    return 2


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
