"""The error boundary of a ``stamlane`` tool command: an expected failure is one line on stderr and exit status 2.

Expected failures are bad input in any library's words: an OS error (a missing, unreadable or unwritable file),
a ``ValueError`` (every stamlane input error derives from it: `stamlane.safety.guard.GuardError`,
`stamlane.safety.budget.BudgetError`, a data or checkpoint error), YAML and jsonargparse errors, a text that is not
UTF-8, a nesting too deep to parse, a worker process that died. Anything else is a bug and keeps its traceback
(exit status 1).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import TypeVar

__all__ = ["MAX_MESSAGE", "expected_errors", "one_line", "run_command"]

T = TypeVar("T")

MAX_MESSAGE = 400
"""Characters of an error message kept on its line: a library may quote a whole input in its message (jsonargparse
quotes a ``--config`` file that is no mapping), which a bad input must not turn into a page of stderr."""


def expected_errors(*extra: type[BaseException]) -> tuple[type[BaseException], ...]:
    """The exception classes a command reports as bad input: the common ones, those of the libraries already
    imported (YAML, jsonargparse, torch's unpickler), and ``extra``."""
    from concurrent.futures.process import BrokenProcessPool

    found: list[type[BaseException]] = [OSError, ValueError, RecursionError, BrokenProcessPool, *extra]
    yaml = sys.modules.get("yaml")
    if yaml is not None:
        found.append(yaml.YAMLError)
    jsonargparse = sys.modules.get("jsonargparse")
    if jsonargparse is not None:
        found.append(jsonargparse.ArgumentError)
    pickle = sys.modules.get("pickle")
    if pickle is not None:
        found.append(pickle.UnpicklingError)
    return tuple(found)


def one_line(err: BaseException) -> str:
    """An error's message on one line, at most `MAX_MESSAGE` characters of it. An error raised in a DataLoader
    worker comes back with the worker's traceback as its message ("Caught DataError in DataLoader worker process 0.
    Original Traceback ..."): its last line is the original message; other multi-line messages are joined."""
    lines = [line.strip() for line in str(err).splitlines() if line.strip()]
    if not lines:
        return type(err).__name__
    if "Original Traceback" in str(err):
        last = lines[-1]
        name, sep, message = last.partition(": ")
        return message if sep and name.replace(".", "").replace("_", "").isalnum() else last
    text = lines[0]
    for line in lines[1:]:  # a line ending in ":" introduces the next one (jsonargparse's nested messages)
        text += (" " if text.endswith(":") else "; ") + line
    if len(text) > MAX_MESSAGE:
        text = f"{text[:MAX_MESSAGE]} … ({len(text) - MAX_MESSAGE} characters more)"
    return text


def run_command(prog: str, body: Callable[[], T], *extra: type[BaseException]) -> T | int:
    """Run ``body``; an expected error (`expected_errors` and ``extra``) becomes one line ``"{prog}: {message}"``
    on stderr and the return value 2."""
    try:
        return body()
    except expected_errors(*extra) as err:
        print(f"{prog}: {one_line(err)}", file=sys.stderr)
        return 2
