"""Test setup shared by the whole suite."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest

from stamlane.synth import SynthConfig, generate_dataset
from stamlane.synth.layout import SplitCounts

# With the other core busy, torch's default OpenMP spin-waiting ran 15x slower on the 2-core CI machine.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
if os.environ.get("PYTEST_XDIST_WORKER"):  # `pytest -n N`: N workers share the cores, one torch thread each
    os.environ["OMP_NUM_THREADS"] = "1"  # and so does every process a test starts
    import torch

    torch.set_num_threads(1)

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


_CACHE_HOME: list[tuple[str, str | None]] = []  # (the session's folder, the variable's value before it)


def pytest_configure(config: pytest.Config) -> None:
    """The suite's cache home (``$STAMLANE_CACHE_DIR``, `stamlane.align.user_cache`): a fresh folder of the session,
    set before any test module is imported (some build a subprocess environment at import), so that no test reads
    what an earlier session cached nor writes into the user's ``~/.cache``; processes a test starts inherit it."""
    folder = tempfile.mkdtemp(prefix="stamlane-test-cache-")
    _CACHE_HOME.append((folder, os.environ.get("STAMLANE_CACHE_DIR")))
    os.environ["STAMLANE_CACHE_DIR"] = folder


def pytest_unconfigure(config: pytest.Config) -> None:
    while _CACHE_HOME:
        folder, before = _CACHE_HOME.pop()
        shutil.rmtree(folder, ignore_errors=True)
        if before is None:
            os.environ.pop("STAMLANE_CACHE_DIR", None)
        else:
            os.environ["STAMLANE_CACHE_DIR"] = before


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


@pytest.fixture(scope="session")
def tiny_synthetic(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., Path]:
    """``tiny_synthetic(width, height, num_frames, train=, val=, test=, challenging=, seed=0)``: a small synthetic
    set in the TuSimple layout (``stamlane synth``), written to a fresh temporary folder, without a progress bar."""

    def make(width: int, height: int, num_frames: int, *, seed: int = 0, **splits: int) -> Path:
        root = tmp_path_factory.mktemp("synthetic")
        config = SynthConfig(width=width, height=height, num_frames=num_frames)
        generate_dataset(root, SplitCounts(**splits), seed=seed, config=config, progress=False)
        return root

    return make


TINY_SYNTH = SynthConfig(width=160, height=96, num_frames=8)
"""The settings of the session's tiny synthetic set (`synthetic_root`)."""


@pytest.fixture(scope="session")
def synthetic_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny synthetic set (160x96, 8 frames): 3 train, 1 val, 1 test, 1 challenging clip."""
    root = tmp_path_factory.mktemp("synthetic")
    generate_dataset(
        root, SplitCounts(train=3, val=1, test=1, challenging=1), seed=3, config=TINY_SYNTH, progress=False
    )
    return root


@pytest.fixture(scope="session")
def reveal_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny synthetic set (160x96) with the two reveal splits only: 6 ``reveal`` clips (2 of each kind) and 4
    ``reveal-traffic`` clips (2 of each kind), 12 frames each, with their visibility masks."""
    root = tmp_path_factory.mktemp("reveal")
    splits = {"train": 0, "val": 0, "test": 0, "challenging": 0, "reveal": 6, "reveal_traffic": 4}
    generate_dataset(root, SplitCounts(**splits), seed=5, config=TINY_SYNTH, progress=False)
    return root
