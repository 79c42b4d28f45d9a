"""``stamlane-eval`` command line: happy paths, --json, --per-image, and every bad input -> one line, exit 2."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from stamlane_eval import tusimple
from stamlane_eval.cli import main

GOLDEN = Path(__file__).parent / "golden"
TS_PRED, TS_GT = GOLDEN / "tusimple_pred.json", GOLDEN / "tusimple_gt.json"
CU = GOLDEN / "culane"
H56 = list(range(160, 720, 10))


def _run(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_tusimple_table_json_and_per_image(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    exp = json.loads((GOLDEN / "tusimple_expected.json").read_text())
    code, out, err = _run(capsys, "tusimple", TS_PRED, TS_GT)
    assert code == 0 and err.count("\n") == 1 and "1 of 22 images" in err  # the image at 200.001 ms, said once
    assert "accuracy %" in out and f"{100 * exp['totals']['accuracy']:.2f}" in out  # percent, like the papers
    code, out, _ = _run(capsys, "tusimple", TS_PRED, TS_GT, "--json", "--per-image", tmp_path / "per.jsonl")
    res = json.loads(out)
    assert code == 0
    assert {"accuracy", "fp", "fn", "f1", "images"} <= set(res)
    assert (res["accuracy"], res["fp"], res["fn"]) == tuple(exp["totals"][k] for k in ("accuracy", "fp", "fn"))
    rows = [json.loads(x) for x in (tmp_path / "per.jsonl").read_text().splitlines()]
    assert [(r["acc"], r["fp"], r["fn"]) for r in rows] == [(p["acc"], p["fp"], p["fn"]) for p in exp["per_image"]]
    assert rows[0]["raw_file"] == exp["per_image"][0]["raw_file"]


def test_tusimple_without_the_time_limit(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """--no-time-limit scores the golden set's image timed at 200.001 ms on its lanes; every other image as before."""
    exp = json.loads((GOLDEN / "tusimple_expected.json").read_text())
    code, _, err = _run(capsys, "tusimple", TS_PRED, TS_GT, "--no-time-limit", "--per-image", tmp_path / "per.jsonl")
    assert code == 0 and err == ""  # nothing scored as missed for its time: nothing to warn about
    rows = [json.loads(x) for x in (tmp_path / "per.jsonl").read_text().splitlines()]
    preds = [json.loads(x) for x in TS_PRED.read_text().splitlines()]
    gts = {g["raw_file"]: g for g in map(json.loads, TS_GT.read_text().splitlines())}
    late = [i for i, p in enumerate(preds) if p["run_time"] > tusimple.MAX_RUN_TIME_MS]
    assert len(late) == 1
    for i, (row, p, e) in enumerate(zip(rows, preds, exp["per_image"], strict=True)):
        if i in late:
            g = gts[p["raw_file"]]
            on_lanes = tusimple.evaluate_image(p["lanes"], g["lanes"], g["h_samples"], run_time=0.0)
            assert (row["acc"], row["fp"], row["fn"]) == (on_lanes.acc, on_lanes.fp, on_lanes.fn)
            assert (row["acc"], row["fn"]) != (e["acc"], e["fn"])  # the rule had scored it as missed
        else:
            assert (row["acc"], row["fp"], row["fn"]) == (e["acc"], e["fp"], e["fn"])


def test_tusimple_late_images_are_warned_in_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """The 200 ms rule, kept, and said: one line with the count and the flag; --json carries the count."""
    preds = [{**PRED_REC, "raw_file": f"{i}.jpg", "run_time": 250 if i % 2 else 5} for i in range(40)]
    gts = [{**GT_REC, "raw_file": f"{i}.jpg"} for i in range(40)]
    p, g = _write(tmp_path / "pred.json", preds), _write(tmp_path / "gt.json", gts)
    code, out, err = _run(capsys, "tusimple", p, g, "--json")
    assert code == 0 and err.count("\n") == 1
    assert "20 of 40 images" in err and "200 ms" in err and "--no-time-limit" in err and str(p) in err
    res = json.loads(out)
    assert res["late_images"] == 20 and res["accuracy"] == 0.5  # scored as missed, as lane.py does
    code, out, err = _run(capsys, "tusimple", p, g, "--json", "--no-time-limit")
    assert code == 0 and err == ""
    assert json.loads(out)["late_images"] == 20 and json.loads(out)["accuracy"] == 1.0


def test_tusimple_swapped_files_are_named(capsys: pytest.CaptureFixture[str]) -> None:
    """GT PRED instead of PRED GT: one line naming the order, exit 2 (never a valid input: PRED needs run_time)."""
    code, out, err = _run(capsys, "tusimple", TS_GT, TS_PRED)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "look swapped" in err and "PRED GT" in err and str(TS_GT) in err
    code, _, err = _run(capsys, "culane", TS_GT, TS_PRED, "--size", "1280x720")  # the culane metric on json
    assert code == 2 and "look swapped" in err and "--as-given" in err
    code, _, err = _run(capsys, "culane", TS_GT, TS_PRED, "--size", "1280x720", "--as-given")
    assert code == 2 and "look swapped" not in err and "h_samples" in err  # read as given: the pred has no rows


def test_a_frame_labels_list_is_pointed_to_the_video_command(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """The generator's ``frame_labels/<clip>.json`` is one JSON list of records, which lane.py cannot read either:
    refused in one line that names the command that reads it."""
    records = [json.loads(line) for line in TS_GT.read_text().splitlines()[:3]]
    labels = tmp_path / "challenging-0000.json"
    labels.write_text(json.dumps(records))
    code, out, err = _run(capsys, "tusimple", TS_PRED, str(labels))
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "a list of records" in err and "stamlane-eval video" in err
    labels.write_text(json.dumps([[1, 2]]))  # any other list: no such hint
    code, _, err = _run(capsys, "tusimple", TS_PRED, str(labels))
    assert code == 2 and "expected a JSON object, got list" in err and "stamlane-eval video" not in err


def test_culane_swapped_folders_are_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A dataset root (images beside the .lines.txt) given as PRED and a prediction folder as GT: refused in one
    line (P and R would be exchanged silently); --as-given scores them as given; the right order is unchanged."""
    root = tmp_path / "culane"
    shutil.copytree(CU / "anno", root)
    for lines in root.rglob("*.lines.txt"):
        (lines.parent / (lines.name[: -len(".lines.txt")] + ".jpg")).write_bytes(b"")
    code, out, err = _run(capsys, "culane", root, CU / "pred", "--list", CU / "list.txt")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "look swapped" in err and "PRED_DIR GT_DIR" in err and "--as-given" in err
    code, _, err = _run(capsys, "culane", root, CU / "pred")  # without a list too
    assert code == 2 and "look swapped" in err
    code, right, _ = _run(capsys, "culane", CU / "pred", root, "--list", CU / "list.txt", "--json")
    code2, plain, _ = _run(capsys, "culane", CU / "pred", CU / "anno", "--list", CU / "list.txt", "--json")
    assert code == code2 == 0 and json.loads(right) == json.loads(plain)
    code, given, _ = _run(capsys, "culane", root, CU / "pred", "--list", CU / "list.txt", "--json", "--as-given")
    swapped, normal = json.loads(given)["0.5"], json.loads(plain)["0.5"]
    assert code == 0 and (swapped["fp"], swapped["fn"]) == (normal["fn"], normal["fp"])


@pytest.mark.parametrize("variant", ["official", "lanedet"])
def test_culane_json_and_per_image(capsys: pytest.CaptureFixture[str], tmp_path: Path, variant: str) -> None:
    exp = json.loads((CU / "expected.json").read_text())["per_image"]
    key = "cpp" if variant == "official" else "lanedet"
    argv = ["culane", CU / "pred", CU / "anno", "--list", CU / "list.txt", "--variant", variant, "--json"]
    code, out, _ = _run(capsys, *argv, "--per-image", tmp_path / "per.jsonl")
    assert code == 0
    res = json.loads(out)
    assert set(res) == {"0.3", "0.5", "images"} and res["images"] == len(exp)
    for t in ("0.3", "0.5"):
        assert res[t]["tp"] == sum(p[key][t][0] for p in exp)
        assert res[t]["fp"] == sum(p[key][t][1] for p in exp)
        assert res[t]["fn"] == sum(p[key][t][2] for p in exp)
    rows = [json.loads(x) for x in (tmp_path / "per.jsonl").read_text().splitlines()]
    assert [r["0.5"] for r in rows] == [p[key]["0.5"] for p in exp]


def test_culane_without_list_missing_prediction_and_table(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    shutil.copytree(CU / "pred", tmp_path / "pred")
    missing = tmp_path / "pred" / "driver_edge" / "edge.MP4" / "00000.lines.txt"
    missing.unlink()  # a missing prediction file means no lanes
    code, out, _ = _run(capsys, "culane", tmp_path / "pred", CU / "anno", "--json", "--iou", "0.5")
    res = json.loads(out)
    assert code == 0 and set(res) == {"0.5", "images"}
    exp = json.loads((CU / "expected.json").read_text())["per_image"]
    assert res["0.5"]["tp"] == sum(p["cpp"]["0.5"][0] for p in exp) - 4
    code, out, _ = _run(capsys, "apollo", CU / "pred", CU / "anno", "--width", "10", "--size", "1640x590")
    assert code == 0 and "apollo (official)" in out and "F1" in out


def test_culane_scores_tusimple_files(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(capsys, "culane", TS_PRED, TS_GT, "--size", "1280x720", "--json")
    assert code == 0 and json.loads(out)["images"] == 22
    code, _, err = _run(capsys, "culane", TS_PRED, TS_GT)
    assert code == 2 and "--size" in err


def _write(path: Path, lines: list[object]) -> Path:
    path.write_text("".join((x if isinstance(x, str) else json.dumps(x)) + "\n" for x in lines))
    return path


GT_REC = {"raw_file": "a.jpg", "lanes": [[300] * 56], "h_samples": H56}
PRED_REC = {"raw_file": "a.jpg", "lanes": [[300] * 56], "run_time": 5}

TUSIMPLE_BAD = {
    "malformed_json": ([PRED_REC, "{oops"], [GT_REC, {**GT_REC, "raw_file": "b.jpg"}], "pred", "line 2"),
    "missing_key": ([{"raw_file": "a.jpg", "lanes": []}], [GT_REC], "pred", "run_time"),
    "gt_missing_key": ([PRED_REC], [{"raw_file": "a.jpg", "lanes": []}], "gt", "h_samples"),
    "lane_length": ([{**PRED_REC, "lanes": [[300] * 55]}], [GT_REC], "pred", "Format of lanes error"),
    "gt_lane_length": (
        [PRED_REC],
        [{**GT_REC, "lanes": [[300] * 50]}],
        "gt",
        "lane 0 has 50 x values, h_samples has 56",
    ),
    "nan": (['{"raw_file": "a.jpg", "lanes": [[NaN]], "run_time": 1}'], [GT_REC], "pred", "line 1"),
    "null_values": ([{**PRED_REC, "lanes": [[None] * 56]}], [GT_REC], "pred", "Format of lanes error"),
    "unknown_raw_file": ([{**PRED_REC, "raw_file": "z.jpg"}], [GT_REC], "pred", "do not exist"),
    "duplicate_raw_file": (
        [PRED_REC, PRED_REC],
        [GT_REC, {**GT_REC, "raw_file": "b.jpg"}],
        "pred",
        "duplicate prediction",
    ),
    "count_mismatch": ([PRED_REC], [GT_REC, {**GT_REC, "raw_file": "b.jpg"}], "pred", "predictions of all"),
    "empty_file": ([], [GT_REC], "pred", "empty file"),
    "blank_line": ([PRED_REC, ""], [GT_REC], "pred", "blank"),
    "not_an_object": (["[1, 2]"], [GT_REC], "pred", "JSON object"),
}


@pytest.mark.parametrize("case", sorted(TUSIMPLE_BAD))
def test_tusimple_bad_input(capsys: pytest.CaptureFixture[str], tmp_path: Path, case: str) -> None:
    preds, gts, culprit, words = TUSIMPLE_BAD[case]
    p, g = _write(tmp_path / "pred.json", preds), _write(tmp_path / "gt.json", gts)
    if not preds:
        p.write_text("")
    code, out, err = _run(capsys, "tusimple", p, g)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert str(p if culprit == "pred" else g) in err and words in err, err


def test_tusimple_unreadable_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, _, err = _run(capsys, "tusimple", tmp_path / "nope.json", TS_GT)
    assert code == 2 and "nope.json" in err and len(err.strip().splitlines()) == 1
    code, _, err = _run(capsys, "tusimple", tmp_path, TS_GT)  # a directory
    assert code == 2 and "cannot read" in err


def _culane_tree(tmp_path: Path, pred_text: str, gt_text: str = "10 500 20 400 30 300\n") -> tuple[Path, Path]:
    for sub, text in (("pred", pred_text), ("anno", gt_text)):
        (tmp_path / sub / "d").mkdir(parents=True)
        (tmp_path / sub / "d" / "0.lines.txt").write_text(text)
    return tmp_path / "pred", tmp_path / "anno"


@pytest.mark.parametrize(
    ("gt_text", "words"),
    [("10 500 20\n", "odd number"), ("10 500 abc 400\n", "not a finite number"), ("10 500 nan 400\n", "not a finite")],
)
def test_culane_bad_labels(capsys: pytest.CaptureFixture[str], tmp_path: Path, gt_text: str, words: str) -> None:
    """A label is checked (a prediction with the same text is read as the C++ tool reads it: test_hostile_eval)."""
    pred, gt = _culane_tree(tmp_path, "10 500 20 400\n", gt_text)
    code, out, err = _run(capsys, "culane", pred, gt)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "0.lines.txt" in err and words in err and "line 1" in err


def test_culane_bad_setup(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    pred, gt = _culane_tree(tmp_path, "10 500 20 400\n")
    (tmp_path / "list.txt").write_text("/d/0.jpg\n/d/missing.jpg\n")
    cases = [
        (["culane", pred, gt, "--list", tmp_path / "list.txt"], "missing.lines.txt"),  # gt file missing
        (["culane", pred, tmp_path / "nodir"], "not a directory"),
        (["culane", pred, gt, "--list", tmp_path / "nolist.txt"], "nolist.txt"),
        (["culane", pred, gt, "--size", "12"], "WxH"),
        (["culane", pred, gt, "--iou", "1.5"], "IoU"),
        (["culane", pred, gt, "--variant", "cpp"], "variant"),
        (["culane", pred, gt, "--width", "0"], "positive"),
        (["culane", pred, tmp_path / "empty"], "no .lines.txt"),
        (["nosuch"], "invalid choice"),
    ]
    (tmp_path / "empty").mkdir()
    for argv, words in cases:
        code, out, err = _run(capsys, *argv)
        assert code == 2 and out == "", argv
        assert len(err.strip().splitlines()) == 1 and words in err and "Traceback" not in err, (argv, err)


def test_official_format_is_what_the_official_tools_print(capsys: pytest.CaptureFixture[str]) -> None:
    """``--format official``: lane.py's JSON line byte for byte; the C++ tool's -o text per IoU threshold."""
    shared = Path(__file__).resolve().parents[3] / "shared" / "fixtures" / "evaluators"
    if not shared.is_dir():
        pytest.skip(f"the official tools' outputs are not here ({shared} is absent)")
    expected = json.loads((shared / "tusimple" / "expected.json").read_text())
    code, out, _ = _run(
        capsys, "tusimple", shared / "tusimple" / "pred.json", shared / "tusimple" / "gt.json", "--format", "official"
    )
    assert code == 0 and out == expected["official_output"] + "\n"
    cu = shared / "culane"
    cpp = json.loads((cu / "expected.json").read_text())["cpp_output_file"]
    code, out, _ = _run(capsys, "culane", cu / "pred", cu / "anno", "--list", cu / "list.txt", "--format", "official")
    want = "\n".join(cpp[t].split("\n", 1)[1].rstrip("\n") + "\n" for t in ("0.3", "0.5"))  # without "file:"
    assert code == 0 and out == want
    code, _, err = _run(capsys, "video", cu / "pred", cu / "anno", "--format", "official")
    assert code == 2 and "invalid choice" in err


def test_list_entries_never_leave_the_folders(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    pred, gt = _culane_tree(tmp_path, "10 500 20 400\n")
    (tmp_path / "secret.lines.txt").write_text("10 500 20 400\n")  # beside, not inside, the annotation folder
    for entry in ("../secret.jpg", "/d/../../secret.jpg", "d/..\\..\\secret.jpg"):
        (tmp_path / "list.txt").write_text(f"/d/0.jpg\n{entry}\n")
        code, out, err = _run(capsys, "culane", pred, gt, "--list", tmp_path / "list.txt")
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, entry
        assert "leaves the folder" in err and "Traceback" not in err


def test_outputs_never_overwrite_inputs(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    gt = tmp_path / "gt.json"
    shutil.copy(TS_GT, gt)
    before = gt.read_bytes()
    link = tmp_path / "link.json"
    link.symlink_to(gt)
    for target in (gt, link):
        code, _, err = _run(capsys, "tusimple", TS_PRED, gt, "--per-image", target)
        assert code == 2 and "would overwrite or write into the input" in err and len(err.strip().splitlines()) == 1
    assert gt.read_bytes() == before
    pred, anno = _culane_tree(tmp_path / "cu", "10 500 20 400\n")
    code, _, err = _run(capsys, "culane", pred, anno, "--per-image", pred / "d" / "per_image.jsonl")
    assert code == 2 and "write into the input" in err


def test_console_script_runs() -> None:
    exe = Path(sys.executable).with_name("stamlane-eval")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "stamlane_eval.cli"]
    ok = subprocess.run([*cmd, "tusimple", str(TS_PRED), str(TS_GT), "--json"], capture_output=True, text=True)
    assert ok.returncode == 0 and "accuracy" in json.loads(ok.stdout)
    bad = subprocess.run([*cmd, "tusimple", str(TS_PRED), "/nonexistent.json"], capture_output=True, text=True)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "Traceback" not in bad.stderr


def test_documented_limits_are_one_line_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    from stamlane_eval.io import MAX_IMAGE_POINTS, MAX_IMAGE_SIDE, MAX_LANE_WIDTH, MAX_LANES

    long_lane = " ".join(f"{i % 1000} {i % 500}" for i in range(MAX_IMAGE_POINTS + 1)) + "\n"
    many_lanes = "10 500 20 400\n" * (MAX_LANES + 1)
    nested = tmp_path / "nested.json"
    nested.write_text("[" * 100000 + "]" * 100000 + "\n")
    cases = [
        (lambda: _culane_tree(tmp_path / "a", long_lane), [], f"more than {MAX_IMAGE_POINTS} points"),
        (lambda: _culane_tree(tmp_path / "b", many_lanes), [], f"more than {MAX_LANES} lanes"),
        (lambda: _culane_tree(tmp_path / "c", "10 500 20 400\n"), ["--width", str(MAX_LANE_WIDTH + 1)], "lane width"),
        (lambda: _culane_tree(tmp_path / "d", "10 500 20 400\n"), ["--size", f"{MAX_IMAGE_SIDE + 1}x10"], "sides in"),
    ]
    for make, extra, words in cases:
        pred, gt = make()
        code, out, err = _run(capsys, "culane", pred, gt, *extra)
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and words in err, (words, err)
    code, _, err = _run(capsys, "tusimple", nested, TS_GT)
    assert code == 2 and "nested too deeply" in err and len(err.strip().splitlines()) == 1


def test_a_vil100_frame_of_absurd_size_is_refused(tmp_path: Path) -> None:
    from stamlane_eval.io import LaneFileError, read_vil100_json

    path = tmp_path / "0.jpg.json"
    path.write_text(json.dumps({"info": {"width": 200000, "height": 200000}, "annotations": {"lane": []}}))
    with pytest.raises(LaneFileError, match=r"outside 1\.\.16384"):
        read_vil100_json(path)
