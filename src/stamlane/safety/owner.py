"""Output folders that belong to one source: a folder a command writes into holds what one source made, never files
of two beside each other.

A command that writes a folder of results (``predict``, ``stream``, ``export --streaming``, ``synth``) claims it
first with `claim`: a missing or empty folder is its own; so is a folder whose owner file (`OWNER_NAME`, written by
`mark` when the command starts writing) names the same command and source (a run again replaces its files). Any
other folder — another source's results, files stamlane did not write — is not written into: a folder stamlane
chose itself (``outputs/predict/<model>/<source>``) gives way to the next free one (``clip-2``, ``clip-3``); a folder
the user named is refused in one line naming the flag (one without an owner file only by ``synth``, which writes into
nothing but an empty folder or its own: an older stamlane's results carry none).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

from stamlane.safety.guard import LOCK_NAME, GuardError, make_folder, read_inside, write_atomic

__all__ = ["MAX_SIBLINGS", "OWNER_NAME", "claim", "mark", "owner_of"]

OWNER_NAME = ".stamlane-owner.json"
"""The owner file of an output folder: the command and the source whose results it holds, and the run that wrote
them last."""
MAX_SIBLINGS = 1000
"""Folders tried for a source whose name is taken (``clip-2`` ... ``clip-1000``)."""
_OURS = (OWNER_NAME, LOCK_NAME)


def owner_of(folder: str | os.PathLike[str]) -> dict[str, Any] | None:
    """What the owner file of ``folder`` says (None: none, or one that cannot be read as a mapping)."""
    path = Path(folder) / OWNER_NAME
    if not path.is_file():
        return None
    try:
        data = json.loads(read_inside(path, folder, 1 << 20, "owner file"))
    except (ValueError, RecursionError):
        return None
    return data if isinstance(data, dict) else None


def _is_ours(folder: Path, owner: dict[str, Any], strict: bool) -> str | None:
    """None when ``folder`` may be written for ``owner``; else what is in the way. A folder without an owner file
    that holds files is in the way when ``strict`` (always for a folder stamlane chose)."""
    try:
        if not folder.is_dir():  # missing, or no folder: the output guard says what is in the way
            return None
        names = sorted(p.name for p in folder.iterdir() if p.name not in _OURS)
        record = folder / OWNER_NAME
        if os.path.lexists(record) and not record.is_file():  # a folder, a FIFO, a dangling link: never replaced
            return f"holds an owner file {OWNER_NAME} that is no file (a folder, a link to nothing or a FIFO)"
    except OSError as err:
        return f"cannot be read ({err.strerror})"
    found = owner_of(folder)
    if found is not None:
        other = next((key for key, value in owner.items() if found.get(key) != value), None)
        if other is None:
            return None
        return f"holds the {found.get('command', '?')} output of another {other} ({found.get(other)})"
    if not names or not strict:
        return None
    return f"holds files stamlane did not write there ({names[0]}{', ...' if len(names) > 1 else ''})"


def claim(
    folder: str | os.PathLike[str], owner: dict[str, Any], flag: str, *, chosen: bool = False, strict: bool = False
) -> Path:
    """The folder to write ``owner``'s results into (nothing is written yet: `mark` does, when writing starts).

    Args:
        folder: the folder the command would write.
        owner: what the results are of: ``{"command": ..., "source": ...}`` (plain JSON values), compared with the
            owner file of an existing folder.
        flag: the option that names the folder, for the refusal.
        chosen: the command chose ``folder`` itself: a folder taken by another source gives way to the next free
            sibling (``NAME-2``, ``NAME-3``, ...) instead of a refusal; a folder without an owner file that holds
            files is taken too (an older stamlane's results, or anything else).
        strict: a folder the user named that holds files but no owner file is refused too (``synth --out``); else
            it is written into (what an older stamlane wrote there has no owner file).

    Raises:
        GuardError: ``folder`` holds another source's results or files stamlane did not write (and was named by
            the user), or no free sibling was found.
    """
    folder = Path(folder)
    problem = _is_ours(folder, owner, strict or chosen)
    if problem is None:
        return folder
    if not chosen:
        raise GuardError(
            f"{flag} {folder} {problem}: give another {flag} (an output folder holds one source's results)"
        )
    for n in range(2, MAX_SIBLINGS + 1):
        sibling = folder.with_name(f"{folder.name}-{n}")
        if _is_ours(sibling, owner, True) is None:
            return sibling
    raise GuardError(f"{folder} and {MAX_SIBLINGS - 1} folders beside it hold other sources' results: give {flag}")


def mark(folder: str | os.PathLike[str], owner: dict[str, Any]) -> None:
    """Write ``folder``'s owner file (atomically): ``owner``, and this run (its start time and process id)."""
    folder = make_folder(folder)
    run = {"run": {"started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "pid": os.getpid()}}
    write_atomic(folder / OWNER_NAME, json.dumps(owner | run, indent=1) + "\n")
