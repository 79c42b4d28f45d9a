"""The path gate: what a path a command receives IS, answered without raising, before anything opens it.

Every path a ``stamlane`` command takes from a user (a flag, a fit argument after ``--``, a config value, a file a
checkpoint names) is looked at once by `inspect_path`, which never raises: ``Path.exists()`` raises ``OSError: File
name too long`` on Python 3.11 for a name over the file system's limit, ``os.stat`` a ``ValueError`` for a NUL
byte; here both are answers. `require` turns the answer into the one-line refusal of a command (`PathError`, a
``ValueError``: exit status 2): a path that is missing, of the wrong kind (a FIFO would block the reader, a device
such as ``/dev/zero`` never ends), larger than the reader's limit, outside the root it must lie in, or whose name
cannot be used (too long, a NUL byte, bytes that are not UTF-8: the name could not be written into a UTF-8
output).

`check_arguments` is the door of every command (``stamlane.cli.main`` runs it on every argument before a command
starts): an argument that names no usable path in any reading (a component over 255 bytes, a NUL byte, bytes that
are not UTF-8, a loop of links) is refused in one line, whichever option it was given to. `check_command_files` is
the early check of a LightningCLI command line (``stamlane fit|validate|test|predict``
and the fit arguments ``stamlane demo`` / ``ablate`` take after ``--``): every ``--config``, ``--ckpt_path`` and
``--source`` through `require`, a config at most `MAX_CONFIG_BYTES`. `check_config_paths` is the same check for
the path-valued options of a parsed config (`CONFIG_PATHS`: ``data.root``, ``model.init_weights``, ...), whether
they came from a flag, a ``--config`` file or the config a checkpoint carries.
"""

from __future__ import annotations

import errno
import os
import stat
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stamlane_eval.io.files import NAME_MAX, PATH_MAX, name_problem

__all__ = [
    "CKPT_NAMES",
    "CONFIG_PATHS",
    "KINDS",
    "MAX_CONFIG_BYTES",
    "NAME_MAX",
    "PATH_MAX",
    "PathError",
    "PathInfo",
    "check_arguments",
    "check_command_files",
    "check_config_paths",
    "inspect_path",
    "require",
    "shown",
]

MAX_CONFIG_BYTES = 16 << 20
"""Largest config file read (16 MiB; the paper's table configs take a few KiB), wherever it is given."""
KINDS = ("file", "folder", "fifo", "device", "socket", "missing", "unusable")
"""What `inspect_path` answers: a path is one of these (links followed; `PathInfo.link` says it was one)."""
CKPT_NAMES = ("last", "best", "hpc", "registry", "null", "None")
"""``--ckpt_path`` values that are no file (Lightning's names, and "none")."""

PathLike = str | os.PathLike[str]


class PathError(ValueError):
    """A path a command cannot use: one line naming it and why; exit status 2."""


@dataclass(frozen=True)
class PathInfo:
    """What a path is.

    Attributes:
        path: the path as given.
        kind: one of `KINDS`: ``unusable`` when the name itself cannot be used (``problem`` says why).
        size: bytes of a file (of a sparse one: its apparent size), else None.
        link: the path itself is a symbolic link (``kind`` is its target's; ``missing`` for a dangling one).
        root: the first of the roots given that the path lies in, links resolved; None when in none.
        problem: why the name cannot be used (too long, a NUL byte, not UTF-8, unreadable folder), else None.
    """

    path: str
    kind: str
    size: int | None = None
    link: bool = False
    root: Path | None = None
    problem: str | None = None

    @property
    def exists(self) -> bool:
        return self.kind not in ("missing", "unusable")

    @property
    def shown(self) -> str:
        return shown(self.path)


def shown(path: PathLike | bytes) -> str:
    """A path as one printable line: bytes that are not UTF-8 as ``\\xNN``, control characters escaped, at most
    300 characters (the middle of a longer one left out)."""
    raw = os.fsencode(path)
    text = raw.decode("utf-8", "backslashreplace")
    text = "".join(c if c.isprintable() else ascii(c)[1:-1] for c in text)
    return text if len(text) <= 300 else f"{text[:150]}…{text[-150:]} ({len(text)} characters)"


def _kind(mode: int) -> str:
    if stat.S_ISREG(mode):
        return "file"
    if stat.S_ISDIR(mode):
        return "folder"
    if stat.S_ISFIFO(mode):
        return "fifo"
    if stat.S_ISSOCK(mode):
        return "socket"
    return "device"


def inspect_path(path: PathLike | bytes, roots: Iterable[PathLike] = ()) -> PathInfo:
    """What ``path`` is, never raising: its kind (links followed), size, whether it is a link, which of ``roots``
    it lies in (links resolved) and why its name cannot be used, if it cannot."""
    try:
        raw = os.fsencode(path)
        given = os.fsdecode(raw)
    except (TypeError, ValueError) as err:
        return PathInfo(str(path), "unusable", problem=f"is no path ({err})")
    problem = name_problem(raw)
    if problem is not None:
        return PathInfo(given, "unusable", problem=problem)
    try:
        link = stat.S_ISLNK(os.lstat(raw).st_mode)
    except FileNotFoundError:
        return PathInfo(given, "missing")
    except OSError as err:
        return _os_problem(given, err, False)
    try:
        info = os.stat(raw)
    except FileNotFoundError:
        return PathInfo(given, "missing", link=link)  # a dangling link
    except OSError as err:
        return _os_problem(given, err, link)
    kind = _kind(info.st_mode)
    root = None
    for top in roots:
        try:
            real, real_top = Path(os.path.realpath(given)), Path(os.path.realpath(top))
        except (OSError, ValueError):
            continue
        if real == real_top or real.is_relative_to(real_top):
            root = Path(top)
            break
    return PathInfo(given, kind, info.st_size if kind == "file" else None, link, root)


def _os_problem(given: str, err: OSError, link: bool) -> PathInfo:
    if err.errno == errno.ENOTDIR:
        return PathInfo(given, "missing", link=link)  # under a file: nothing can be there
    problems: dict[int | None, str] = {
        errno.ENAMETOOLONG: "has a name too long for the file system",
        errno.ELOOP: "is a loop of links",
    }
    problem = problems.get(err.errno, f"cannot be looked at: {err.strerror}")
    return PathInfo(given, "unusable", link=link, problem=problem)


def require(
    path: PathLike | bytes,
    what: str,
    kinds: Sequence[str] = ("file",),
    *,
    limit: int | None = None,
    roots: Sequence[PathLike] = (),
    missing_ok: bool = False,
) -> PathInfo:
    """`inspect_path`, with a refusal in one line for what the reader cannot take.

    Args:
        path: the path given.
        what: what it is, for the message (``--config``, ``config``, ``video``).
        kinds: the kinds the reader takes (``("file",)``, ``("file", "folder")``).
        limit: the largest size of a file, in bytes.
        roots: when given, the path must lie in one of them (links resolved).
        missing_ok: a missing path is answered, not refused.

    Raises:
        PathError: the name cannot be used, the path is missing, of another kind, over ``limit`` or outside
            ``roots``.
    """
    info = inspect_path(path, roots)
    if info.problem is not None and info.kind == "unusable":
        raise PathError(f"{what} {info.shown} {info.problem}")
    if info.kind == "missing":
        if missing_ok:
            return info
        raise PathError(f"{what} {info.shown} does not exist" + (" (a link to nothing)" if info.link else ""))
    if info.kind not in kinds:
        names = {"file": "a file", "folder": "a folder", "fifo": "a FIFO", "device": "a device", "socket": "a socket"}
        wanted = " or ".join(names[k] for k in kinds)
        raise PathError(f"{what} {info.shown} is {names[info.kind]}, not {wanted}")
    if limit is not None and info.size is not None and info.size > limit:
        raise PathError(f"{what} {info.shown} is {info.size:,} bytes, over the limit of {limit >> 20} MiB")
    if roots and info.root is None:
        raise PathError(f"{what} {info.shown} lies outside {', '.join(shown(r) for r in roots)} (links resolved)")
    return info


_FILE_OPTIONS = {"--config": ("file",), "-c": ("file",), "--ckpt_path": ("file",), "--source": ("file", "folder")}
"""The path options of a LightningCLI command line, with the kinds each takes."""


def command_files(args: Sequence[str]) -> list[tuple[str, str]]:
    """``(option, value)`` of every path option (`_FILE_OPTIONS`) in ``args`` (``--opt VALUE`` or ``--opt=VALUE``),
    in order."""
    found = []
    for i, arg in enumerate(args):
        option, eq, value = arg.partition("=")
        if option not in _FILE_OPTIONS:
            continue
        if not eq:
            if i + 1 >= len(args):
                continue
            value = args[i + 1]
        found.append(("--config" if option == "-c" else option, value))
    return found


def check_command_files(args: Sequence[str], *, missing_ok: bool = False) -> None:
    """Refuse, before jsonargparse or torch reads them, every ``--config``, ``--ckpt_path`` and ``--source`` of a
    LightningCLI command line that is not of the kind its reader takes: a config or checkpoint must be a file (a
    config at most `MAX_CONFIG_BYTES`), a source a file (a video) or a folder (of frames); a FIFO, a device, a name
    too long or not UTF-8 is refused without being opened. ``--ckpt_path`` names (`CKPT_NAMES`) are no files.

    Raises:
        PathError: one line naming the option, the path and the problem.
    """
    for option, value in command_files(args):
        if not value or (option == "--ckpt_path" and value in CKPT_NAMES):
            continue
        limit = MAX_CONFIG_BYTES if option == "--config" else None
        what = {"--config": "config", "--ckpt_path": "checkpoint", "--source": "--source"}[option]
        require(value, what, _FILE_OPTIONS[option], limit=limit, missing_ok=missing_ok)


def check_arguments(args: Sequence[str]) -> None:
    """Refuse, in one line, an argument (or the value of ``--option=VALUE``) that cannot be a usable path in any
    reading (`inspect_path` answers ``unusable``: a name too long, a NUL byte, bytes that are not UTF-8, a loop of
    links). Every other argument passes: what a path IS (a FIFO, a device, a folder) is for its reader's check; so
    does a YAML or JSON value (``[...]``, ``{...}``), however long.

    Raises:
        PathError: naming the argument and the problem.
    """
    for arg in args:
        value = arg.split("=", 1)[1] if arg.startswith("-") and "=" in arg else arg
        if value.lstrip().startswith(("[", "{")):  # a YAML / JSON value (a list of label files, callbacks): no path
            continue
        info = inspect_path(value)
        if info.kind == "unusable":
            raise PathError(f"argument {info.shown} {info.problem}")


CONFIG_PATHS: dict[str, tuple[str, ...]] = {
    "data.root": ("folder",),
    "data.label_dir": ("folder",),
    "data.clip.cache_dir": ("folder",),
    "model.init_weights": ("file",),
    "model.encoder.init_args.weights": ("file",),
    "predictions.output_dir": ("folder",),
    "trainer.default_root_dir": ("folder",),
    "ckpt_path": ("file",),
    "source": ("file", "folder"),
}
"""The path-valued options of a ``stamlane fit|validate|test|predict`` config (dotted keys), with the kinds each
takes."""


def _dotted(config: Any, key: str) -> object:
    """The value at the dotted ``key`` of a nested mapping (a dict, or jsonargparse's Namespace); None if absent."""
    for part in key.split("."):
        getter = getattr(config, "get", None)
        if not callable(getter):
            return None
        try:
            config = getter(part)
        except (KeyError, TypeError, AttributeError):
            return None
    return config


def check_config_paths(config: Any) -> None:
    """Refuse, in one line naming the key, a path-valued option of a parsed config (`CONFIG_PATHS`; a nested dict
    or jsonargparse's Namespace) that `require` refuses: a name too long, a NUL byte, bytes that are not UTF-8, a
    loop of links, or a path of the wrong kind (a FIFO or a device as ``model.init_weights``, a file as
    ``data.root``); each logger's ``save_dir`` as a folder. A missing path passes (its reader says so, or makes it); ``ckpt_path`` names (`CKPT_NAMES`)
    are no files.

    Raises:
        PathError: naming the key, the path and the problem.
    """
    for key, kinds in CONFIG_PATHS.items():
        value = _dotted(config, key)
        if not isinstance(value, (str, os.PathLike)) or not os.fspath(value):
            continue
        if key == "ckpt_path" and value in CKPT_NAMES:
            continue
        require(value, key, kinds, missing_ok=True)
    logger = _dotted(config, "trainer.logger")  # each logger's folder (one logger, or a list of them)
    for one in logger if isinstance(logger, list) else [logger]:
        value = _dotted(one, "init_args.save_dir")
        if isinstance(value, (str, os.PathLike)) and os.fspath(value):
            require(value, "trainer.logger.init_args.save_dir", ("folder",), missing_ok=True)
