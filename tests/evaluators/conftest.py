"""Fixtures of the evaluator tests: the golden inputs committed beside them."""

from __future__ import annotations

import importlib.util
import json
import os
import socket
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

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


def run_ddp_pair(worker: Path, out: Path, timeout: float) -> dict[str, Any]:
    """Run a DDP worker script as two processes (ranks 0 and 1 of 2, on a free local port) and read what it wrote.

    Args:
        worker: the script, called as ``worker RANK WORLD_SIZE PORT OUT``.
        out: the json file the workers write.
        timeout: seconds each process may take.

    Returns:
        the json in ``out``, after both processes exited 0 (asserted, with their stderr).
    """
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OMP_WAIT_POLICY": "PASSIVE"}
    procs = [
        subprocess.Popen(
            [sys.executable, str(worker), str(r), "2", str(port), str(out)], env=env, stderr=subprocess.PIPE
        )
        for r in range(2)
    ]
    errs = [p.communicate(timeout=timeout)[1].decode() for p in procs]
    assert [p.returncode for p in procs] == [0, 0], errs
    result: dict[str, Any] = json.loads(out.read_text())
    return result
