"""The homography cache and the ``stamlane align`` command on a tiny generated clip set."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from stamlane.align import Alignment
from stamlane.align.cache import (
    alignment_from_json,
    alignment_to_json,
    cache_file,
    find_clip_dirs,
    list_frames,
    load_alignment,
)
from stamlane.align.cli import main
from stamlane.align.egomotion import RoadCamera, key_from_hist_motion
from stamlane.align.synthetic import render_road

from .conftest import corner_error

TINY = RoadCamera(width=320, height=180, focal=250.0, horizon_row=70.0, camera_height=1.5)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, texture) -> Path:
    """TuSimple-like ``clips/<date>/<id>/1..4.jpg`` (PNG frames in one, to cover both) and a VIL-like folder."""
    root = tmp_path_factory.mktemp("data")
    layouts = {"clips/0530/a": ".jpg", "clips/0530/b": ".png", "JPEGImages/video1": ".jpg"}
    for n, (rel, ext) in enumerate(layouts.items()):
        folder = root / rel
        folder.mkdir(parents=True)
        for i in range(4):
            frame = render_road(texture, TINY, forward=10.0 * n + 0.6 * i)
            name = f"{i:05d}{ext}" if rel.startswith("JPEG") else f"{i + 1}{ext}"
            cv2.imwrite(str(folder / name), frame, [cv2.IMWRITE_JPEG_QUALITY, 95])
    (root / "clips" / "0530" / "a" / "notes.txt").write_text("not a frame")
    (root / "clips" / "0530" / "a" / "20.json").write_text("{}")  # numbered, but not an image
    return root


def test_cache_file_layout(tmp_path):
    root = tmp_path / "data"
    assert cache_file("c", root, root / "clips/0530/a") == Path("c/clips/0530/a.json")
    assert cache_file("c", root, "clips/0530/a") == Path("c/clips/0530/a.json")
    assert cache_file("c", root, root) == Path("c/__root__.json")
    with pytest.raises(ValueError, match="elsewhere"):
        cache_file("c", root, tmp_path / "elsewhere")


def test_alignment_json_round_trip():
    alignment = Alignment(np.arange(9, dtype=float).reshape(3, 3), 12, 10, True, "")
    back = alignment_from_json(json.loads(json.dumps(alignment_to_json(alignment))))
    np.testing.assert_array_equal(back.key_from_hist, alignment.key_from_hist)
    assert (back.num_matches, back.num_inliers, back.ok, back.reason) == (12, 10, True, "")


def test_clip_discovery(dataset):
    clips = [c.relative_to(dataset).as_posix() for c in find_clip_dirs(dataset)]
    assert clips == ["JPEGImages/video1", "clips/0530/a", "clips/0530/b"]
    assert [p.name for p in list_frames(dataset / "clips/0530/a")] == ["1.jpg", "2.jpg", "3.jpg", "4.jpg"]


def test_command_writes_resumes_and_loads(dataset, tmp_path, capsys):
    cache = tmp_path / "cache"
    args = [str(dataset), "--cache", str(cache), "--num-frames", "3", "--horizon-row", "81", "--quiet"]
    assert main(args) == 0
    assert "aligned 3 clip folders (0 already cached)" in capsys.readouterr().out
    data = json.loads((cache / "clips/0530/a.json").read_text())
    assert list(data) == ["4.jpg"]
    assert sorted(data["4.jpg"]) == ["2.jpg", "3.jpg"]
    entry = data["4.jpg"]["3.jpg"]
    assert set(entry) == {"key_from_hist", "ok", "num_matches", "num_inliers", "reason"}
    assert np.asarray(entry["key_from_hist"]).shape == (3, 3)
    vil = json.loads((cache / "JPEGImages/video1.json").read_text())
    assert sorted(vil["00003.jpg"]) == ["00001.jpg", "00002.jpg"]

    alignment = load_alignment(cache, dataset, "clips/0530/a/4.jpg", dataset / "clips/0530/a/3.jpg")
    assert isinstance(alignment, Alignment) and alignment.ok, alignment
    truth = key_from_hist_motion(TINY, 0.6)
    assert corner_error(alignment.key_from_hist, truth, (180, 320), 81) < 3.0
    assert load_alignment(cache, dataset, "clips/0530/a/4.jpg", "clips/0530/a/1.jpg") is None  # not requested
    assert load_alignment(cache, dataset, "clips/0530/a/4.jpg", "clips/0530/b/3.png") is None  # other clip
    assert load_alignment(tmp_path / "nothing", dataset, "clips/0530/a/4.jpg", "clips/0530/a/3.jpg") is None

    mtime = (cache / "clips/0530/a.json").stat().st_mtime_ns
    assert main(args) == 0  # resumed: everything is cached
    assert "aligned 0 clip folders (3 already cached)" in capsys.readouterr().out
    assert (cache / "clips/0530/a.json").stat().st_mtime_ns == mtime

    assert main([*args[:-1], "--key-frames", "all", "--stride", "1", "--quiet"]) == 0  # a larger request
    data = json.loads((cache / "clips/0530/a.json").read_text())
    assert sorted(data) == ["1.jpg", "2.jpg", "3.jpg", "4.jpg"] and data["1.jpg"] == {}
    assert sorted(data["3.jpg"]) == ["1.jpg", "2.jpg"]


def test_command_visualize_and_workers(dataset, tmp_path):
    pictures = tmp_path / "pictures"
    argv = [str(dataset), "--cache", str(tmp_path / "c"), "--workers", "2", "--visualize", str(pictures), "--quiet"]
    argv += ["--strategy", "direct", "--num-frames", "3"]
    assert main(argv) == 0
    written = sorted(p.name for p in pictures.iterdir())
    assert written == ["JPEGImages__video1_00003_00002.jpg", "clips__0530__a_4_3.jpg", "clips__0530__b_4_3.jpg"]
    picture = cv2.imread(str(pictures / written[1]))
    assert picture is not None and picture.shape == (3 * 180 // 2, 320, 3)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["{root}", "--num-frames", "1"], "--num-frames must be >= 2, got 1"),
        (["{root}", "--stride", "0"], "--stride must be >= 1, got 0"),
        (["{root}", "--workers", "0"], "--workers must be >= 1, got 0"),
        (["{root}/missing"], "is not a folder"),
        (["{root}", "--key-frames", "first"], "invalid choice: 'first'"),
        (["{empty}"], "no clip folders"),
    ],
)
def test_command_bad_input_is_one_line_and_status_2(dataset, tmp_path, capsys, argv, message):
    argv = [a.format(root=dataset, empty=tmp_path) for a in argv]
    assert main([*argv, "--cache", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_command_module_does_not_import_torch():
    code = "import sys, stamlane.align.cli; sys.exit('torch' in sys.modules or 'lightning' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_command_with_a_relative_root(dataset, tmp_path, monkeypatch):
    monkeypatch.chdir(dataset.parent)
    assert main([dataset.name, "--cache", "cache", "--num-frames", "2", "--quiet"]) == 0
    assert (dataset.parent / "cache" / "clips" / "0530" / "b.json").is_file()
    assert load_alignment("cache", dataset.name, "clips/0530/b/4.png", "clips/0530/b/3.png") is not None


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("0.45", "--horizon-row: invalid int value: '0.45'"),  # a row in pixels, as in the data and stream options
        ("-3", "--horizon-row must be >= 0, got -3"),
        ("170", "horizon_row must be in [0, 148] for an image of height 180, got 170"),
    ],
)
def test_horizon_row_is_a_row_and_is_checked(dataset, tmp_path, capsys, row: str, message: str) -> None:
    assert main([str(dataset), "--cache", str(tmp_path / "c"), "--horizon-row", row, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
