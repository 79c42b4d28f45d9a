"""`stamlane_eval.io`, one module per format: every name it exported as one module is still exported, each format
has its module, and the package's one atomic writer and one path-inside-root check."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from stamlane_eval import io, video
from stamlane_eval.io import files, limits
from stamlane_eval.io import tusimple as tusimple_io

GOLDEN = Path(__file__).parent / "golden"

EXPORTED_BEFORE = (
    "MAX_COORDINATE MAX_DRAWN_PIXELS MAX_FILE_BYTES MAX_IMAGE_POINTS MAX_IMAGE_SIDE MAX_LANES MAX_LANE_POINTS "
    "MAX_LANE_WIDTH TUSIMPLE_SUFFIXES CanvasBudget Inside LaneFileError TuSimpleFile TuSimpleFrames "
    "TuSimpleInputError check_image_size check_tusimple cpp_stream_doubles culane_entries culane_lines_path "
    "duplicate_raw_file inside iter_tusimple read_culane_lines read_text read_tusimple read_tusimple_frames "
    "read_vil100_json tusimple_frame_key tusimple_lanes tusimple_points tusimple_record_error video_frames"
).split()
"""``stamlane_eval.io.__all__`` when it was one module: users and stamlane import these from it."""


def test_every_name_the_single_module_exported_is_still_exported() -> None:
    assert set(EXPORTED_BEFORE) <= set(io.__all__)
    assert len(set(io.__all__)) == len(io.__all__)  # built from the modules' own lists: no name twice
    for name in io.__all__:
        assert getattr(io, name) is not None, name


@pytest.mark.parametrize(
    ("name", "module"),
    [
        ("read_tusimple", "tusimple"),
        ("check_tusimple", "tusimple"),
        ("lane_py_line", "tusimple"),
        ("read_culane_lines", "culane"),
        ("culane_entries", "culane"),
        ("cpp_tool_text", "culane"),
        ("read_vil100_json", "vil100"),
        ("video_frames", "video"),
        ("read_tusimple_frames", "video"),
        ("read_video", "video"),
        ("Frame", "video"),
        ("read_text", "files"),
        ("inside", "files"),
        ("write_atomic", "files"),
        ("CanvasBudget", "limits"),
        ("check_image_size", "limits"),
    ],
)
def test_each_name_lives_in_the_module_of_its_format(name: str, module: str) -> None:
    assert getattr(io, name).__module__ == f"stamlane_eval.io.{module}"


def test_the_video_metrics_take_the_frames_the_readers_give() -> None:
    assert video.Frame is io.Frame


def test_what_the_official_tools_print() -> None:
    assert (
        io.cpp_tool_text(811, 80, 71)
        == "tp: 811 fp: 80 fn: 71\nprecision: 0.910213\nrecall: 0.919501\nFmeasure: 0.914834\n"
    )
    assert io.cpp_tool_text(0, 0, 0).endswith("precision: -1\nrecall: -1\nFmeasure: -1\n")  # both 0/0: -1
    assert io.cpp_tool_text(0, 3, 2).endswith("Fmeasure: -nan\n")  # 0.0 / 0.0, printed by glibc


def test_what_lane_py_prints(shared_dir: Path) -> None:
    want = json.loads((shared_dir / "fixtures" / "evaluators" / "tusimple" / "expected.json").read_text())
    t = want["totals"]
    assert io.lane_py_line(t["accuracy"], t["fp"], t["fn"]) == want["official_output"]  # byte for byte


# -------------------------------------------------------------------------------- the atomic writer
def test_write_atomic_replaces_the_whole_file_or_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "per.jsonl"
    out.write_text("old\n")
    files.write_jsonl(out, [{"a": 1}, {"b": [2, 3]}])
    assert out.read_text() == '{"a": 1}\n{"b": [2, 3]}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["per.jsonl"]  # no temporary left

    def fail(src: object, dst: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(io.LaneFileError, match=r"per\.jsonl: cannot write: .*No space left"):
        files.write_atomic(out, "new\n")
    assert out.read_text() == '{"a": 1}\n{"b": [2, 3]}\n'  # the old file, whole
    assert [p.name for p in tmp_path.iterdir()] == ["per.jsonl"]
    monkeypatch.undo()
    with pytest.raises(io.LaneFileError, match="cannot write"):
        files.write_atomic(tmp_path / "missing" / "out.txt", "x")


def test_write_atomic_never_writes_into_an_input(tmp_path: Path) -> None:
    from stamlane_eval.cli_tools import OutputError

    with pytest.raises(OutputError, match="would overwrite or write into the input"):
        files.write_atomic(tmp_path / "out.txt", "x", inputs=[tmp_path])  # its temporary would lie in the input
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------ the path-inside-root check
def test_inside_is_the_one_check_of_a_path_in_its_root(tmp_path: Path) -> None:
    root, elsewhere = tmp_path / "pred", tmp_path / "secret.txt"
    (root / "v").mkdir(parents=True)
    elsewhere.write_text("1 2 3 4\n")
    (root / "v" / "ok.lines.txt").write_text("1 2 3 4\n")
    (root / "v" / "bad.lines.txt").symlink_to(elsewhere)
    (root / "link").symlink_to(tmp_path)
    check = files.Inside(root)
    for path in (root / "v" / "ok.lines.txt", root / "v" / "missing.lines.txt", root / "link" / "pred" / "v"):
        assert files.inside(path, root) == check(path) == path
    for path in (root / "v" / "bad.lines.txt", root / "link" / "secret.txt", root / "v" / ".." / ".."):
        with pytest.raises(io.LaneFileError) as one:
            files.inside(path, root)
        with pytest.raises(io.LaneFileError) as many:
            check(path)
        assert str(one.value) == str(many.value) == f"{path}: a link to {path.resolve()}, outside the folder {root}"


# ------------------------------------------------------------------------------ formats into frames
def test_read_video_gives_the_frames_of_the_golden_set(tmp_path: Path) -> None:
    base = GOLDEN / "temporal"
    sizes = json.loads((base / "sizes.json").read_text())
    (tmp_path / "sizes.json").write_text(json.dumps({e: f"{w}x{h}" for e, (h, w) in sizes.items()}))
    found = io.read_video(base / "pred", base / "anno", list_file=base / "list.txt", sizes=tmp_path / "sizes.json")
    entries = (base / "list.txt").read_text().split()
    assert found.frames == len(entries) == 113 and found.predicted == 113 and not found.tusimple_pred
    frames = [(seq, i, f) for seq, fs in found.sequences.items() for i, f in enumerate(fs)]
    for entry, (seq, _, frame) in zip(entries, frames, strict=True):
        assert entry.rsplit("/", 1)[0] == seq and frame.size == tuple(sizes[entry])
        want = io.read_culane_lines(base / "anno" / f"{entry}.lines.txt")
        assert [lane.tolist() for lane in frame.target] == [lane.tolist() for lane in want]
    assert io.read_sizes(None) == {} and io.is_tusimple_input(GOLDEN / "tusimple_gt.json")
    assert not io.is_tusimple_input(base / "anno")


def test_tusimple_files_as_lanes_per_image() -> None:
    preds = tusimple_io.read_tusimple(GOLDEN / "tusimple_pred.json")
    gts = tusimple_io.read_tusimple(GOLDEN / "tusimple_gt.json")
    names, pred_lanes, gt_lanes = io.tusimple_lanes_by_image(preds, gts, "pred.json", "gt.json")
    assert names == [g["raw_file"] for g in gts] and len(pred_lanes) == len(gt_lanes) == 22
    by_name = {p["raw_file"]: p for p in preds}
    for name, lanes, g in zip(names, pred_lanes, gts, strict=True):
        want = io.tusimple_points(by_name[name]["lanes"], g["h_samples"])
        assert [lane.tolist() for lane in lanes] == [lane.tolist() for lane in want]
    assert limits.MAX_IMAGE_SIDE == io.MAX_IMAGE_SIDE == 16384
