"""stamlane's configs: one YAML per experiment (the demo, the paper's tables), installed with the package.

This folder stays at the top of the repository, where the README points; ``pyproject.toml`` installs it as the
package ``stamlane.configs`` (``package-dir``), so that a wheel carries it and ``stamlane demo`` / ``stamlane
ablate`` find it from any folder. `configs_dir` is the one way to find it.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

__all__ = ["configs_dir"]


def configs_dir() -> Path:
    """The folder of stamlane's configs: this repository's ``configs/`` in a source checkout or an editable
    install, the installed ``stamlane/configs`` of a wheel."""
    return Path(str(files(__name__)))
