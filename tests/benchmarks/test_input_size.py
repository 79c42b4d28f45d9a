"""benchmarks/input_size.py: ``stamlane stream``'s loop timed at several network input sizes (issue #56's 15 frames/s
at 640x360). One real run on a few frames of a folder the test writes, and the refusals of bad input."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.benchmarks.scripts import benchmark_module


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("input_size") as module:
        yield module


def _frames(folder: Path, count: int) -> Path:
    folder.mkdir()
    rng = np.random.default_rng(0)
    for i in range(count):
        image = rng.integers(0, 255, (720, 1280, 3), dtype=np.uint8)
        cv2.imwrite(str(folder / f"{i:03d}.png"), image)
    return folder


def test_times_every_model_at_every_size(bench, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = _frames(tmp_path / "frames", 3)
    out = tmp_path / "input_size.json"
    args = ["--ckpt", "single-synthetic", "--sizes", "80x256", "96x320", "--source", str(source)]
    assert bench.main([*args, "--frames", "3", "--repeats", "2", "--threads", "1", "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    assert set(result["rows"]) == {"single-synthetic@80x256", "single-synthetic@96x320"}
    for row in result["rows"].values():
        assert len(row["fps"]) == 2 and all(f > 0 for f in row["fps"])
        assert row["median_fps"] in row["fps"] and 0 < row["network_share"] <= 1.5
    assert result["stream_size"] == [640, 360] and result["machine"]["cores"] >= 1
    assert "single-synthetic   96x320" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--sizes", "81x256"], "multiples of"),
        (["--frames", "1"], "--frames must be in 2..1000"),
        (["--frames", "1001"], "--frames must be in 2..1000"),
        (["--frames", "9"], "fewer than --frames 9"),
        (["--ckpt", "no-such-model"], "no-such-model"),
    ],
)
def test_refuses_bad_input_in_one_line(bench, tmp_path: Path, capsys: pytest.CaptureFixture[str], extra, words) -> None:
    source = _frames(tmp_path / "frames", 3)
    out = tmp_path / "input_size.json"
    args = ["--ckpt", "single-synthetic", "--source", str(source), "--frames", "3", "--out", str(out), *extra]
    assert bench.main(args) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1
    assert not out.exists()
