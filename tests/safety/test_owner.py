"""Output folders that belong to one source (`stamlane.safety.owner`), and the commands that claim them."""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from stamlane.cli import main
from stamlane.safety.guard import GuardError
from stamlane.safety.owner import OWNER_NAME, claim, mark, owner_of
from stamlane.weights import DEFAULT

A = {"command": "predict", "source": "/data/v/clip.mp4"}
B = {"command": "predict", "source": "/data/f/clip"}


def test_a_folder_holds_one_sources_results(tmp_path: Path) -> None:
    out = tmp_path / "clip"
    assert claim(out, A, "--out") == out and not out.exists()  # nothing written by claiming
    mark(out, A)
    assert owner_of(out)["source"] == A["source"] and owner_of(out)["run"]["pid"] == os.getpid()
    assert claim(out, A, "--out") == out  # the same source again: its folder
    with pytest.raises(GuardError, match=r"--out .*clip holds the predict output of another source \(/data/v/clip"):
        claim(out, B, "--out")
    assert claim(out, B, "--out", chosen=True) == tmp_path / "clip-2"  # a folder stamlane chose gives way
    mark(tmp_path / "clip-2", B)
    assert claim(out, B, "--out", chosen=True) == tmp_path / "clip-2"
    assert claim(out, {**B, "source": "/c"}, "--out", chosen=True) == tmp_path / "clip-3"


def test_a_folder_without_an_owner_file(tmp_path: Path) -> None:
    out = tmp_path / "set"
    out.mkdir()
    assert claim(out, A, "--out", strict=True) == out  # empty: anyone's
    (out / "0.jpg").write_bytes(b"x")
    (out / "test_label.json").write_text("{}")
    with pytest.raises(GuardError, match="holds files stamlane did not write there"):
        claim(out, A, "--out", strict=True)
    assert claim(out, A, "--out") == out  # named by the user, not strict: an older stamlane's results carry none
    assert claim(out, A, "--out", chosen=True) == tmp_path / "set-2"
    (out / OWNER_NAME).write_text("[not a mapping")  # an owner file that cannot be read owns nothing
    assert owner_of(out) is None


def test_synth_writes_into_nothing_it_did_not_write(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A folder holding frames and ``test_label.json`` (no name of the set synth writes) is refused, untouched."""
    out = tmp_path / "frames"
    out.mkdir()
    (out / "0.jpg").write_bytes(b"frame")
    (out / "test_label.json").write_text("{}\n")
    argv = ["synth", "--out", str(out), "--clips", "1", "--challenging-clips", "0", "--quiet", "--size", "64x48"]
    assert main([*argv, "--frames", "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "holds files stamlane did not write there (0.jpg" in err
    assert sorted(p.name for p in out.iterdir()) == ["0.jpg", "test_label.json"]
    assert (out / "0.jpg").read_bytes() == b"frame"


@pytest.fixture
def two_clips(tmp_path: Path) -> tuple[Path, Path]:
    """``v/clip.mp4`` and a folder ``f/clip`` of frames: two sources of one name."""
    (tmp_path / "v").mkdir()
    (tmp_path / "f" / "clip").mkdir(parents=True)
    video = tmp_path / "v" / "clip.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (128, 72))
    for i in range(3):
        frame = np.full((72, 128, 3), 40 * i, np.uint8)
        writer.write(frame)
        cv2.imwrite(str(tmp_path / "f" / "clip" / f"{i}.jpg"), frame)
    writer.release()
    return video, tmp_path / "f" / "clip"


def test_predict_gives_a_second_source_of_the_same_name_its_own_folder(
    two_clips: tuple[Path, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    plain_argv: None,
    capsys: pytest.CaptureFixture[str],
) -> None:
    video, frames = two_clips
    monkeypatch.chdir(tmp_path)
    top = tmp_path / "outputs" / "predict" / DEFAULT  # what predict --source runs with no model
    assert main(["predict", "--source", str(video), "--trainer.enable_progress_bar=false"]) == 0
    first = {p: p.read_bytes() for p in (top / "clip").rglob("*") if p.is_file()}
    assert (top / "clip" / "overlay.mp4") in first
    assert main(["predict", "--source", str(frames), "--trainer.enable_progress_bar=false"]) == 0
    assert {p: p.read_bytes() for p in (top / "clip").rglob("*") if p.is_file()} == first  # as the first run left it
    assert json.loads((top / "clip-2" / OWNER_NAME).read_text())["source"] == str(frames.resolve())
    assert not (top / "clip-2" / "overlay.mp4").exists()
    capsys.readouterr()
    given = ["--predictions.output_dir", str(top / "clip"), "--trainer.enable_progress_bar=false"]
    assert main(["predict", "--source", str(frames), *given]) == 2  # named by the user: refused, naming the flag
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("stamlane predict:")]
    assert len(err) == 2 and "--predictions.output_dir" in err[-1] and "another source" in err[-1], err


def test_stream_gives_a_second_source_of_the_same_name_its_own_folder(
    two_clips: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    video, frames = two_clips
    monkeypatch.chdir(tmp_path)
    for source in (video, frames):
        assert main(["stream", str(source), "--ckpt", "stam4-synthetic", "--no-video", "--max-frames", "2"]) == 0
    top = tmp_path / "outputs" / "stream"
    assert owner_of(top / "clip")["source"] == str(video.resolve())
    assert owner_of(top / "clip-2")["source"] == str(frames.resolve())
    assert main(["stream", str(frames), "--ckpt", "stam4-synthetic", "--out", str(top / "clip"), "--no-video"]) == 2
    assert "--out" in capsys.readouterr().err.splitlines()[-1]
