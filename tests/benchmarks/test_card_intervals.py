"""``benchmarks/card_intervals.py``: a card's F1 with clip-bootstrap intervals, on label files written here."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.benchmarks.scripts import benchmark_module

H_SAMPLES = [200, 210, 220, 230]
LANES = [[100, 110, 120, 130], [300, 310, 320, 330]]


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("card_intervals") as module:
        yield module


def _write(path: Path, records: list[dict]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(json.dumps(record) + "\n" for record in records))
    return path


def _files(tmp_path: Path) -> tuple[Path, Path, Path]:
    names = [f"clips/c{clip}/{frame}.jpg" for clip in range(4) for frame in (8, 20)]
    gt = _write(tmp_path / "gt.json", [{"raw_file": n, "lanes": LANES, "h_samples": H_SAMPLES} for n in names])
    # every lane found, in reverse file order (the images are matched by name, not by line)
    perfect = [{"raw_file": n, "lanes": LANES, "run_time": 1000} for n in reversed(names)]
    # clip c0 loses its second lane in both key frames: 2 of 8 images with FN 0.5
    half = [{"raw_file": n, "lanes": LANES[:1] if "/c0/" in n else LANES, "run_time": 1000} for n in names]
    return gt, _write(tmp_path / "a" / "predictions.json", perfect), _write(tmp_path / "b" / "predictions.json", half)


def test_scores_and_paired_difference_resample_clips(bench, tmp_path: Path, capsys) -> None:
    gt, perfect, half = _files(tmp_path)
    assert bench.main([str(gt), str(perfect), str(half), "--names", "all", "some", "--resamples", "200"]) == 0
    out = capsys.readouterr().out
    assert "gt.json: 8 images in 4 clips" in out
    assert "  all: 100.0 [100.0, 100.0]" in out  # run_time 1000 ms is not a miss: no time limit
    some = 100 * 2 * 1.0 * (1 - 1 / 8) / (1.0 + (1 - 1 / 8))  # FN 0.125 over the images, FP 0
    assert f"  some: {some:.1f} [" in out
    line = next(row for row in out.splitlines() if row.startswith("  all - some: "))
    assert line.startswith(f"  all - some: {100 - some:+.1f} [+0.0, +")


def test_iou_f1_counts_lanes_and_resamples_clips(bench, tmp_path: Path, capsys) -> None:
    gt, perfect, half = _files(tmp_path)
    args = [str(gt), str(perfect), str(half), "--names", "all", "some", "--resamples", "200", "--iou", "0.5"]
    assert bench.main([*args, "--size", "640x360"]) == 0
    out = capsys.readouterr().out
    assert "gt.json: 8 images in 4 clips, IoU F1 @0.5 in %" in out
    assert "  all: 100.0 [100.0, 100.0]" in out
    some = 100 * 2 * 14 / (2 * 14 + 2)  # 16 lanes, 14 matched, 2 missed, none false
    assert f"  some: {some:.1f} [" in out
    assert f"  all - some: {100 - some:+.1f} [+0.0, +" in out
    # without --size the frame size comes from the set: here no dataset.json and no frame, so one line, status 2
    assert bench.main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("card_intervals: error: ") and "\n" not in err


def test_files_of_other_images_are_one_line_and_status_2(bench, tmp_path: Path, capsys) -> None:
    gt, perfect, _ = _files(tmp_path)
    other = _write(tmp_path / "c" / "predictions.json", [{"raw_file": "clips/x/1.jpg", "lanes": [], "run_time": 1}])
    assert bench.main([str(gt), str(perfect), str(other)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("card_intervals: error: ") and "\n" not in err
    assert bench.main([str(gt), str(perfect), "--names", "a", "b"]) == 2
    assert "2 names for 1 prediction files" in capsys.readouterr().err


@pytest.mark.parametrize(
    "hostile",
    [
        "missing",
        "folder",
        "not json",
        "binary",
        "resamples 0",
        "resamples -5",
        "resamples 1000000000",
        "iou 1.5",
        "size 640",
        "size 0x9",
    ],
)
def test_hostile_input_is_one_line_and_status_2_and_writes_nothing(bench, tmp_path: Path, capsys, hostile: str) -> None:
    gt, perfect, _ = _files(tmp_path)
    pred, extra = str(perfect), []
    if hostile == "missing":
        pred = str(tmp_path / "nowhere.json")
    elif hostile == "folder":
        pred = str(tmp_path / "a")
    elif hostile == "not json":
        (tmp_path / "bad.json").write_text("{not json\n")
        pred = str(tmp_path / "bad.json")
    elif hostile == "binary":
        (tmp_path / "bad.json").write_bytes(b"\x00\xff" * 64)
        pred = str(tmp_path / "bad.json")
    elif hostile.startswith("resamples"):
        extra = ["--resamples", hostile.split()[1]]
    else:
        option, value = hostile.split()
        extra = ["--iou", value] if option == "iou" else ["--iou", "0.5", "--size", value]
    before = sorted(p.name for p in tmp_path.rglob("*"))
    assert bench.main([str(gt), pred, *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("card_intervals: error: ") and "\n" not in err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before
