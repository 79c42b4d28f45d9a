"""What every command line of stamlane and stamlane-eval shares: one-line errors, outputs that spare the inputs.

Torch-free, so ``stamlane-eval`` keeps its light imports; ``stamlane``'s commands import it from here (the
dependency runs from ``stamlane`` to ``stamlane_eval``, never back).
"""

from __future__ import annotations

import argparse
import os
import stat
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import NoReturn

__all__ = [
    "InputError",
    "OneLineParser",
    "OutputError",
    "check_input_file",
    "check_output",
    "check_outputs",
    "format_wxh",
    "parse_or_status",
    "parse_wxh",
]


class OneLineParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line on stderr and exit status 2 (no usage dump)."""

    def error(self, message: str) -> NoReturn:
        print(f"{self.prog}: {message} (see --help)", file=sys.stderr)
        raise SystemExit(2)


def parse_or_status(parser: argparse.ArgumentParser, argv: list[str] | None) -> argparse.Namespace | int:
    """Parsed arguments, or the exit status when parsing ended (``--help`` / ``--version``: 0, bad input: 2)."""
    try:
        return parser.parse_args(argv)
    except SystemExit as stop:
        return int(stop.code or 0)


def parse_wxh(text: str, max_side: int | None = None) -> tuple[int, int]:
    """An image size as people type it, ``WxH`` (``1640x590``), as the code holds it: ``(H, W)``, like torch.

    Raises:
        argparse.ArgumentTypeError: not two positive integers joined by ``x``, or a side over ``max_side``.
    """
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WxH such as 640x360, got {text!r}") from None
    if w <= 0 or h <= 0 or (max_side is not None and max(w, h) > max_side):
        sides = f"sides in 1..{max_side}" if max_side is not None else "positive sides"
        raise argparse.ArgumentTypeError(f"expected WxH with {sides}, got {text!r}")
    return h, w


def format_wxh(size: tuple[int, int]) -> str:
    """An ``(H, W)`` size written for people: ``"WxH"``."""
    return f"{size[1]}x{size[0]}"


class OutputError(ValueError):
    """An output path that would overwrite or write into an input."""


def check_output(path: str | Path, inputs: Iterable[str | Path | None]) -> None:
    """`check_outputs` for one output."""
    check_outputs([path], inputs)


def check_outputs(
    outputs: Iterable[str | Path | None], inputs: Iterable[str | Path | None], *, files: bool = False
) -> None:
    """THE output guard, run before anything is written: refuse an output that IS one of the inputs (the same
    path, symlinks resolved, or the same file under another name), lies inside an input folder, or is another
    output too. Temporary names are checked the same way by whoever makes them (unique names, made in the
    output's folder: never an existing file).

    Args:
        outputs: every path the command will write (None: not written).
        inputs: every path it reads: files and folders (None: not given).
        files: the outputs are files: an existing folder is refused too.

    Raises:
        OutputError: naming the output and the input it would clobber.
    """
    sources = [(source, Path(source).resolve()) for source in inputs if source is not None]
    seen: dict[Path, str | Path] = {}
    for path in outputs:
        if path is None:
            continue
        target = Path(path).resolve()
        for source, src in sources:
            if target == src or (src.is_dir() and target.is_relative_to(src)) or _same_file(target, src):
                raise OutputError(f"{path}: the output would overwrite or write into the input {source}")
        if files and target.is_dir():
            raise OutputError(f"{path}: is a folder; the output is a file")
        if files and _is_special(target):  # renaming over it would replace a device node (as root: /dev/zero)
            raise OutputError(f"{path}: is a FIFO, device or socket, not a file to write")
        if target in seen:
            raise OutputError(f"{path}: the same path as the output {seen[target]}")
        seen[target] = path


def _is_special(path: Path) -> bool:
    """Whether ``path`` exists and is a FIFO, a device or a socket (links followed); False when it cannot be
    looked at."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def _same_file(a: Path, b: Path) -> bool:
    """Whether two existing paths are one file (a hard link, a bind mount); False when either is missing."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


class InputError(ValueError):
    """An input path that cannot be read as a file: missing, a directory, a FIFO, a device or a socket."""


def check_input_file(path: str | os.PathLike[str], what: str = "input") -> None:
    """Refuse an input that is not a regular file (symlinks followed), without reading it: a FIFO would block
    the reader until something writes to it, a device such as ``/dev/zero`` never ends.

    Raises:
        InputError: naming the path and what it is.
    """
    try:
        mode = os.stat(path).st_mode
    except OSError as e:
        raise InputError(f"{what} {path}: {e.strerror}") from None
    if not stat.S_ISREG(mode):
        kind = "a directory" if stat.S_ISDIR(mode) else "a FIFO, device or socket"
        raise InputError(f"{what} {path} is {kind}, not a regular file")
