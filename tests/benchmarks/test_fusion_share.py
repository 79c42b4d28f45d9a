"""``benchmarks/fusion_share.py``: the history's share of the fused features, the model opened as a stored one."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.benchmarks.scripts import benchmark_module


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("fusion_share") as module:
        yield module


def test_a_shipped_model_reads_its_own_data_options_and_gives_shares(
    bench, tiny_synthetic: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A shipped 4-frame model on a tiny set (two challenging clips: another clip's history needs two): a share in (0, 1) on lane and other cells of every key
    frame; the key frame copied differs from the real history (the fusion reads what it is given)."""
    synthetic_root = tiny_synthetic(160, 96, 6, train=1, val=1, test=1, challenging=2)
    real = bench.shares("stam4-synthetic", synthetic_root, "challenging", "real")
    copied = bench.shares("stam4-synthetic", synthetic_root, "challenging", "key")
    assert real and set(real) == set(copied)
    for values in (*real.values(), *copied.values()):
        assert values and all(0 < share < 1 for pair in values for share in pair)
    assert real != copied
    out = tmp_path / "shares.json"
    argv = ["stam4-synthetic", "--data", str(synthetic_root), "--split", "challenging", "--out", str(out)]
    assert bench.main(argv) == 0
    result = json.loads(out.read_text())
    assert result["split"] == "challenging" and set(result["shares"]) == {"real", "key", "other_clip"}
    assert "| factor | real | key | other_clip |" in capsys.readouterr().out


def test_a_run_that_is_not_there_is_one_line(bench, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert bench.main([str(tmp_path / "no-run"), "--data", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("fusion_share.py: error: ") and "no-run" in err
