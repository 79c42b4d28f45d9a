"""The evaluator distribution builds (wheel and sdist) and works on its own: a fresh venv, no torch."""

from __future__ import annotations

import subprocess
import sys
import venv
from pathlib import Path

import pytest

EVALUATORS = Path(__file__).resolve().parents[2] / "evaluators"
GOLDEN = Path(__file__).resolve().parent / "golden"


def test_wheel_and_sdist_build_and_install_without_torch(tmp_path: Path) -> None:
    pytest.importorskip("build", reason="the 'build' package (test extra) builds the distributions")
    dist = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "build", "--wheel", "--sdist", "--outdir", str(dist), str(EVALUATORS)],
        check=True,
        capture_output=True,
        timeout=900,
    )
    (wheel,) = dist.glob("stamlane_eval-*.whl")
    (sdist,) = dist.glob("stamlane_eval-*.tar.gz")
    assert sdist.stat().st_size > 0
    env = tmp_path / "venv"
    venv.create(env, with_pip=True)
    python = env / "bin" / "python"
    subprocess.run([python, "-m", "pip", "install", "-q", str(wheel)], check=True, capture_output=True, timeout=900)
    check = (
        "import importlib.util, sys\n"
        "import stamlane_eval.cli, stamlane_eval.tusimple, stamlane_eval.culane, stamlane_eval.stats\n"
        "assert importlib.util.find_spec('torch') is None, 'torch got installed'\n"
        "assert 'torch' not in sys.modules\n"
    )
    subprocess.run([python, "-c", check], check=True, capture_output=True, timeout=300)
    scored = subprocess.run(
        [
            env / "bin" / "stamlane-eval",
            "tusimple",
            GOLDEN / "tusimple_pred.json",
            GOLDEN / "tusimple_gt.json",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert scored.returncode == 0, scored.stderr
    assert '"images": 22' in scored.stdout
