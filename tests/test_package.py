"""The stamlane distribution carries its configs and its shipped weights: a wheel installed elsewhere runs
``stamlane ablate --list`` and ``stamlane demo --quick`` from an empty folder (`stamlane.configs.configs_dir`, the
one way to find them)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_the_wheel_carries_the_configs_and_finds_them_from_an_empty_folder(tmp_path: Path) -> None:
    pytest.importorskip("build", reason="the 'build' package (test extra) builds the distribution")
    dist = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "build", "--wheel", "--outdir", str(dist), str(REPO)],
        check=True,
        capture_output=True,
        timeout=900,
    )
    (wheel,) = dist.glob("stamlane-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    configs = sorted(p.relative_to(REPO).as_posix() for p in (REPO / "configs").rglob("*.yaml"))
    assert len(configs) > 30 and "configs/paper/tables.yaml" in configs
    assert [c for c in configs if f"stamlane/{c}" not in names] == []  # every config, at its place
    assert "stamlane/configs/__init__.py" in names
    shipped = {
        f"stamlane/weights/{name}.ckpt"
        for name in ("stam4-synthetic", "single-synthetic", "single-dashcam", "stam4-dashcam")
    }
    assert shipped <= names

    site = tmp_path / "site"  # the wheel alone, in front of the test environment's dependencies
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(site), str(wheel)],
        check=True,
        capture_output=True,
        timeout=900,
    )
    empty = tmp_path / "empty"
    empty.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site)}
    check = (
        "import stamlane, stamlane.configs\n"
        "from stamlane.experiments.recipes import CONFIG_DIR\n"
        "from stamlane.experiments.table_index import load_tables\n"
        f"assert stamlane.__file__.startswith({str(site)!r}), stamlane.__file__\n"
        f"assert str(CONFIG_DIR).startswith({str(site)!r}), CONFIG_DIR\n"
        "assert (CONFIG_DIR / 'demo.yaml').is_file() and (CONFIG_DIR / 'common' / 'demo_model.yaml').is_file()\n"
        "assert load_tables().tables\n"
    )
    found = subprocess.run([sys.executable, "-c", check], cwd=empty, env=env, capture_output=True, text=True)
    assert found.returncode == 0, found.stderr
    listed = subprocess.run(
        [sys.executable, "-m", "stamlane.cli", "ablate", "--list"],
        cwd=empty,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert listed.returncode == 0, listed.stderr
    assert "f4_mixed_cs_features" in listed.stdout
    assert list(empty.iterdir()) == []  # nothing written where it ran
    demo = subprocess.run(
        # the splits and probes cut to the fewest: what comes from the wheel is the same for every split
        [sys.executable, "-m", "stamlane.cli", "demo", "--quick", "--splits", "test", "--reveal-probes", "key"],
        cwd=empty,
        env=env | {"OMP_NUM_THREADS": "1"},
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert demo.returncode == 0, demo.stderr[-2000:]
    summary = json.loads((empty / "outputs" / "demo" / "summary.json").read_text())  # --out's default, here
    assert [m["name"] for m in summary["models"]] == ["stam4", "single"]
    assert summary["models"][0]["configs"] == ["configs/demo.yaml"]
