"""Fixtures of the evaluator tests: the golden inputs committed beside them."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

HERE = Path(__file__).parent


def _golden_module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("_golden_data", HERE / "_golden_data.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="session")
def golden() -> ModuleType:
    """The helpers of ``_golden_data.py`` (``tusimple_records()``, ``culane_lanes()``, ``xs_to_points()``)."""
    return _golden_module()
