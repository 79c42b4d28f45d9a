"""``benchmarks/outer_lanes_seeds.py``: where the lines go missing over seeds, on results written by hand."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from tests.benchmarks.scripts import benchmark_module


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("outer_lanes_seeds") as module:
        yield module


def _line(position: str, cause: str, peak: float) -> dict:
    return {"position": position, "cause": cause, "support": {"mean_max": peak}}


def _result(adjacent: list[tuple[str, float]]) -> dict:
    """One checkpoint on three photos, each an ego line and one adjacent line (``(cause, peak)`` per photo)."""
    photos = [
        {"raw_file": f"frames/{i}.jpg", "lines": [_line("ego", "matched", 0.9), _line("adjacent", *adjacent[i])]}
        for i in range(3)
    ]
    return {"photos": photos}


def _write(path: Path, results: dict[str, dict]) -> str:
    path.write_text(json.dumps({"split": "dev", "results": results}))
    return str(path)


def test_lines_are_counted_by_cause_and_compared_photo_by_photo(bench, tmp_path: Path, capsys) -> None:
    new = [("matched", 0.9), ("matched", 0.8), ("drawn off the label", 0.7)]
    old = [("matched", 0.8), ("absent", 0.2), ("absent", 0.1)]
    first = _write(tmp_path / "a.json", {"new-s0": _result(new), "new-s1": _result(new), "shipped": _result(old)})
    second = _write(tmp_path / "b.json", {"old-s0": _result(old), "old-s1": _result(new)})
    assert bench.main([first, second, "--groups", "new", "old", "--resamples", "500"]) == 0
    out = capsys.readouterr().out
    assert "| new | 2 | adjacent | 3 | 4 (2 / 2) | 0 (0 / 0) | 0 (0 / 0) | 0 (0 / 0) | 2 (1 / 1) |" in out
    assert "| old | 2 | adjacent | 3 | 3 (1 / 2) | 2 (2 / 0) | 0 (0 / 0) | 0 (0 / 0) | 1 (0 / 1) |" in out
    assert "| new | 2 | outer |" not in out, "a position without lines has no row"
    line = next(row for row in out.splitlines() if row.startswith("- new − old, 3 adjacent lines of 3 photos"))
    # per line, old's seeds averaged: absent 0, 0.5, 0.5; matched 1, 0.5, 0; peak 0.85, 0.5, 0.4
    assert "absent -0.333 [" in line and "matched +0.167 [" in line and "peak probability +0.217 [" in line
    assert "shipped" not in out, "an unseeded checkpoint is left alone"


def test_bad_inputs_are_one_line_and_status_2(bench, tmp_path: Path, capsys) -> None:
    good = [("matched", 0.9)] * 3
    one = _write(tmp_path / "one.json", {"new-s0": _result(good), "old-s0": _result(good)})
    two = _write(tmp_path / "two.json", {"old-s0": _result(good)})
    other = _result(good)
    other["photos"][2]["raw_file"] = "frames/elsewhere.jpg"
    moved = _write(tmp_path / "moved.json", {"new-s0": _result(good), "old-s0": other})
    bare = _write(tmp_path / "bare.json", {"new-s0": {"photos": [{"raw_file": "frames/0.jpg"}]}})
    (tmp_path / "broken.json").write_text("{broken")
    cases = {
        "name one of them": [one, two, "--groups", "new", "old"],
        "no <group>-s<seed> results of gone": [one, "--groups", "new", "gone"],
        "other photos or lines": [moved, "--groups", "new", "old"],
        "has no photos with lines": [bare, "--groups", "new"],
        "not JSON": [str(tmp_path / "broken.json"), "--groups", "new"],
        "--position: middle not of": [one, "--groups", "new", "old", "--position", "middle"],
        "--resamples must be in": [one, "--groups", "new", "old", "--resamples", "5"],
    }
    for said, argv in cases.items():
        assert bench.main(argv) == 2, said
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("outer_lanes_seeds: error:") and said in err[0], (said, err)
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    for hostile in ("/dev/zero", str(fifo), str(tmp_path)):  # never read to the end, never hung on, not a file
        assert bench.main([hostile, "--groups", "new"]) == 2, hostile
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("outer_lanes_seeds: error:"), (hostile, err)
