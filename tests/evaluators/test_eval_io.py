"""Readers: the official tools' reading rules and clear errors."""

from __future__ import annotations

from pathlib import Path

import pytest
from stamlane_eval.io import LaneFileError, culane_entries, culane_lines_path, read_culane_lines, read_tusimple


def test_culane_reader_keeps_blank_lines_as_empty_lanes(tmp_path: Path) -> None:
    f = tmp_path / "a.lines.txt"
    f.write_text("1 2 3 4\n   \n5.5 6\n")
    lanes = read_culane_lines(f)
    assert [lane.shape for lane in lanes] == [(2, 2), (0, 2), (1, 2)]  # the C++ counts every line as a lane
    assert lanes[2].tolist() == [[5.5, 6.0]]
    assert read_culane_lines(tmp_path / "missing.lines.txt") == []  # a missing prediction: no lanes
    with pytest.raises(LaneFileError, match="no such file"):
        read_culane_lines(tmp_path / "missing.lines.txt", missing_ok=False)


def test_culane_paths_and_entries(tmp_path: Path) -> None:
    assert culane_lines_path(tmp_path, "/d/v.MP4/001.jpg") == tmp_path / "d" / "v.MP4" / "001.lines.txt"
    assert culane_lines_path(tmp_path, "/d/v.MP4/001.lines.txt") == tmp_path / "d" / "v.MP4" / "001.lines.txt"
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "b.lines.txt").write_text("")
    (tmp_path / "d" / "a.lines.txt").write_text("")
    assert culane_entries(tmp_path) == ["/d/a.lines.txt", "/d/b.lines.txt"]
    (tmp_path / "list.txt").write_text("\n")
    with pytest.raises(LaneFileError, match="empty list"):
        culane_entries(tmp_path, tmp_path / "list.txt")
    (tmp_path / "list.txt").write_bytes(b"\x00\x01\n")  # a binary file given as the list
    with pytest.raises(LaneFileError, match="holds a NUL byte: not a path"):
        culane_entries(tmp_path, tmp_path / "list.txt")
    (tmp_path / "list.txt").write_text("/d/a.jpg\n/d/b.jpg\nd/a.lines.txt\n")  # the same image, written twice
    with pytest.raises(LaneFileError, match=r"entries 1 and 3 name the same image .*two results for one image"):
        culane_entries(tmp_path, tmp_path / "list.txt")


def test_tusimple_reader(tmp_path: Path) -> None:
    f = tmp_path / "p.json"
    f.write_text('{"a": 1}\n{"a": 2}')  # no final newline is fine
    assert read_tusimple(f) == [{"a": 1}, {"a": 2}]
    f.write_text('{"a": 1}\n\n{"a": 2}\n')
    with pytest.raises(LaneFileError, match="line 2 is blank"):
        read_tusimple(f)
    f.write_text('{"a": Infinity, "b": NaN}\n')  # numbers to lane.py's ujson; check_tusimple says where they may stand
    rec = read_tusimple(f)[0]
    assert rec["a"] == float("inf") and rec["b"] != rec["b"]
    f.write_bytes(b"\xff\xfe\n")
    with pytest.raises(LaneFileError, match="cannot read"):
        read_tusimple(f)
    f.write_text('{"raw_file": "a", "lanes": [[1, false]], "run_time": 1}\n')  # lane.py would read 0
    with pytest.raises(LaneFileError, match=r"line 1: a boolean .true/false. where a number belongs"):
        read_tusimple(f)
    f.write_text('{"raw_file": "a/true/1.jpg", "lanes": [[1, 2]], "run_time": 1}\n')  # the word, not a boolean
    assert read_tusimple(f)[0]["lanes"] == [[1, 2]]
