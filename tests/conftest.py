"""Test setup shared by the whole suite."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

# With the other core busy, torch's default OpenMP spin-waiting ran 15x slower on the 2-core CI machine.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """``../shared`` beside the checkout; tests that need it skip where a user's clone has none."""
    if not SHARED.is_dir():
        pytest.skip(f"{SHARED} is absent (it exists only beside the project's own checkouts)")
    return SHARED


@pytest.fixture
def plain_argv(monkeypatch: pytest.MonkeyPatch) -> None:
    """``sys.argv`` set to ``["stamlane"]``: LightningCLI warns when given args while it holds pytest's own."""
    monkeypatch.setattr(sys, "argv", ["stamlane"])
