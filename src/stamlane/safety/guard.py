"""The output guard of every ``stamlane`` command: what it writes never replaces or lands among what it reads.

A command names, before it writes anything, every path it will write (final names and the temporary names of
`atomic_path`) and every path it reads (inputs, checkpoints, configs, summaries, data roots); `check_outputs`
compares them with links resolved and refuses, in one line naming both paths:

- an output that IS an input (``stamlane report S --out S``, a checkpoint named like ``stream``'s output);
- an output inside an input's folder tree where the docs forbid it (a data root, a ``--source`` folder);
- an output under a file, a file output that is a folder (or a folder output that is a file), an output whose
  folder cannot be written.

Records of a run folder (``done.json``, ``run/config.yaml``) are read with `read_inside`: only when the file,
links resolved, lies inside that folder (`is_inside`, the one path-inside-root check, which the data's label and
list paths go through too). `atomic_path` / `write_atomic` are the one atomic writer (a temporary
name beside the output, then a rename); `exclusive` takes a folder's lock file, so that two runs never write one
folder at once.
"""

from __future__ import annotations

import errno
import hashlib
import os
import stat
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from stamlane_eval.io import read_text

__all__ = [
    "LOCK_NAME",
    "GuardError",
    "atomic_path",
    "check_outputs",
    "exclusive",
    "file_sha256",
    "is_inside",
    "make_folder",
    "read_input",
    "read_inside",
    "temporary_name",
    "write_atomic",
]

LOCK_NAME = ".stamlane.lock"
"""The lock file `exclusive` takes in an output folder."""

PathLike = str | os.PathLike[str]


class GuardError(ValueError):
    """An output that would replace or write into an input, or cannot be written: one line, exit status 2."""


def _resolved(path: PathLike) -> Path:
    return Path(path).expanduser().resolve()


def is_inside(path: PathLike, top: PathLike) -> bool:
    """Whether ``path`` is ``top`` or lies inside it, links resolved in both (``..`` and a link out of ``top`` lead
    outside): the one path-inside-root check of stamlane (a data root's label and list paths, a run folder's
    records, an output inside a protected input)."""
    path, top = Path(path).resolve(), Path(top).resolve()
    return path == top or path.is_relative_to(top)


def temporary_name(path: PathLike) -> Path:
    """The name `atomic_path` writes ``path`` under before renaming it: hidden, beside it, this process's and this
    thread's ids (two threads writing one entry of a cache never share a temporary file), the same suffix (image and
    video writers pick their format by it)."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}-{threading.get_native_id()}.tmp{path.suffix}")


def _existing_ancestor(path: Path) -> Path:
    for parent in (path, *path.parents):
        if os.path.lexists(parent):
            return parent
    return Path("/")


def _check_writable(out: PathLike, resolved: Path, folder: bool) -> None:
    if os.path.lexists(resolved):
        mode = os.stat(resolved).st_mode if resolved.exists() else 0
        if folder and not stat.S_ISDIR(mode):
            raise GuardError(f"{out} is a file, not a folder")
        if not folder and stat.S_ISDIR(mode):
            raise GuardError(f"{out} is a folder, not a file")
        if not folder and not stat.S_ISREG(mode):
            raise GuardError(f"{out} is a FIFO, device or socket, not a file to write")
    anchor = _existing_ancestor(resolved.parent if not folder else resolved)
    if not anchor.is_dir():
        raise GuardError(f"{out}: cannot write under {anchor}, a file, not a folder")
    if not os.access(anchor, os.W_OK | os.X_OK):
        raise GuardError(f"{out}: cannot write into {anchor} (permission denied)")
    try:
        read_only = bool(os.statvfs(anchor).f_flag & os.ST_RDONLY)  # root is not exempt from a read-only mount
    except OSError:  # a file system that cannot say: the write itself will (make_folder, one line)
        read_only = False
    if read_only:
        raise GuardError(f"{out}: cannot write into {anchor} (a read-only file system)")


def make_folder(path: PathLike, what: str = "output folder") -> Path:
    """Create the folder ``path`` (and its parents) where it is missing: the one ``mkdir`` of every command's
    outputs (`atomic_path`, `stamlane.safety.owner.mark`, a writer's folder), so that a folder that cannot be made
    (under a file, in a read-only or a permission-less place, a name the file system refuses) is one line naming
    it, never a traceback, whichever command and writer meets it.

    Raises:
        GuardError: the folder cannot be created (the OS's reason in words).
    """
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise GuardError(f"{what} {path} cannot be created: it, or a folder above it, is a file") from None
    except OSError as err:
        reason = err.strerror or type(err).__name__
        where = f" ({err.filename})" if err.filename and os.fspath(err.filename) != os.fspath(path) else ""
        raise GuardError(f"{what} {path} cannot be created: {reason}{where}") from None
    return path


def check_outputs(
    files: Iterable[PathLike | None] = (),
    reads: Iterable[PathLike | None] = (),
    *,
    folders: Iterable[PathLike | None] = (),
    protected: Iterable[PathLike | None] = (),
) -> None:
    """Refuse, before anything is written, an output that would replace an input or land inside a protected one.

    Args:
        files: every file the command writes, final and temporary names (`temporary_name`).
        reads: every path it reads; no output may be one of them (links resolved).
        folders: output folders it creates and writes into: each must be a folder or missing, and writable.
        protected: inputs whose whole folder tree is off limits (data roots, ``--source``, a config file):
            no output may be one of them or lie inside them.

    Raises:
        GuardError: one line naming the output and the input (or the reason it cannot be written).
    """
    ins = [(p, _resolved(p)) for p in reads if p is not None]
    trees = [(p, _resolved(p)) for p in protected if p is not None]
    outs = [(p, True) for p in folders if p is not None] + [(p, False) for p in files if p is not None]
    for out, folder in outs:
        target = _resolved(out)
        for given, source in ins:
            if target == source:
                raise GuardError(f"{out}: the output would overwrite or write into the input {given}")
        for given, source in trees:
            if is_inside(target, source):
                raise GuardError(f"{out}: the output would overwrite or write into the input {given}")
        _check_writable(out, target, folder)


def read_input(path: PathLike, limit: int, what: str = "input") -> str:
    """The text of a regular file of at most ``limit`` bytes, never blocking on a FIFO nor reading a device.

    Raises:
        GuardError: missing, not a regular file, larger than ``limit`` or not UTF-8.
    """
    try:
        return read_text(path, limit=limit, universal_newlines=False)
    except FileNotFoundError:
        raise GuardError(f"{what} {path} does not exist") from None
    except (OSError, ValueError) as err:
        raise GuardError(f"{what} {err}") from None


def read_inside(path: PathLike, top: PathLike, limit: int, what: str = "record") -> str:
    """The text of a record of a run folder, read only when ``path`` (links resolved) lies inside ``top``.

    Raises:
        GuardError: outside ``top`` (a link out of the folder: its target is never read), or unreadable as in
            `read_input`.
    """
    if not is_inside(_resolved(path), _resolved(top)):
        raise GuardError(f"{what} {path} leads outside {top} (a link?); it is not read")
    return read_input(path, limit, what)


@contextmanager
def atomic_path(path: PathLike) -> Iterator[Path]:
    """A temporary name to write ``path`` under (`temporary_name`), renamed over ``path`` when the block ends
    without an error, removed when it fails: a reader never sees half a file, an interrupted write leaves the old
    one. A block that writes nothing at the temporary name leaves ``path`` as it was."""
    path = Path(path)
    make_folder(path.parent, f"the folder of {path}")
    tmp = temporary_name(path)
    try:
        yield tmp
        if os.path.lexists(tmp):
            os.replace(tmp, path)
    finally:
        if os.path.lexists(tmp):
            tmp.unlink()


def write_atomic(path: PathLike, text: str) -> None:
    """Write ``text`` to ``path`` through `atomic_path`."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


@contextmanager
def exclusive(folder: PathLike, what: str = "--out") -> Iterator[None]:
    """Hold ``folder``'s lock file (`LOCK_NAME`) while the block runs; a second holder is refused at once. The lock
    goes with the process (a killed run leaves no stale lock).

    Raises:
        GuardError: another process holds the lock.
    """
    import fcntl

    lock = Path(folder) / LOCK_NAME
    try:
        fd = os.open(lock, os.O_CREAT | os.O_RDWR | os.O_NOFOLLOW, 0o644)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise GuardError(f"{what} {folder}: its lock file {lock} is a link; remove it") from None
        raise
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise GuardError(
                f"{what} {folder} is in use by another stamlane run (lock {lock}); wait for it or give another one"
            ) from None
        yield
    finally:
        os.close(fd)


def file_sha256(path: PathLike) -> str:
    """SHA-256 of a file's bytes, hexadecimal, read in 1 MiB blocks (a checkpoint's, a label file's)."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
