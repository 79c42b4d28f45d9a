"""``benchmarks/real_roads_seeds.py``: the real-road check over seeds, on results written by hand."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.benchmarks.scripts import benchmark_module

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("real_roads_seeds") as module:
        yield module


def _result(rates: list[tuple[float, float]], over: int, video_f1: float | None = None) -> dict:
    fp, fn = (sum(r[k] for r in rates) / len(rates) for k in (0, 1))
    per_image = [{"fp": a, "fn": b} for a, b in rates]
    frames = {"f1": 2 * (1 - fp) * (1 - fn) / ((1 - fp) + (1 - fn)), "fp": fp, "fn": fn, "per_image": per_image}
    video = {"frames_over_max": over, "frames_with_crossing": 0, "mean_lanes": 4.0}
    if video_f1 is not None:  # files written before the video's labelled frames have none
        video["labelled_frames"] = {"f1": video_f1}
    return {"labelled_frames": frames, "video": video}


def test_groups_are_summed_over_seeds_and_compared_image_by_image(bench, tmp_path: Path, capsys) -> None:
    good = [(0.0, 0.0), (0.25, 0.25), (0.0, 0.5)]
    bad = [(0.5, 0.5), (0.5, 0.75), (0.25, 0.5)]
    for seed, over in ((0, 10), (1, 20)):
        (tmp_path / f"good-s{seed}.json").write_text(json.dumps(_result(good, over, 1.0 - seed / 10)))
        (tmp_path / f"bad-s{seed}.json").write_text(json.dumps(_result(bad, over + 1)))
    (tmp_path / "lone-s3.json").write_text(json.dumps(_result(bad, 5)))  # a group of one seed
    (tmp_path / "synthetic-test.json").write_text(json.dumps({"good-s0": 97.0, "good-s1": 98.0}))
    (tmp_path / "summary.json").write_text("{}")  # not a seeded result: left alone
    assert bench.main([str(tmp_path), "--groups", "good", "bad", "--boot", "200"]) == 0
    out = capsys.readouterr().out
    good_f1 = 100 * bench.f1(0.25 / 3, 0.75 / 3)
    assert f"| **good** | 2 | {good_f1:.1f} ± 0.0 |" in out
    assert "| 95.0 ± 7.1 | 15 ± 7 |" in out and "| – | 16 ± 7 |" in out  # the video's labelled F1, where there is one
    assert "| 15 ± 7 |" in out and "97.5 ± 0.7 |" in out  # frames over 4 lanes; the synthetic test where given
    assert bench.main([str(tmp_path), "--groups", "lone", "--boot", "200"]) == 0
    lone = capsys.readouterr().out
    assert "| **lone** | 1 | " in lone and "±" not in lone  # one seed: its numbers, no spread
    difference = good_f1 - 100 * bench.f1(1.25 / 3, 1.75 / 3)
    line = next(row for row in out.splitlines() if row.startswith("- good − bad"))
    low, high = (float(v) for v in line.split("[")[1].split("]")[0].split(", "))
    assert f"{difference:+.1f}" in line and low <= difference <= high and low > 0  # better on every image
    assert bench.main([str(tmp_path), "--groups", "lone", "good", "bad", "--boot", "200"]) == 0
    assert line in capsys.readouterr().out.splitlines()  # a pair's interval whatever else is shown


def test_several_folders_are_read_as_one_and_a_run_in_two_of_them_is_refused(bench, tmp_path: Path, capsys) -> None:
    new, control = tmp_path / "new", tmp_path / "control"
    for folder, group, rates in ((new, "new", [(0.0, 0.0), (0.0, 0.25)]), (control, "control", [(0.5, 0.5)] * 2)):
        folder.mkdir()
        for seed in (0, 1):
            (folder / f"{group}-s{seed}.json").write_text(json.dumps(_result(rates, 0)))
    (control / "synthetic-test.json").write_text(json.dumps({"control-s0": 99.0, "control-s1": 98.0}))
    assert bench.main([str(new), str(control), "--groups", "new", "control", "--boot", "200"]) == 0
    out = capsys.readouterr().out
    assert "| **new** | 2 | " in out and "| **control** | 2 | " in out and "98.5 ± 0.7 |" in out
    assert any(row.startswith("- new − control: +") for row in out.splitlines())
    (new / "control-s1.json").write_text(json.dumps(_result([(0.5, 0.5)] * 2, 0)))
    assert bench.main([str(new), str(control), "--boot", "200"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "control-s1 is in" in err[0] and "name one of them" in err[0]


def test_a_missing_group_is_one_line_and_status_2(bench, tmp_path: Path, capsys) -> None:
    assert bench.main([str(tmp_path)]) == 2
    assert bench.main([str(tmp_path), "--groups", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("real_roads_seeds: error: no <group>-s<seed>.json") for line in err)


def test_broken_run_files_and_bad_options_are_one_line_each(bench, tmp_path: Path, capsys) -> None:
    good = json.dumps(_result([(0.0, 0.0), (0.25, 0.25)], 1))
    cases = {
        "not-json": ({"a-s0.json": "{broken"}, "not JSON"),
        "not-a-result": (
            {"a-s0.json": json.dumps({"labelled_frames": {"f1": "high"}})},
            "not a real_roads.py dev result",
        ),
        "other-images": ({"a-s0.json": good, "b-s0.json": json.dumps(_result([(0.0, 0.0)], 1))}, "different numbers"),
        "bad-synthetic": ({"a-s0.json": good, "synthetic-test.json": "[1, 2]"}, "synthetic-test.json"),
    }
    for name, (files, said) in cases.items():
        folder = tmp_path / name
        folder.mkdir()
        for file, text in files.items():
            (folder / file).write_text(text)
        assert bench.main([str(folder), "--boot", "10"]) == 2, name
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("real_roads_seeds: error:") and said in err[0], (name, err)
    folder = tmp_path / "folder-run"
    (folder / "a-s0.json").mkdir(parents=True)  # a run "file" that is a folder
    for argv in ([str(folder)], [str(tmp_path / "missing")], [str(tmp_path / "not-json"), "--boot", "0"]):
        assert bench.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("real_roads_seeds: error:"), (argv, err)
