"""Where stamlane keeps what it derives from a user's data: one folder of the user's, never the data itself.

``$STAMLANE_CACHE_DIR`` when it is set, else ``$XDG_CACHE_HOME/stamlane`` (an absolute ``XDG_CACHE_HOME``, as the
XDG base directory specification asks), else ``~/.cache/stamlane``. Each cache is a subfolder of it, named by
`cache_folder`: ``alignment/`` holds the frame-pair estimates of ``data.clip.align: fly``
(`stamlane.align.cache.PairCache`), keyed by the frames' content, so the same pair is one entry wherever its frames
lie. Everything in it can be deleted at any time (``rm -r``) and is estimated again on the next read.

A folder that cannot be made or written (a read-only home, a full disk) or that lies inside the data being read
is not written, said once per process in one line (`say_unwritable`); one that exists outside the data is still
read. Nothing fails for it: what the cache lacks is computed again.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from pathlib import Path

from stamlane.safety.guard import is_inside

__all__ = ["CACHE_ENV", "LOGGER", "cache_folder", "cache_home", "say_unwritable", "writable_folder"]

CACHE_ENV = "STAMLANE_CACHE_DIR"
"""The environment variable that names the cache home."""

LOGGER = logging.getLogger("stamlane.cache")
"""Where a cache that is not written is said (a warning; with no logging set up, one line on stderr)."""

_said: set[str] = set()  # the folders this process has already said it does not write


def cache_home(environ: Mapping[str, str] | None = None) -> Path | None:
    """The cache home (see the module docstring), or None when none can be named (no ``$HOME`` and no
    ``$STAMLANE_CACHE_DIR``)."""
    env = os.environ if environ is None else environ
    named = env.get(CACHE_ENV, "")
    if named:
        return Path(named).expanduser()
    xdg = env.get("XDG_CACHE_HOME", "")
    if xdg and Path(xdg).is_absolute():  # a relative one is to be ignored (XDG base directory specification)
        return Path(xdg) / "stamlane"
    try:
        return Path.home() / ".cache" / "stamlane"
    except RuntimeError:  # no home directory to be found
        return None


def cache_folder(name: str, environ: Mapping[str, str] | None = None) -> Path | None:
    """The folder of the cache ``name`` in the cache home (not made here), or None where there is no home."""
    home = cache_home(environ)
    return None if home is None else home / name


def writable_folder(folder: Path | None, what: str, inputs: tuple[Path, ...] = ()) -> bool:
    """Whether the cache ``what`` may write ``folder``: made where missing, writable, and inside none of ``inputs``
    (the data being read, which is never written). Where not, says so once per process and folder
    (`say_unwritable`) and returns False."""
    if folder is None:
        say_unwritable(what, None, f"no folder for it: set {CACHE_ENV} or HOME")
        return False
    inside = next((root for root in inputs if is_inside(folder, root)), None)
    if inside is not None:
        say_unwritable(what, folder, f"it lies inside the data {inside}, which is never written")
        return False
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        say_unwritable(what, folder, f"it cannot be made: {err.strerror or err}")
        return False
    if not os.access(folder, os.W_OK | os.X_OK):  # a read-only mount too (EROFS)
        say_unwritable(what, folder, "it is not writable")
        return False
    return True


def say_unwritable(what: str, folder: Path | None, reason: str) -> None:
    """Say once per process and folder, in one line (`LOGGER`), that the cache ``what`` in ``folder`` is not
    written (what it lacks is computed again each time), and why."""
    key = str(folder)
    if key in _said:
        return
    _said.add(key)
    where = "" if folder is None else f" {folder}"
    LOGGER.warning(
        "stamlane: %s%s is not written (%s); what it lacks is computed again (%s names another folder)",
        what,
        where,
        reason,
        CACHE_ENV,
    )
