"""The type checker: ``mypy --strict`` over ``src/stamlane`` and ``evaluators/src/stamlane_eval``, as configured in
pyproject.toml (``[tool.mypy]``), inside README command 2. Its incremental cache is ``.mypy_cache/`` (gitignored):
the first run of a clone checks every module, later runs only what changed."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_mypy_strict_passes():
    if importlib.util.find_spec("mypy") is None:
        pytest.skip("mypy is not installed (it comes with the `test` extra)")
    run = subprocess.run([sys.executable, "-m", "mypy"], capture_output=True, text=True, cwd=REPO)
    assert run.returncode == 0, (run.stdout[-20000:] + run.stderr).strip()
