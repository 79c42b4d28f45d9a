"""Where an experiment keeps its runs, and the one way a run is declared finished.

A run (one model, one seed) is finished when its folder holds ``done.json``, written last and atomically, with
the settings it was made with and the SHA-256 of its final checkpoint. `finished` is the resume lock: a record
made with other settings is refused (another ``--out`` is needed), a record that does not parse, names files
outside the experiment's folder or whose checkpoint no longer matches its digest (a tampered or half-copied
folder) is refused too, each with one line (`StoreError`).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stamlane.safety.budget import MAX_RECORD_BYTES
from stamlane.safety.guard import GuardError, read_inside, write_atomic  # the one atomic writer, re-exported here

__all__ = ["DONE", "StoreError", "file_sha256", "finished", "mark_finished", "write_atomic"]

DONE = "done.json"


class StoreError(Exception):
    """A run folder that cannot be used: printed as one line, exit status 2."""


def file_sha256(path: Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


RECORD_TYPES: dict[str, tuple[type, ...]] = {
    "run": (str,),
    "last_ckpt": (str,),
    "frames": (int,),
    "seed": (int,),
    "train_minutes": (int, float),
    "pretrain_minutes": (int, float),
    "scores": (dict,),
    "labels": (dict,),
    "last_ckpt_sha256": (str,),
}
"""The type of each value of a run record that is read back (a tampered record is refused, not half used)."""
OPTIONAL = ("pretrain_minutes", "scores", "labels", "last_ckpt_sha256")
"""Values a finished record may lack: written later, only by two-stage recipes, or by older versions."""


def _inside(path: str, top: Path) -> bool:
    try:
        Path(path).resolve().relative_to(top.resolve())
    except ValueError:
        return False
    return True


def finished(
    folder: Path,
    settings: dict[str, Any],
    top: Path,
    upgrade: Callable[[dict[str, Any]], dict[str, Any]] | None = None,
) -> dict[str, Any] | None:
    """The record of a finished run in ``folder``, or None when it has not finished.

    Args:
        folder: the run's folder.
        settings: what every run of the experiment shares (data, steps, precision, ...); the record must hold
            the same values.
        top: the experiment's folder: every path the record names must lie inside it.
        upgrade: how a record written by an older stamlane reads today, applied before anything is compared
            (the record returned is the upgraded one).

    Raises:
        StoreError: the record does not parse, was made with other settings, names a path outside ``top``, or
            its checkpoint is missing or differs from the digest it recorded.
    """
    path = folder / DONE
    if not path.is_file():
        return None
    if not _inside(str(folder), top):  # a run folder linked from elsewhere: its record is not read
        raise StoreError(f"{folder} leads outside {top} (a link?); delete it to run it again")
    try:  # only inside the run's folder: a done.json that links elsewhere is never read
        record = json.loads(read_inside(path, folder, MAX_RECORD_BYTES, "run record"))
    except GuardError as err:
        raise StoreError(f"{err}; delete the folder to run it again") from None
    except (RecursionError, json.JSONDecodeError) as err:
        raise StoreError(f"{path} is not a run record ({err}); delete the folder to run it again") from None
    if not isinstance(record, dict):
        raise StoreError(f"{path} is not a run record (a JSON object); delete the folder to run it again")
    if upgrade is not None:
        record = upgrade(record)
    if {k: record.get(k) for k in settings} != settings:
        theirs = {k: record.get(k) for k in settings}
        raise StoreError(f"{folder} was made with other settings ({theirs}); use another --out")
    for key in ("run", "last_ckpt"):
        value = record.get(key)
        if value is not None and (not isinstance(value, str) or not _inside(value, top)):
            raise StoreError(f"{path}: {key} {value!r} is not a path inside {top}; delete the folder to run it again")
    for key, types in RECORD_TYPES.items():  # frames: null was a TypeError far from the file
        value = record.get(key)
        if value is None and key in OPTIONAL:
            continue
        if isinstance(value, types) and not isinstance(value, bool) and (key != "frames" or value >= 1):
            continue
        wanted = " or ".join(t.__name__ for t in types) + (" >= 1" if key == "frames" else "")
        raise StoreError(f"{path}: {key} must be {wanted}, got {value!r:.60}; delete the folder to run it again")
    ckpt, digest = record.get("last_ckpt"), record.get("last_ckpt_sha256")
    if ckpt is not None:
        if not Path(ckpt).is_file():
            raise StoreError(f"{path}: its checkpoint {ckpt} is missing; delete the folder to run it again")
        if digest is not None and file_sha256(Path(ckpt)) != digest:
            raise StoreError(f"{path}: its checkpoint {ckpt} changed since the run finished; delete the folder")
    return record


def mark_finished(folder: Path, record: dict[str, Any]) -> None:
    """Write ``record`` as the run's ``done.json`` (with its checkpoint's digest when it names one)."""
    if record.get("last_ckpt") and "last_ckpt_sha256" not in record:
        record["last_ckpt_sha256"] = file_sha256(Path(record["last_ckpt"]))
    write_atomic(folder / DONE, json.dumps(record, indent=2))
