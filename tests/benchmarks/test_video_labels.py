"""The video's labels (``benchmarks/video_labels.py``): the fit on lines drawn by hand, the TuSimple record's scaling,
and the committed labels redrawn from the real video (``../shared``)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.benchmarks.scripts import benchmark_module

VP = (480.0, 311.0)


@pytest.fixture(scope="module")
def labels():
    with benchmark_module("video_labels") as module:
        yield module


def _road(bottoms: list[float], dashed: list[bool]) -> np.ndarray:
    """A 960x540 road: sky above the vanishing point, noisy asphalt below, white lines from it to ``bottoms``."""
    rng = np.random.default_rng(0)
    image = np.full((540, 960, 3), 90, dtype=np.uint8)
    image[: int(VP[1])] = (230, 190, 140)
    image[int(VP[1]) :] = np.clip(90 + rng.normal(0, 4, (540 - int(VP[1]), 960, 1)), 0, 255).astype(np.uint8)
    for x_bottom, dash in zip(bottoms, dashed, strict=True):
        ys = np.arange(VP[1] + 6, 540, 1.0)
        xs = VP[0] + (x_bottom - VP[0]) * (ys - VP[1]) / (539 - VP[1])
        for i in range(len(ys) - 1):
            if dash and (ys[i] // 25) % 2:
                continue
            width = 1 + int(8 * (ys[i] - VP[1]) / (540 - VP[1]))
            cv2.line(image, (round(xs[i]), round(ys[i])), (round(xs[i + 1]), round(ys[i + 1])), (235, 235, 235), width)
    return image


def test_the_fit_finds_drawn_lines_and_their_vanishing_point(labels):
    bottoms = [-400.0, 150.0, 840.0]
    vp, lines = labels.label_frame(_road(bottoms, [True, True, False]))
    assert abs(vp[0] - VP[0]) <= 4 and abs(vp[1] - VP[1]) <= 3
    assert len(lines) == 3
    for line, x_bottom in zip(lines, bottoms, strict=True):
        ys = line.paint[:, 1]  # the rows where the line is painted and inside the frame
        truth = VP[0] + (x_bottom - VP[0]) * (ys - VP[1]) / (539 - VP[1])
        slope = (x_bottom - VP[0]) / (
            539 - VP[1]
        )  # px across per row: a flat line's x error is its distance times this
        distance = np.abs(np.polyval(line.coeffs, ys) - truth) / np.hypot(1.0, slope)
        assert len(ys) >= labels.MIN_PAINT_ROWS and distance.max() < 1.5
        assert line.y_top < 360  # the label starts at the farthest paint, near the vanishing point


def test_a_road_without_paint_has_no_lines(labels):
    _, lines = labels.label_frame(_road([], []))
    assert lines == []


def test_the_record_is_in_tusimples_1280x720_frame(labels):
    line = labels.Line((0.0, 1.0, 0.0), 300.0, np.zeros((0, 2)))  # x = y in a 960-wide frame, from row 300
    record = labels.tusimple_record("v.mp4#7", [line], 960)
    xs = dict(zip(record["h_samples"], record["lanes"][0], strict=True))
    assert xs[390] == -2 and xs[400] == 400.0 and xs[700] == 700.0  # row 300 of 540 is row 400 of 720
    assert labels.frame_of(record["raw_file"]) == 7


def test_the_committed_labels_are_what_the_rule_draws(labels, shared_dir: Path):
    from stamlane_eval.io import check_tusimple

    committed = [json.loads(line) for line in labels.LABELS.read_text().splitlines()]
    check_tusimple(committed, "gt")
    assert [labels.frame_of(r["raw_file"]) for r in committed] == list(labels.FRAMES)
    assert all(len(r["lanes"]) == 3 for r in committed)  # the rule: the ego lane's two lines and the next on the left
    again, _ = labels.label_video(shared_dir / labels.VIDEO, (labels.FRAMES[0], labels.FRAMES[-1]))
    for new, old in zip(again, [committed[0], committed[-1]], strict=True):
        assert new["raw_file"] == old["raw_file"] and len(new["lanes"]) == len(old["lanes"])
        for a, b in zip(new["lanes"], old["lanes"], strict=True):
            assert [x < 0 for x in a] == [x < 0 for x in b]
            assert max(abs(x - y) for x, y in zip(a, b, strict=True)) <= 0.5


def test_a_missing_video_is_one_line_and_writes_nothing(labels, tmp_path: Path, capsys: pytest.CaptureFixture):
    out = tmp_path / "labels.json"
    assert labels.main(["--shared", str(tmp_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("video_labels: error:") and "solidWhiteRight.mp4" in err[0]
    assert not out.exists()


def test_bad_frames_and_an_output_over_the_video_are_one_line_each(
    labels, shared_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
):
    video = shared_dir / labels.VIDEO
    before = video.stat().st_size
    out = tmp_path / "labels.json"
    for argv in (["--frames", "-1"], ["--frames", "5000"], ["--out", str(video)]):
        assert labels.main(["--shared", str(shared_dir), "--out", str(out), *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("video_labels: error:")
    assert not out.exists() and video.stat().st_size == before


def test_a_frame_twice_and_an_output_that_is_no_label_file_are_one_line_each(
    labels, shared_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
):
    mine, folder, text = tmp_path / "mine.json", tmp_path / "folder.json", tmp_path / "labels.txt"
    mine.write_text('{"my": "settings"}\n')  # a file of the user's: never replaced by labels
    folder.mkdir()
    cases = [
        (["--frames", "11", "33", "11", "--out", str(tmp_path / "new.json")], "frame 11 more than once"),
        (["--frames", "11", "--out", str(mine)], "no TuSimple label file"),
        (["--frames", "11", "--out", str(folder)], "is a folder"),
        (["--frames", "11", "--out", str(text)], ".json"),
    ]
    for argv, said in cases:
        assert labels.main(["--shared", str(shared_dir), *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("video_labels: error:") and said in err[0], err
    assert mine.read_text() == '{"my": "settings"}\n' and not any(folder.iterdir())
    assert not (tmp_path / "new.json").exists() and not text.exists()


def test_an_existing_label_file_is_replaced_atomically(labels, shared_dir: Path, tmp_path: Path):
    out = tmp_path / "labels.json"
    out.write_text(labels.LABELS.read_text().splitlines()[0] + "\n")  # a label file of one frame: replaced
    assert labels.main(["--shared", str(shared_dir), "--frames", "33", "--out", str(out)]) == 0
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["raw_file"] for r in records] == ["solidWhiteRight.mp4#33"]
    assert [p.name for p in tmp_path.iterdir()] == ["labels.json"]  # no temporary file left beside it
