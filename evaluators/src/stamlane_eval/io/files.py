"""Files in and out, safely: what every reader and writer of `stamlane_eval.io` shares.

- `read_text` reads a regular file of bounded size (a FIFO, a device or a folder is refused unread); `read_file`
  the same, with a missing file as a `LaneFileError`;
- `inside` / `Inside`: THE check that a path, links resolved, lies in a root folder (a link in a prediction or
  annotation folder never makes the evaluator read a file elsewhere);
- `write_atomic` / `write_jsonl`: THE atomic writer (a temporary file of a unique name beside the output, renamed
  over it);
- the JSON values of every format: `is_json_number`, `json_float`, and `gc_paused` for parsing fast.
"""

from __future__ import annotations

import errno
import gc
import json
import math
import os
import posixpath
import stat
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from stamlane_eval.cli_tools import OutputError, check_outputs
from stamlane_eval.io.limits import MAX_FILE_BYTES

__all__ = [
    "Inside",
    "LaneFileError",
    "image_key",
    "inside",
    "name_problem",
    "path_problem",
    "read_text",
    "write_atomic",
    "write_jsonl",
]
# read_file, is_json_number, json_float and gc_paused serve the readers of this package


class LaneFileError(ValueError):
    """An input file that cannot be evaluated; the message names the file and the problem."""


def read_text(path: str | os.PathLike[str], limit: int = MAX_FILE_BYTES, universal_newlines: bool = True) -> str:
    """The text of a regular file of at most ``limit`` bytes; with ``universal_newlines`` "\\r\\n" and "\\r" read
    as "\\n", as ``open(path).read()`` (lane.py's reading).

    A FIFO, a device (``/dev/zero``), a socket or a directory is refused at once, never read: reading one would
    wait for a writer or never end.

    Raises:
        FileNotFoundError: no such file (callers that treat a missing file as empty catch it).
        LaneFileError: anything else that cannot be read: not a regular file, larger than ``limit``, not UTF-8.
    """
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK)  # O_NONBLOCK: a FIFO opens without waiting for a writer
    except FileNotFoundError:
        raise
    except OSError as e:
        raise LaneFileError(f"{p}: cannot read: {e.strerror}") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = "a directory" if stat.S_ISDIR(mode) else "a FIFO, device or socket"
            raise LaneFileError(f"{p}: cannot read: {kind}, not a regular file")
        chunks, size = [], 0
        while size <= limit:  # os.read, not a file object: faster on many small files
            chunk = os.read(fd, min(limit + 1 - size, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        data = b"".join(chunks)
    finally:
        os.close(fd)
    if len(data) > limit:
        raise LaneFileError(f"{p}: larger than the limit of {limit >> 20} MiB")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise LaneFileError(f"{p}: cannot read: not UTF-8 text ({e.reason} at byte {e.start})") from None
    if universal_newlines and "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text


def read_file(path: str | os.PathLike[str]) -> str:
    """`read_text`, a missing file included among the errors.

    Raises:
        LaneFileError: naming the file and the problem.
    """
    try:
        return read_text(path)
    except FileNotFoundError as e:
        raise LaneFileError(f"{path}: cannot read: {e.strerror}") from None


NAME_MAX = 255
"""Bytes of one path component the file systems take."""
PATH_MAX = 4096
"""Bytes of a whole path the kernel takes."""


def name_problem(raw: bytes) -> str | None:
    """Why the name ``raw`` (a path's bytes) can be no file's name — a NUL byte, bytes that are not UTF-8 (names are
    written into UTF-8 files), a component over `NAME_MAX` bytes, over `PATH_MAX` in all — or None; looks at nothing
    on disk."""
    if b"\x00" in raw:
        return "holds a NUL byte"
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError:
        return "is not UTF-8: rename it"
    longest = max((len(part) for part in raw.split(b"/")), default=0)
    if longest > NAME_MAX:
        return f"has a name of {longest} bytes, over the file system's limit of {NAME_MAX}"
    if len(raw) > PATH_MAX:
        return f"is {len(raw)} bytes long, over the file system's limit of {PATH_MAX}"
    return None


def path_problem(arg: str) -> str | None:
    """Why ``arg`` can be no usable path in any reading — a NUL byte, bytes that are not UTF-8, a component over
    `NAME_MAX` bytes, over `PATH_MAX` in all, a loop of links — or None. Never raises (``Path.exists()`` raises
    ``OSError: File name too long`` on Python 3.11, ``RuntimeError`` for a loop in ``Path.resolve()``)."""
    try:
        raw = os.fsencode(arg)
    except (TypeError, ValueError):
        return "is no path"
    problem = name_problem(raw)
    if problem:
        return problem
    try:
        os.stat(raw)
    except OSError as e:
        if e.errno == errno.ELOOP:
            return "is a loop of links"
        if e.errno == errno.ENAMETOOLONG:
            return "has a name too long for the file system"
    return None


def image_key(name: str) -> str:
    """THE key of an image or frame a record or list names: its path POSIX-normalised once (``//`` and ``.``
    segments dropped, ``a/..`` collapsed, as the file system resolves the name), so that ``s1/./2.jpg`` and
    ``s1/2.jpg`` are one image (found twice: refused as a duplicate, as the same name twice is). A leading ``/``
    and leading ``..`` segments are kept; names are compared as written otherwise (case included: the file
    systems the benchmarks ship on are case-sensitive)."""
    if "//" not in name and "/." not in name and not name.startswith("./") and name != ".":
        return name  # the common case, a plain a/b/c.jpg: already normal (a few hundred ns saved per record)
    return posixpath.normpath(name)


def inside(path: Path, root: Path) -> Path:
    """``path`` after checking that, symlinks resolved, it lies in ``root``: a link in a prediction or annotation
    folder never makes the evaluator read (and quote in an error) a file elsewhere (`Inside`, for one file).

    Raises:
        LaneFileError: naming the link and where it leads.
    """
    return Inside(root)(path)


class Inside:
    """THE check of a path inside a root folder, for many files under one ``root``: the root and each folder
    resolved once (a file that is not a link resolves to its resolved folder + its name), the file itself checked
    with one ``lstat``.

    Raises:
        LaneFileError: (when called) naming the link and where it leads.
    """

    def __init__(self, root: Path) -> None:
        self.root = root
        self.real_root = root.resolve()
        self.folders: dict[Path, Path] = {}

    def __call__(self, path: Path) -> Path:
        name = path.name
        if name in ("", ".", "..") or os.path.islink(path):
            real = path.resolve()
        else:
            folder = self.folders.get(path.parent)
            if folder is None:
                folder = self.folders[path.parent] = path.parent.resolve()
            real = folder / name
        if not real.is_relative_to(self.real_root):
            raise LaneFileError(f"{path}: a link to {real}, outside the folder {self.root}")
        return path


def write_atomic(path: Path, text: str, inputs: Iterable[str | Path | None] = ()) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically: a temporary file of a unique name beside ``path`` (created,
    so never an existing file; checked against ``inputs`` as the output was), then renamed over it. A reader sees
    the old file or the whole new one; a failed write leaves no temporary file.

    Raises:
        LaneFileError: the file cannot be written (naming it and why).
        OutputError: the temporary file would be one of ``inputs``.
    """
    try:  # a FIFO, a device or a socket where the file goes is never replaced (as root: /dev/zero itself)
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        mode = stat.S_IFREG
    except (OSError, ValueError) as e:
        raise LaneFileError(f"{path}: cannot write: {e}") from None
    if not (stat.S_ISREG(mode) or stat.S_ISLNK(mode)):
        raise LaneFileError(f"{path}: cannot write: a FIFO, device, socket or folder, not a file")
    try:
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as e:
        raise LaneFileError(f"{path}: cannot write: {e.strerror}") from None
    tmp = Path(name)
    try:
        check_outputs([tmp], inputs, files=True)
        with open(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)  # the file this call created, nothing else
        raise LaneFileError(f"{path}: cannot write: {e}") from None
    except OutputError:
        os.close(fd)
        tmp.unlink(missing_ok=True)
        raise


def write_jsonl(path: Path, records: Sequence[object], inputs: Iterable[str | Path | None] = ()) -> None:
    """Write json-lines (one ``json.dumps`` per record) atomically (`write_atomic`)."""
    write_atomic(path, "".join(json.dumps(rec) + "\n" for rec in records), inputs)


# ---------------------------------------------------------------------------------------------- JSON values
def is_json_number(v: object) -> bool:
    """A JSON number: ``int`` or ``float``, never ``bool`` (a subclass of int) nor a string."""
    return type(v) is int or type(v) is float


def json_float(v: int | float) -> float:
    """A JSON number as float64; an integer beyond the float range becomes +-inf (lane.py compares the exact
    integer: the same outcome, a miss or an absent row)."""
    try:
        return float(v)
    except OverflowError:
        return math.inf if v > 0 else -math.inf


@contextmanager
def gc_paused() -> Iterator[None]:
    """The cyclic garbage collector off while JSON builds its (acyclic) lists: it would walk them again and again
    as they pile up, a third of the time of reading a TuSimple file."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
