"""The error boundary of a ``stamlane`` tool command: an expected failure is one line on stderr and exit status 2.

Expected failures are bad input in any library's words: an OS error (a missing, unreadable or unwritable file),
a ``ValueError`` (every stamlane input error derives from it: `stamlane.safety.guard.GuardError`,
`stamlane.safety.budget.BudgetError`, a data or checkpoint error), YAML and jsonargparse errors, a text that is not
UTF-8, a nesting too deep to parse, a worker process that died. Anything else is a bug and keeps its traceback
(exit status 1).
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

__all__ = ["MAX_MESSAGE", "expected_errors", "one_line", "peer_failure", "run_command", "share_failure"]

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


PEER_WAIT = 20.0
"""Seconds a process whose collective broke waits for the line of the process that stopped it."""
_PEER_WORDS = ("Connection closed by peer", "Connection reset by peer", "Broken pipe")
"""gloo's (and the socket's) words for a collective another process of the run left."""


def _failure_file() -> Path | None:
    """The file the processes of one several-process run (Lightning's ddp, torchrun: ``MASTER_ADDR`` and
    ``MASTER_PORT`` set) share a bad input's line through, in the machine's temporary folder; None in one process."""
    address, port = os.environ.get("MASTER_ADDR"), os.environ.get("MASTER_PORT")
    if not address or not port or os.environ.get("WORLD_SIZE") == "1":  # Lightning's ddp children lack WORLD_SIZE
        return None
    run = f"{address}:{port}:{os.environ.get('TORCHELASTIC_RUN_ID', '')}"
    return Path(tempfile.gettempdir()) / f"stamlane-failure-{hashlib.sha256(run.encode()).hexdigest()[:16]}.txt"


def share_failure(line: str) -> None:
    """Leave a bad input's line where the other processes of this run find it (`peer_failure`): the process that
    met it ends with it; the others, whose collectives break when it leaves, end with the same line, not gloo's
    traceback. Nothing in one process; the first line of a run is kept."""
    path = _failure_file()
    if path is None:
        return
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    except FileExistsError:
        if time.time() - path.stat().st_mtime < 60:  # this run's: the first line stays
            return
        path.unlink(missing_ok=True)  # an earlier run's on the same port
        return share_failure(line)
    except OSError:
        return  # no shared temporary folder: the other processes say their own error
    with os.fdopen(fd, "w") as file:
        file.write(line)


def peer_failure(err: BaseException, wait: float = PEER_WAIT) -> str | None:
    """The line another process of this run stopped with (`share_failure`), when ``err`` is a collective broken by
    that process leaving (gloo's "Connection closed by peer"); None for any other error, or when no line comes
    within ``wait`` seconds (the other process died of something else: ``err`` keeps its traceback)."""
    path = _failure_file()
    if path is None or not any(words in str(err) for words in _PEER_WORDS):
        return None
    deadline = time.monotonic() + wait
    while time.monotonic() < deadline:
        try:
            if time.time() - path.stat().st_mtime < 120:
                return path.read_text().strip() or None
        except OSError:
            pass
        time.sleep(0.2)
    return None
