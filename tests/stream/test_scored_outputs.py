"""``stamlane stream --tusimple --culane`` writes what ``stamlane-eval tusimple | culane | video`` score, frames
named as the generator's labels name them: a video of a synthetic clip streamed, scored against its frame labels."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from stamlane_eval.cli import main as evaluate

from stamlane.cli import main as stamlane
from stamlane.safety.owner import OWNER_NAME
from stamlane.synth import SynthConfig, generate_dataset
from stamlane.synth.layout import SplitCounts

torch.set_num_threads(1)
FRAMES = 8
SIZE = "160x96"
NO_LIMIT = "--no-time-limit"
"""The stream's run_time is this busy machine's: lane.py's 200 ms rule would score slow frames as missed."""


@pytest.fixture(scope="module")
def streamed(tmp_path_factory: pytest.TempPathFactory, save_checkpoint) -> dict[str, Path]:
    """A synthetic clip, the video of its frames, the stream's outputs, and its labels as json-lines and CULane
    text (the ground truth of ``stamlane-eval tusimple`` / ``culane``)."""
    tmp = tmp_path_factory.mktemp("scored")
    config = SynthConfig(width=160, height=96, num_frames=FRAMES)
    generate_dataset(tmp / "synth", SplitCounts(test=1), config=config, progress=False)
    clip = tmp / "synth" / "clips" / "test-0000"
    video = tmp / "test-0000.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 20.0, (160, 96))
    for i in range(1, FRAMES + 1):
        writer.write(cv2.imread(str(clip / f"{i}.jpg")))
    writer.release()
    labels = tmp / "synth" / "frame_labels" / "test-0000.json"
    records = json.loads(labels.read_text())
    rows = records[0]["h_samples"]
    ckpt = save_checkpoint(tmp / "last.ckpt")
    argv = ["stream", str(video), "--ckpt", str(ckpt), "--out", str(tmp / "out"), "--no-video", "--tusimple"]
    argv += ["--culane", "--sequence", "clips/test-0000", "--first-frame", "1.jpg"]
    argv += ["--h-samples", str(rows[0]), str(rows[-1] + 1), str(rows[1] - rows[0])]
    assert stamlane(argv) == 0
    gt_jsonl = tmp / "gt.jsonl"
    gt_jsonl.write_text(
        "".join(json.dumps({k: r[k] for k in ("raw_file", "lanes", "h_samples")}) + "\n" for r in records)
    )
    for record in records:
        _write_lines(tmp / "gt_lines", record["raw_file"], record["lanes"], record["h_samples"])
    return {"out": tmp / "out", "labels": labels, "gt_jsonl": gt_jsonl, "gt_lines": tmp / "gt_lines", "tmp": tmp}


def _write_lines(root: Path, raw_file: str, lanes: list[list[float]], rows: list[int]) -> None:
    path = root / f"{raw_file.rsplit('.', 1)[0]}.lines.txt"
    path.parent.mkdir(parents=True, exist_ok=True)
    points = [[(x, y) for x, y in zip(lane, rows) if x >= 0] for lane in lanes]
    path.write_text("".join(" ".join(f"{x} {y}" for x, y in lane) + "\n" for lane in points if len(lane) >= 2))


def _score(capsys, *argv: str) -> dict:
    capsys.readouterr()
    assert evaluate([*argv, "--json"]) == 0
    said = capsys.readouterr()
    assert "no prediction for any" not in said.err  # every frame found by its name
    return json.loads(said.out)


def test_the_frames_are_named_as_the_labels_name_them(streamed: dict[str, Path]) -> None:
    labels = json.loads(streamed["labels"].read_text())
    records = [json.loads(line) for line in (streamed["out"] / "predictions.json").read_text().splitlines()]
    assert [r["raw_file"] for r in records] == [r["raw_file"] for r in labels]  # clips/test-0000/1.jpg ...
    assert all(r["h_samples"] == labels[0]["h_samples"] and r["run_time"] > 0 for r in records)
    lines = sorted(
        (streamed["out"] / "lines" / "clips" / "test-0000").iterdir(), key=lambda p: int(p.name.split(".")[0])
    )
    assert [p.name for p in lines] == [f"{i}.lines.txt" for i in range(1, FRAMES + 1)]
    # the three outputs hold the same lanes: lanes.jsonl's points are the TuSimple rows' (the lanes are sampled
    # at --h-samples) and the CULane text's
    own = [json.loads(line)["lanes"] for line in (streamed["out"] / "lanes.jsonl").read_text().splitlines()]
    for record, lanes, text in zip(records, own, lines, strict=True):
        assert len(record["lanes"]) == len(lanes) == len(text.read_text().splitlines())
        for xs, lane in zip(record["lanes"], lanes, strict=True):
            assert [[x, y] for x, y in zip(xs, record["h_samples"]) if x >= 0] == lane


def test_the_evaluators_score_what_the_stream_wrote(streamed: dict[str, Path], capsys) -> None:
    out, size = streamed["out"], ["--size", SIZE]
    tusimple = _score(capsys, "tusimple", str(out / "predictions.json"), str(streamed["gt_jsonl"]), NO_LIMIT)
    culane = _score(capsys, "culane", str(out / "lines"), str(streamed["gt_lines"]), *size)
    video = _score(capsys, "video", str(out / "predictions.json"), str(streamed["labels"]), *size)
    video_lines = _score(capsys, "video", str(out / "lines"), str(streamed["gt_lines"]), *size)
    assert tusimple["images"] == culane["images"] == video["frames"] == FRAMES
    assert video == video_lines  # the same lanes in either format, the same numbers
    assert 0 <= tusimple["f1"] <= 1 and 0 <= culane["0.5"]["f1"] <= 1


def test_a_perfect_file_in_the_streams_format_scores_1(streamed: dict[str, Path], capsys) -> None:
    """The numbers come from the file: the stream's own records with the labels' lanes score F1 1, with no lanes
    F1 0; so do its CULane files."""
    labels = {r["raw_file"]: r["lanes"] for r in json.loads(streamed["labels"].read_text())}
    records = [json.loads(line) for line in (streamed["out"] / "predictions.json").read_text().splitlines()]
    tmp, size = streamed["tmp"], ["--size", SIZE]
    for name, lanes_of in (("perfect", lambda r: labels[r["raw_file"]]), ("empty", lambda r: [])):
        path = tmp / f"{name}.json"
        path.write_text("".join(json.dumps(r | {"lanes": lanes_of(r)}) + "\n" for r in records))
        want = 1.0 if name == "perfect" else 0.0
        assert _score(capsys, "tusimple", str(path), str(streamed["gt_jsonl"]), NO_LIMIT)["f1"] == pytest.approx(want)
        assert _score(capsys, "video", str(path), str(streamed["labels"]), *size)["0.5"]["f1"] == pytest.approx(want)
    perfect_lines = tmp / "perfect_lines"
    for record in records:  # the stream's layout, the labels' lanes
        _write_lines(perfect_lines, record["raw_file"], labels[record["raw_file"]], record["h_samples"])
    assert {p.relative_to(perfect_lines) for p in perfect_lines.rglob("*.txt")} == {
        p.relative_to(streamed["out"] / "lines") for p in (streamed["out"] / "lines").rglob("*.txt")
    }
    assert _score(capsys, "culane", str(perfect_lines), str(streamed["gt_lines"]), *size)["0.5"]["f1"] == 1.0


def test_a_folder_of_frames_keeps_its_names(streamed: dict[str, Path], tmp_path: Path) -> None:
    clip = streamed["tmp"] / "synth" / "clips" / "test-0000"
    out = tmp_path / "out"
    ckpt = streamed["tmp"] / "last.ckpt"
    argv = ["stream", str(clip), "--ckpt", str(ckpt), "--out", str(out), "--no-video", "--tusimple", "--culane"]
    assert stamlane([*argv, "--max-frames", "3"]) == 0
    records = [json.loads(line) for line in (out / "predictions.json").read_text().splitlines()]
    assert [r["raw_file"] for r in records] == ["test-0000/1.jpg", "test-0000/2.jpg", "test-0000/3.jpg"]
    assert records[0]["h_samples"] == list(range(0, 96, 5))  # every y_step (5 in this checkpoint) rows
    assert sorted(p.name for p in (out / "lines" / "test-0000").iterdir()) == [f"{i}.lines.txt" for i in (1, 2, 3)]
    # a second run replaces the folder whole: no file of the first one stays
    assert stamlane([*argv, "--max-frames", "2"]) == 0
    assert sorted(p.name for p in (out / "lines" / "test-0000").iterdir()) == ["1.lines.txt", "2.lines.txt"]
    assert sorted(p.name for p in out.iterdir()) == sorted(["lanes.jsonl", "lines", "predictions.json", OWNER_NAME])


def test_the_default_names_of_a_videos_frames_are_predicts(streamed: dict[str, Path], tmp_path: Path) -> None:
    video, ckpt = streamed["tmp"] / "test-0000.mp4", streamed["tmp"] / "last.ckpt"
    argv = ["stream", str(video), "--ckpt", str(ckpt), "--out", str(tmp_path), "--no-video", "--tusimple"]
    assert stamlane([*argv, "--max-frames", "2"]) == 0
    names = [json.loads(line)["raw_file"] for line in (tmp_path / "predictions.json").read_text().splitlines()]
    assert names == ["test-0000/000000.jpg", "test-0000/000001.jpg"]  # stamlane predict --source VIDEO's names
    assert np.isfinite([json.loads(line)["run_time"] for line in (tmp_path / "predictions.json").open()]).all()


def test_a_failed_run_keeps_the_previous_lines(streamed: dict[str, Path], tmp_path: Path, capsys) -> None:
    clip, ckpt = streamed["tmp"] / "synth" / "clips" / "test-0000", streamed["tmp"] / "last.ckpt"
    broken = tmp_path / "test-0000"  # the same names, the third frame unreadable
    broken.mkdir()
    for i in (1, 2, 4):
        (broken / f"{i}.jpg").write_bytes((clip / f"{i}.jpg").read_bytes())
    (broken / "3.jpg").write_bytes(b"not an image")
    out = tmp_path / "out"
    argv = ["--ckpt", str(ckpt), "--out", str(out), "--no-video", "--tusimple", "--culane"]
    assert stamlane(["stream", str(broken), *argv, "--max-frames", "2"]) == 0  # the readable frames
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert stamlane(["stream", str(broken), *argv]) == 2
    assert "cannot read image" in capsys.readouterr().err
    assert {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    names = ["lanes.jsonl", "lines", "predictions.json", OWNER_NAME]
    assert sorted(p.name for p in out.iterdir()) == sorted(names)  # no temporary
    assert stamlane(["stream", str(clip), *argv]) == 2  # another source of that name: never beside its results
    assert "holds the stream output of another source" in capsys.readouterr().err


def test_a_videos_frames_are_counted_on_from_the_first_name() -> None:
    from stamlane.stream.eval_outputs import check_h_samples, frame_namer

    assert [frame_namer("1.jpg")(i) for i in (0, 8, 19)] == ["1.jpg", "9.jpg", "20.jpg"]
    assert frame_namer("00000.jpg")(30) == "00030.jpg" and frame_namer("000000.jpg")(0) == "000000.jpg"
    assert frame_namer("frame_0009.png")(1) == "frame_0010.png" and frame_namer("9.jpg")(1) == "10.jpg"
    assert check_h_samples([160, 720, 10]) == list(range(160, 720, 10))  # TuSimple's rows
