"""``benchmarks/_harness.py``: the option checks, the machine a result came from, the atomic result files and the
side-by-side timing every benchmark script shares."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from tests.benchmarks.scripts import load_script

harness = load_script("_harness")


def test_an_option_out_of_its_range_or_choices_is_named_with_its_value() -> None:
    values = {"kinds": ["blank", "fog"], "draws": 0, "frames": None, "seed": -1, "video_frames": 0}
    ranges = {"draws": harness.Within(1, 8), "frames": harness.Within(1), "seed": harness.Within(0)}
    # the choices first, then the ranges in the order given; None (an option not given) is never a problem
    assert harness.option_problem(values, {"kinds": ("blank", "glare")}, ranges) == "--kinds: fog not of blank glare"
    assert harness.option_problem(values, ranges=ranges) == "--draws must be in 1..8, got 0"
    assert harness.option_problem(values | {"draws": 8}, ranges=ranges) == "--seed must be >= 0, got -1"
    why = {"video_frames": harness.Within(2, 9, " (the intervals resample clips)")}
    assert harness.option_problem(values, ranges=why) == (
        "--video-frames must be in 2..9 (the intervals resample clips), got 0"
    )
    assert harness.option_problem(values | {"draws": 1, "seed": 0}, {"kinds": ("blank", "fog")}, ranges) is None


def test_variants_take_turns_and_their_medians_give_the_ratio() -> None:
    order: list[tuple[str, int]] = []
    seconds = {"slow": [3.0, 5.0, 4.0], "fast": [1.0, 2.0, 9.0]}

    def measure(variant: str, repeat: int) -> float:
        order.append((variant, repeat))
        return seconds[variant][repeat]

    times = harness.in_turn(measure, ["slow", "fast"], 3)
    assert order == [("slow", 0), ("fast", 0), ("slow", 1), ("fast", 1), ("slow", 2), ("fast", 2)]
    assert times == seconds and harness.medians(times) == {"slow": 4.0, "fast": 2.0}
    assert harness.ratio(times, "slow", "fast") == 2.0
    assert harness.ratio({"a": [1.0], "b": [3.0]}, "a", "b") == 0.333
    assert harness.ratio({"a": [1.0], "b": [3.0]}, "a", "b", digits=None) == 1 / 3
    order.clear()
    harness.in_turn(measure, ["slow", "fast"], 3, alternate=True)  # ABBA
    assert [v for v, _ in order] == ["slow", "fast", "fast", "slow", "slow", "fast"]
    elapsed, value = harness.timed(lambda: sum(range(1000)))
    assert value == 499500 and elapsed >= 0.0


def test_machine_names_the_cpu_and_its_cores() -> None:
    info = harness.machine()
    assert set(info) == {"cpu", "cores"} and info["cpu"] and info["cores"] == os.cpu_count()
    assert isinstance(harness.load_1min(), float)


def test_results_are_written_whole_or_not_at_all(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "new" / "result.json"
    harness.write_result(out, {"ratio": 1.5, "times_s": [1, 2]})
    assert json.loads(out.read_text()) == {"ratio": 1.5, "times_s": [1, 2]} and out.read_text().endswith("\n")
    assert capsys.readouterr().out == f"wrote {out}\n"
    with pytest.raises(ValueError):  # a NaN refused: the earlier file stays, no temporary file is left
        harness.write_result(out, {"loss": float("nan")}, allow_nan=False)
    assert json.loads(out.read_text())["ratio"] == 1.5 and sorted(p.name for p in out.parent.iterdir()) == [out.name]
    picture = tmp_path / "pictures" / "a.png"
    harness.write_image(picture, np.zeros((4, 6, 3), np.uint8))
    assert picture.read_bytes().startswith(b"\x89PNG")
    with pytest.raises(OSError, match="could not write the picture"):  # OpenCV knows no such format
        harness.write_image(tmp_path / "pictures" / "a.unknown-format", np.zeros((4, 6, 3), np.uint8))
    assert sorted(p.name for p in picture.parent.iterdir()) == ["a.png"]
