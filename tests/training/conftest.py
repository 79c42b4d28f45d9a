"""Tiny training runs shared by the tests of ``stamlane.training`` (schedule, processes)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest


@pytest.fixture(scope="module")
def tiny_set(tiny_synthetic: Callable[..., Path]) -> Path:
    """4 train, 5 val, 7 test clips of 2 frames at 128x72 (odd splits: their remainders on 2 processes)."""
    return tiny_synthetic(128, 72, 2, train=4, val=5, test=7, challenging=0)
