"""``stamlane align --write-frames``: aligned frames on disk, their manifest, resuming, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from stamlane.align.cli import main
from stamlane.align.egomotion import RoadCamera
from stamlane.align.export import MANIFEST_NAME, aligned_frame_name
from stamlane.align.synthetic import render_road

TINY = RoadCamera(width=320, height=180, focal=250.0, horizon_row=70.0, camera_height=1.5)
GROUND_ROW = 81  # 0.45 * 180, the default --horizon-row


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, texture) -> Path:
    """TuSimple-like ``clips/0530/road/1..5.jpg`` (0.6 m per frame) and a textureless ``blank/1..3.png`` clip."""
    root = tmp_path_factory.mktemp("data")
    road = root / "clips" / "0530" / "road"
    road.mkdir(parents=True)
    for i in range(5):
        frame = render_road(texture, TINY, forward=0.6 * i)
        cv2.imwrite(str(road / f"{i + 1}.jpg"), frame, [cv2.IMWRITE_JPEG_QUALITY, 95])
    blank = root / "clips" / "0530" / "blank"
    blank.mkdir(parents=True)
    for i in range(3):  # nothing to match: every alignment fails
        cv2.imwrite(str(blank / f"{i + 1}.png"), np.full((180, 320, 3), 90 + 10 * i, np.uint8))
    return root


def _argv(dataset: Path, tmp_path: Path, *extra: str) -> list[str]:
    return [str(dataset), "--cache", str(tmp_path / "cache"), "--num-frames", "4", "--quiet", *extra]


def _ground_error(image: np.ndarray, key: np.ndarray) -> float:
    """Mean absolute grey difference on the ground rows, both slightly blurred (the grain aliases)."""
    a, b = (cv2.GaussianBlur(cv2.cvtColor(x, cv2.COLOR_BGR2GRAY).astype(np.float32), (0, 0), 2) for x in (image, key))
    return float(np.abs(a - b)[GROUND_ROW:].mean())


def test_aligned_frame_name():
    assert aligned_frame_name(Path("c/20.jpg"), Path("c/18.jpg"), 2) == "20_back2.jpg"
    assert aligned_frame_name(Path("v/00030.jpg"), Path("v/00000.png"), 1) == "00030_back1.png"


def test_write_frames_names_manifest_and_alignment(dataset, tmp_path, capsys):
    out = tmp_path / "aligned"
    assert main(_argv(dataset, tmp_path, "--write-frames", str(out))) == 0
    summary = capsys.readouterr().out
    assert "wrote 7 frames" in summary and "2 history frames written UNWARPED" in summary

    road = out / "clips" / "0530" / "road"
    assert sorted(p.name for p in road.iterdir()) == [
        "5_back0.jpg",
        "5_back1.jpg",
        "5_back2.jpg",
        "5_back3.jpg",
        MANIFEST_NAME,
    ]
    manifest = json.loads((road / MANIFEST_NAME).read_text())
    assert list(manifest) == ["5.jpg"]
    assert {n: (e["source"], e["back"], e["ok"]) for n, e in manifest["5.jpg"].items()} == {
        "5_back3.jpg": ("2.jpg", 3, True),
        "5_back2.jpg": ("3.jpg", 2, True),
        "5_back1.jpg": ("4.jpg", 1, True),
        "5_back0.jpg": ("5.jpg", 0, True),
    }
    cache = json.loads((tmp_path / "cache" / "clips" / "0530" / "road.json").read_text())
    assert manifest["5.jpg"]["5_back2.jpg"]["key_from_hist"] == cache["5.jpg"]["3.jpg"]["key_from_hist"]
    assert (road / "5_back0.jpg").read_bytes() == (dataset / "clips/0530/road/5.jpg").read_bytes()

    key = cv2.imread(str(dataset / "clips/0530/road/5.jpg"))
    for back in (1, 2, 3):
        aligned = cv2.imread(str(road / f"5_back{back}.jpg"))
        raw = cv2.imread(str(dataset / f"clips/0530/road/{5 - back}.jpg"))
        assert aligned.shape == key.shape
        before, after = _ground_error(raw, key), _ground_error(aligned, key)
        assert after < 3.0 and after < 0.35 * before, (back, before, after)

    blank = out / "clips" / "0530" / "blank"
    entries = json.loads((blank / MANIFEST_NAME).read_text())["3.png"]
    for name, source in (("3_back1.png", "2.png"), ("3_back2.png", "1.png")):
        assert entries[name]["ok"] is False and entries[name]["reason"]
        assert entries[name]["key_from_hist"] == np.eye(3).tolist()
        written = cv2.imread(str(blank / name))  # unwarped and lossless: the source frame itself
        np.testing.assert_array_equal(written, cv2.imread(str(dataset / "clips/0530/blank" / source)))


def test_write_frames_resumes_and_reuses_the_cache(dataset, tmp_path, capsys):
    assert main(_argv(dataset, tmp_path)) == 0  # the cache alone first
    cache_file = tmp_path / "cache" / "clips" / "0530" / "road.json"
    cache_mtime = cache_file.stat().st_mtime_ns
    capsys.readouterr()

    out = tmp_path / "aligned"
    argv = _argv(dataset, tmp_path, "--write-frames", str(out))
    assert main(argv) == 0  # frames from the cached homographies, nothing estimated again
    summary = capsys.readouterr().out
    assert "aligned 0 clip folders (2 already cached)" in summary and "wrote 7 frames" in summary
    assert cache_file.stat().st_mtime_ns == cache_mtime

    files = sorted(p for p in out.rglob("*") if p.is_file())
    mtimes = [p.stat().st_mtime_ns for p in files]
    assert main(argv) == 0  # resumed: nothing to do
    assert "wrote 0 frames" in capsys.readouterr().out
    assert [p.stat().st_mtime_ns for p in files] == mtimes

    (out / "clips/0530/road/5_back2.jpg").unlink()  # an interrupted run: one frame missing
    assert main(argv) == 0
    assert "wrote 1 frames" in capsys.readouterr().out
    assert (out / "clips/0530/road/5_back2.jpg").is_file()
    assert (out / "clips/0530/road/5_back1.jpg").stat().st_mtime_ns == mtimes[
        files.index(out / "clips/0530/road/5_back1.jpg")
    ]
    assert not [p for p in out.rglob(".*")]  # no temporary files left


def test_write_frames_for_every_key_frame_with_a_stride(dataset, tmp_path):
    out = tmp_path / "aligned"
    argv = [str(dataset), "--cache", str(tmp_path / "c"), "--num-frames", "3", "--stride", "2", "--key-frames", "all"]
    assert main([*argv, "--write-frames", str(out), "--quiet"]) == 0
    names = sorted(p.name for p in (out / "clips/0530/road").glob("*.jpg"))
    expected = ["1_back0", "2_back0", "3_back0", "3_back2", "4_back0", "4_back2", "5_back0", "5_back2", "5_back4"]
    assert names == sorted(f"{n}.jpg" for n in expected)
    manifest = json.loads((out / "clips/0530/road" / MANIFEST_NAME).read_text())
    assert manifest["5.jpg"]["5_back4.jpg"]["source"] == "1.jpg" and manifest["1.jpg"] == {
        "1_back0.jpg": {"source": "1.jpg", "back": 0, "ok": True, "reason": "", "key_from_hist": np.eye(3).tolist()}
    }


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--write-frames", "{file}"], "is not a folder"),
        (["--write-frames"], "expected one argument"),
        (["--write-frames", "{file}/sub"], "a file, not a folder"),
    ],
)
def test_write_frames_bad_input_is_one_line_and_status_2(dataset, tmp_path, capsys, extra, message):
    afile = tmp_path / "a_file"
    afile.write_text("not a folder")
    argv = [str(dataset), "--cache", str(tmp_path / "c"), *(a.format(file=afile) for a in extra)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "c").exists()


def test_write_frames_io_error_is_one_line_and_status_2(dataset, tmp_path, capsys):
    out = tmp_path / "aligned"
    out.mkdir()
    (out / "clips").write_text("a file where a clip's output folder goes")
    assert main(_argv(dataset, tmp_path, "--write-frames", str(out))) == 2
    err = capsys.readouterr().err
    assert err.startswith("stamlane align: ") and "clips" in err and err.count("\n") == 1
