"""What every command line of stamlane and stamlane-eval shares: one-line errors, outputs that spare the inputs.

Torch-free, so ``stamlane-eval`` keeps its light imports; ``stamlane``'s commands import it from here (the
dependency runs from ``stamlane`` to ``stamlane_eval``, never back).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import NoReturn

__all__ = ["OneLineParser", "OutputError", "check_output", "parse_or_status"]


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


class OutputError(ValueError):
    """An output path that would overwrite or write into an input."""


def check_output(path: str | Path, inputs: Iterable[str | Path | None]) -> None:
    """Refuse an output that IS one of the inputs or lies inside an input folder (symlinks resolved).

    Raises:
        OutputError: naming the output and the input it would clobber.
    """
    target = Path(path).resolve()
    for source in inputs:
        if source is None:
            continue
        src = Path(source).resolve()
        if target == src or (src.is_dir() and target.is_relative_to(src)):
            raise OutputError(f"{path}: the output would overwrite or write into the input {source}")
