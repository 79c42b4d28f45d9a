"""Hostile input to every ``stamlane-eval`` command: the right number or one line and exit 2; no traceback, no
hang on a special file, nothing read outside the folders given, no input overwritten. One property-based test per
command feeds it malformed files."""

from __future__ import annotations

import json
import os
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from stamlane_eval.cli import main
from stamlane_eval.io import MAX_FILE_BYTES, MAX_LANES

GOLDEN = Path(__file__).parent / "golden"
TS_PRED, TS_GT = GOLDEN / "tusimple_pred.json", GOLDEN / "tusimple_gt.json"
LANE = "10 500 20 400 30 300\n"


@pytest.fixture
def no_hang() -> Iterator[None]:
    def fail(*_: object) -> None:
        raise TimeoutError("the command blocked on a special file")

    previous = signal.signal(signal.SIGALRM, fail)
    signal.alarm(30)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _run(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _refused(capsys: pytest.CaptureFixture[str], *argv: object) -> str:
    code, out, err = _run(capsys, *argv)
    assert code == 2 and out == "", (argv, err)
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err


def _tree(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return root


def _special(tmp_path: Path, kind: str) -> Path:
    if kind == "fifo":
        os.mkfifo(tmp_path / "fifo")
        return tmp_path / "fifo"
    if kind == "device":
        return Path("/dev/zero")
    (tmp_path / "folder").mkdir()
    return tmp_path / "folder"


@pytest.mark.parametrize("kind", ["fifo", "device", "folder"])
def test_special_files_are_refused_unread(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], no_hang: None, kind: str
) -> None:
    special = _special(tmp_path, kind)
    _refused(capsys, "tusimple", special, TS_GT)
    _refused(capsys, "tusimple", TS_PRED, special)
    pred = _tree(tmp_path / "pred", {"d/0.lines.txt": LANE})
    gt = _tree(tmp_path / "gt", {"d/0.lines.txt": LANE})
    _refused(capsys, "culane", pred, gt, "--list", special)
    if kind != "folder":
        _refused(capsys, "culane", special, gt)  # a file where a folder is expected
    link = gt / "d" / "1.lines.txt"  # a special file among the annotations (a link: still refused, unread)
    link.symlink_to(special)
    (tmp_path / "list.txt").write_text("/d/0.jpg\n/d/1.jpg\n")
    err = _refused(capsys, "culane", pred, gt, "--list", tmp_path / "list.txt")
    assert "1.lines.txt" in err or "outside the folder" in err
    link.unlink()
    (pred / "d" / "0.lines.txt").unlink()
    (pred / "d" / "0.lines.txt").symlink_to(special)
    _refused(capsys, "apollo", pred, gt, "--size", "1640x590")


def test_links_never_lead_outside_the_folders(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A prediction or annotation that is a link to a file elsewhere (a hostile archive) is refused, and its
    content never quoted in the error."""
    secret = tmp_path / "secret.txt"
    secret.write_text("the secret 12 34\n")
    pred = _tree(tmp_path / "pred", {"d/0.lines.txt": LANE})
    gt = _tree(tmp_path / "gt", {"d/0.lines.txt": LANE})
    (pred / "d" / "1.lines.txt").symlink_to(secret)
    (gt / "d" / "1.lines.txt").write_text(LANE)
    err = _refused(capsys, "culane", pred, gt)
    assert "outside the folder" in err and "secret 12" not in err
    (pred / "d" / "1.lines.txt").unlink()
    (gt / "d" / "1.lines.txt").unlink()
    (gt / "d" / "1.lines.txt").symlink_to(secret)
    err = _refused(capsys, "video", pred, gt, "--size", "1640x590")
    assert "outside the folder" in err and "secret 12" not in err


def test_inputs_are_never_overwritten(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt = tmp_path / "gt.json"
    gt.write_bytes(TS_GT.read_bytes())
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "per.jsonl").symlink_to(gt)  # an output name that is a link to the input
    for target in (gt, tmp_path / "out" / "per.jsonl", tmp_path):
        err = _refused(capsys, "tusimple", TS_PRED, gt, "--per-image", target)
        assert "would overwrite or write into the input" in err or "is a folder" in err
    assert gt.read_bytes() == TS_GT.read_bytes()


def test_huge_files_are_refused_by_size(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    big = tmp_path / "big.json"
    with open(big, "wb") as f:  # sparse: the size is declared, nothing is written
        f.truncate(MAX_FILE_BYTES + 1)
    assert "larger than the limit" in _refused(capsys, "tusimple", big, TS_GT)


def test_zero_denominators_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pred = _tree(tmp_path / "pred", {"d/0.lines.txt": ""})
    gt = _tree(tmp_path / "gt", {"d/0.lines.txt": LANE})
    assert "precision is 0/0" in _refused(capsys, "culane", pred, gt)
    empty_gt = _tree(tmp_path / "gt2", {"d/0.lines.txt": ""})
    assert "recall is 0/0" in _refused(capsys, "culane", gt, empty_gt)


SETTINGS = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
_LINES = TS_PRED.read_text().splitlines()
_JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
    max_leaves=6,
)


def _mutate(text: str, data: st.DataObject) -> str:
    """One hostile edit of a json-lines file: cut it, flip a byte, replace a value, drop or double a line."""
    how = data.draw(st.sampled_from(["cut", "byte", "value", "key", "line"]))
    if how == "cut":
        return text[: data.draw(st.integers(0, len(text)))]
    if how == "byte":
        i = data.draw(st.integers(0, len(text) - 1))
        return text[:i] + data.draw(st.characters()) + text[i + 1 :]
    lines = text.splitlines()
    k = data.draw(st.integers(0, len(lines) - 1))
    if how == "line":
        lines.insert(k, lines[k]) if data.draw(st.booleans()) else lines.pop(k)
        return "\n".join(lines) + "\n"
    rec = json.loads(lines[k])
    key = data.draw(st.sampled_from(sorted(rec)))
    if how == "key":
        del rec[key]
    elif key == "lanes" and rec["lanes"] and data.draw(st.booleans()):
        lane = rec["lanes"][data.draw(st.integers(0, len(rec["lanes"]) - 1))]
        lane[data.draw(st.integers(0, len(lane) - 1))] = data.draw(_JSON_VALUES)
    else:
        rec[key] = data.draw(_JSON_VALUES)
    lines[k] = json.dumps(rec)
    return "\n".join(lines) + "\n"


@SETTINGS
@given(st.data(), st.booleans())
def test_tusimple_malformed_files(
    tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], data: st.DataObject, gt_side: bool
) -> None:
    """Property: a mutated prediction or ground-truth file is scored (exit 0, at most one warning line) or
    refused in one line (exit 2); never a traceback."""
    folder = tmp_path_factory.mktemp("ts")
    pred, gt = folder / "pred.json", folder / "gt.json"
    pred.write_text("\n".join(_LINES) + "\n")
    gt.write_text(TS_GT.read_text())
    target = gt if gt_side else pred
    target.write_text(_mutate(target.read_text(), data), encoding="utf-8", errors="surrogatepass")
    code, out, err = _run(capsys, "tusimple", pred, gt, "--json")
    assert "Traceback" not in err and len(err.strip().splitlines()) <= 1, err
    if code == 0:
        res = json.loads(out)
        assert all(-1e-9 <= res[k] <= 1 + 1e-9 for k in ("accuracy", "fp", "fn")), res
    else:
        assert code == 2 and out == "" and err.strip(), err


_LINES_TEXT = st.text(alphabet="0123456789 .-+eEnaif_\t\r\n", max_size=80)


@SETTINGS
@given(st.lists(st.tuples(_LINES_TEXT, _LINES_TEXT), min_size=1, max_size=3), st.sampled_from(["culane", "apollo"]))
def test_culane_malformed_files(
    tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], images: list, command: str
) -> None:
    """Property: random text as prediction and annotation files: the official counts or one line, exit 2."""
    folder = tmp_path_factory.mktemp("cu")
    for i, (p, g) in enumerate(images):
        _tree(folder / "pred", {f"d/{i}.lines.txt": p})
        _tree(folder / "gt", {f"d/{i}.lines.txt": g})
    code, out, err = _run(capsys, command, folder / "pred", folder / "gt", "--json", "--size", "640x360")
    assert "Traceback" not in err and len(err.strip().splitlines()) <= 1, err
    if code == 0:
        res = json.loads(out)
        assert res["images"] == len(images) and all(0 <= res[t]["f1"] <= 1 for t in ("0.3", "0.5"))
    else:
        assert code == 2 and out == "", err


@SETTINGS
@given(st.lists(_JSON_VALUES, min_size=1, max_size=3), _LINES_TEXT)
def test_video_malformed_files(
    tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], frames: list, pred: str
) -> None:
    """Property: random JSON as VIL-100 frame annotations: numbers or one line, exit 2."""
    folder = tmp_path_factory.mktemp("vid")
    for i, value in enumerate(frames):
        doc = {"info": {"width": 640, "height": 360}, "annotations": {"lane": value}}
        _tree(folder / "gt", {f"Json/v/{i:05d}.jpg.json": json.dumps(doc)})
        _tree(folder / "pred", {f"v/{i:05d}.lines.txt": pred})
    code, out, err = _run(capsys, "video", folder / "pred", folder / "gt", "--json")
    assert "Traceback" not in err and len(err.strip().splitlines()) <= 1, err
    assert code in (0, 2) and (code == 0) == bool(out), err


def test_the_largest_images_allowed_score_in_bounded_memory() -> None:
    """Images far past the old size limits (64 predicted and 64 gt lanes of 10,000 rows: 41M comparisons each) are
    scored one block at a time, not 512 at once (which asked for tens of GB)."""
    import subprocess
    import sys

    code = (
        "import resource\n"
        "from stamlane_eval import tusimple\n"
        "R = 10000; h = list(range(R))\n"
        "gts = [[[float(300 + k)] * R for k in range(64)]] * 6\n"
        "preds = [[[float(301 + k)] * R for k in range(64)]] * 6\n"
        "assert tusimple.evaluate_batch(preds, gts, [h] * 6)[5].matched == 64\n"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    # KiB. One such image alone is 41M comparisons (~0.33 GB a temporary): its peak was 0.78 GB run alone and
    # 1.6 GB once inside the whole suite (glibc keeps freed blocks for reuse); 512 images at once asked for tens of GB.
    assert int(done.stdout) < 3_000_000


def test_lanes_too_large_to_draw_are_refused_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Lanes crossing a 16384 x 16384 frame (the largest --size): a few of them fill a gigapixel of canvases, so the
    image is refused (a size limit, docs/evaluators.md) instead of drawing 64 of them."""
    lane = "".join(f"{100 + 0.9 * y:.1f} {y} " for y in range(0, 16000, 8)) + "\n"
    pred = _tree(tmp_path / "pred", {"d/0.lines.txt": lane * 6})
    gt = _tree(tmp_path / "gt", {"d/0.lines.txt": lane * 6})
    err = _refused(capsys, "culane", pred, gt, "--size", "16384x16384")
    assert "too large to draw in memory" in err


# ----------------------------------------------------------------------- typed readers: numbers are numbers
def _vil100(root: Path, frames: dict[str, dict]) -> Path:
    return _tree(root, {f"Json/v/{name}": json.dumps(doc) for name, doc in frames.items()})


def _vil_doc(points: object = None, info: object = None, lane_id: object = 1) -> dict:
    lane = {"lane_id": lane_id, "points": [[10, 350], [20, 300], [30, 250]] if points is None else points}
    return {"info": {"width": 640, "height": 360} if info is None else info, "annotations": {"lane": [lane]}}


@pytest.mark.parametrize(
    ("doc", "words"),
    [
        (_vil_doc(points=[[True, 359], [20, 300]]), "two JSON numbers, got a boolean"),
        (_vil_doc(points=[["10", 359], [20, 300]]), "two JSON numbers"),
        (_vil_doc(points=[[10, 359, 1], [20, 300]]), "two JSON numbers"),
        (_vil_doc(points=[10, 359, 20, 300]), "two JSON numbers"),
        (_vil_doc(points=[[10**400, 359], [20, 300]]), "beyond the float range"),
        (_vil_doc(info={"width": "640", "height": 360}), "info.width must be an integer"),
        (_vil_doc(info={"width": True, "height": 360}), "info.width must be an integer"),
        (_vil_doc(info={"width": 640, "height": 360.5}), "info.height must be an integer"),
        (_vil_doc(lane_id="1"), "lane_id must be an integer"),
        (_vil_doc(lane_id=True), "lane_id must be an integer"),
    ],
)
def test_vil100_values_that_are_not_numbers_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], doc: dict, words: str
) -> None:
    gt = _vil100(tmp_path / "gt", {"00000.jpg.json": doc})
    pred = _tree(tmp_path / "pred", {"v/00000.lines.txt": LANE})
    assert words in _refused(capsys, "video", pred, gt)
    assert words in _refused(capsys, "video", pred, gt, "--temporal")


def test_vil100_integral_float_sizes_are_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt = _vil100(tmp_path / "gt", {"00000.jpg.json": _vil_doc(info={"width": 640.0, "height": 360})})
    pred = _tree(tmp_path / "pred", {"v/00000.lines.txt": "10 350 20 300 30 250\n"})
    code, out, _ = _run(capsys, "video", pred, gt, "--json")
    assert code == 0 and json.loads(out)["0.5"]["tp"] == 1


def test_a_frame_labelled_or_listed_twice_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = _vil_doc()
    gt = _vil100(tmp_path / "gt", {"00001.jpg.json": doc, "00001.png.json": doc, "00002.jpg.json": doc})
    pred = _tree(tmp_path / "pred", {"v/00001.lines.txt": LANE})
    for extra in ([], ["--temporal"]):
        assert "labelled twice" in _refused(capsys, "video", pred, gt, *extra)
    (gt / "Json" / "v" / "00001.png.json").unlink()
    for entries in ("v/00001.jpg\nv/00002.jpg\nv/00001.jpg\n", "/JPEGImages/v/00001.jpg\nv/00001.png\n"):
        (tmp_path / "list.txt").write_text(entries)
        for extra in ([], ["--temporal"]):
            err = _refused(capsys, "video", pred, gt, "--list", tmp_path / "list.txt", *extra)
            assert "name the same" in err, err
    lines_gt = _tree(tmp_path / "lgt", {"v/1.lines.txt": LANE, "v/2.lines.txt": LANE})
    (tmp_path / "list2.txt").write_text("v/1.jpg\nv/2.jpg\nv/1.jpg\n")
    assert "name the same" in _refused(
        capsys, "video", pred, lines_gt, "--list", tmp_path / "list2.txt", "--size", "640x360"
    )


def test_culane_json_predictions_are_typed_and_name_each_image_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    h = [300, 350]
    gt_rec = {"raw_file": "a.jpg", "lanes": [[10, 20]], "h_samples": h}
    gt = tmp_path / "gt.json"
    gt.write_text(json.dumps(gt_rec) + "\n" + json.dumps({**gt_rec, "raw_file": "b.jpg"}) + "\n")
    pred = tmp_path / "pred.json"
    ok = {"raw_file": "a.jpg", "lanes": [[10, 20]], "run_time": 1}
    for recs, words in [
        ([ok, ok], "two predictions for one image"),
        ([{**ok, "lanes": [[True, 20]]}], "true/false"),
        ([{**ok, "lanes": [["10", 20]]}], "JSON numbers"),
        ([{**ok, "raw_file": ["a.jpg"]}], "not in the ground truth"),
    ]:
        pred.write_text("".join(json.dumps(r) + "\n" for r in recs))
        assert words in _refused(capsys, "culane", pred, gt, "--size", "640x360"), words
    pred.write_text(json.dumps(ok) + "\n")
    bad_gt = tmp_path / "bad_gt.json"
    for g, words in [
        ([gt_rec, gt_rec], "again"),
        ([{**gt_rec, "h_samples": ["300", 350]}], "h_samples must be a list of numbers"),
    ]:
        bad_gt.write_text("".join(json.dumps(r) + "\n" for r in g))
        assert words in _refused(capsys, "culane", pred, bad_gt, "--size", "640x360"), words
    code, out, _ = _run(capsys, "culane", pred, gt, "--size", "640x360", "--json")
    assert code == 0 and json.loads(out)["0.5"]["tp"] == 1


# ------------------------------------------------------------- parity kept: what the official tools score
@pytest.mark.parametrize(
    ("line", "want"),
    [
        (b"10 500 20 400", [10, 500, 20, 400]),
        (b"10 500 nan 400 30 300", [10, 500]),  # >> fails on "nan": the lane ends there, silently
        (b"10 500 -nan 400", [10, 500]),
        (b"10 500 inf 400", [10, 500]),
        (b"10 500 1e400 400", [10, 500]),  # overflow: failbit
        (b"10 500 20x 400", [10, 500, 20]),  # 20 read, then "x" fails (the caller drops the lone x)
        (b"1-2 3 4", [1, -2, 3, 4]),  # a sign starts the next number
        (b"1e 5", []),  # "1e" accumulated, refused whole
        (b"1.e2 .5 +3 -0", [100, 0.5, 3, 0]),
        (b"\t10\r 20\v", [10, 20]),  # C isspace
        (b"1_000 2", [1]),
        (b"abc 1 2", []),
    ],
)
def test_culane_predictions_are_read_as_the_cpp_stream_reads_them(line: bytes, want: list[float]) -> None:
    from stamlane_eval.io import cpp_stream_doubles

    assert cpp_stream_doubles(line) == want


def test_culane_predictions_with_nan_or_words_are_scored(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt_lane = "100 500 110 400 120 300\n"
    pred = _tree(tmp_path / "pred", {"d/0.lines.txt": "100 500 110 400 120 300 nan 200\n", "d/1.lines.txt": "nan\n"})
    gt = _tree(tmp_path / "gt", {"d/0.lines.txt": gt_lane, "d/1.lines.txt": gt_lane})
    code, out, err = _run(capsys, "culane", pred, gt, "--json")
    assert code == 0 and err == "", err
    res = json.loads(out)
    # image 0: the lane up to the nan matches; image 1: a lane of 0 points (one FP, one FN), as the C++ tool
    assert [res["0.5"][k] for k in ("tp", "fp", "fn")] == [1, 1, 1]


def test_a_culane_prediction_lane_of_10001_points_is_scored(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from stamlane_eval.io import MAX_IMAGE_POINTS

    pts = [(100 + 0.5 * (i % 7), 580 - i * 0.05) for i in range(10_001)]
    lane = " ".join(f"{x:g} {y:g}" for x, y in pts) + "\n"
    pred = _tree(tmp_path / "pred", {"d/0.lines.txt": lane})
    gt = _tree(tmp_path / "gt", {"d/0.lines.txt": "100 580 101 330 102 80\n"})
    code, out, err = _run(capsys, "culane", pred, gt, "--json")
    assert code == 0, err
    assert json.loads(out)["0.3"]["tp"] == 1
    big = " ".join("10 20" for _ in range(MAX_IMAGE_POINTS + 1)) + "\n"
    (pred / "d" / "0.lines.txt").write_text(big)
    assert "memory budget" in _refused(capsys, "culane", pred, gt)


@pytest.mark.parametrize(
    ("pred_text", "gt_text", "want"),
    [
        ("", LANE, "tp: 0 fp: 0 fn: 1\nprecision: -1\nrecall: 0\nFmeasure: 0\n"),
        (LANE, "", "tp: 0 fp: 1 fn: 0\nprecision: 0\nrecall: -1\nFmeasure: 0\n"),
        ("", "", "tp: 0 fp: 0 fn: 0\nprecision: -1\nrecall: -1\nFmeasure: -1\n"),
        ("900 500 910 400 920 300\n", LANE, "tp: 0 fp: 1 fn: 1\nprecision: 0\nrecall: 0\nFmeasure: -nan\n"),
    ],
)
def test_format_official_writes_the_cpp_tools_zero_denominators(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], pred_text: str, gt_text: str, want: str
) -> None:
    """evaluate.cpp: precision/recall -1 where their denominator is 0, F = 2PR/(P+R) from those (0.0/0.0: -nan)."""
    pred = _tree(tmp_path / "pred", {"d/0.lines.txt": pred_text})
    gt = _tree(tmp_path / "gt", {"d/0.lines.txt": gt_text})
    code, out, err = _run(capsys, "culane", pred, gt, "--format", "official", "--iou", "0.5")
    assert code == 0 and out == want, (out, err)
    if "-1" in want:  # as a table or json, 0/0 is no rate: refused
        assert "0/0" in _refused(capsys, "culane", pred, gt)


def test_lanes_too_large_to_draw_are_refused_by_every_metric_that_draws(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One budget of canvases (io.CanvasBudget), counted before each allocation: video and video --temporal refuse
    what culane refuses (16384 x 16384 frames crossed by lanes), with the same words."""
    lane = "".join(f"{100 + 0.9 * y:.1f} {y} " for y in range(0, 16000, 400)) + "\n"
    pred = _tree(tmp_path / "pred", {"v/0.lines.txt": lane * 6, "v/1.lines.txt": lane * 6})
    gt = _tree(tmp_path / "gt", {"v/0.lines.txt": lane * 6, "v/1.lines.txt": lane * 6})
    for extra in ([], ["--temporal"]):
        err = _refused(capsys, "video", pred, gt, "--size", "16384x16384", *extra)
        assert "too large to draw in memory" in err, err


def test_predictions_far_outside_the_image_are_scored_under_temporal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """RVLD's script scores predicted x of +-150,000 (drawn clipped: nothing on the image); so do we, with the
    counts of any other prediction that draws nothing."""
    gt_lane = "100 350 150 250 200 150\n"
    gt = _tree(tmp_path / "gt", {f"v/{i}.lines.txt": gt_lane for i in range(3)})
    counts = []
    for far in (
        "150000 350 150010 250 150020 150",
        "-150000 350 -150010 250 -150020 150",
        "-900 350 -910 250 -920 150",
    ):
        pred = _tree(
            tmp_path / f"pred{len(counts)}",
            {"v/0.lines.txt": gt_lane, "v/1.lines.txt": far + "\n", "v/2.lines.txt": gt_lane},
        )
        code, out, err = _run(capsys, "video", pred, gt, "--temporal", "--size", "640x360", "--json")
        assert code == 0, err
        counts.append({t: json.loads(out)[t] for t in ("0.5", "0.8")})
    assert counts[0] == counts[1] == counts[2] and counts[0]["0.5"]["Nj"] == 2


# --------------------------------------------------------------------------- outputs never touch an input
def _video_tree(tmp_path: Path) -> tuple[Path, Path]:
    pred = _tree(tmp_path / "pred", {"v/0.lines.txt": LANE, "v/1.lines.txt": LANE})
    gt = _tree(tmp_path / "gt", {"v/0.lines.txt": LANE, "v/1.lines.txt": LANE})
    return pred, gt


def test_per_sequence_never_overwrites_the_sizes_file_nor_any_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pred, gt = _video_tree(tmp_path)
    sizes = tmp_path / "sizes.json"
    sizes.write_text('{"v": "640x360"}')
    listing = tmp_path / "list.txt"
    listing.write_text("v/0.jpg\nv/1.jpg\n")
    (tmp_path / "link.jsonl").symlink_to(sizes)
    os.link(listing, tmp_path / "hard.txt")
    before = {p: p.read_bytes() for p in (sizes, listing, pred / "v/0.lines.txt")}
    for extra in ([], ["--temporal"]):
        for out in (sizes, tmp_path / "link.jsonl", listing, tmp_path / "hard.txt", pred / "v/0.lines.txt", gt / "x"):
            argv = ["video", pred, gt, "--sizes", sizes, "--list", listing, "--per-sequence", out, *extra]
            assert "would overwrite or write into the input" in _refused(capsys, *argv)
    assert {p: p.read_bytes() for p in before} == before


def test_per_image_temporary_names_never_remove_an_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The temporary file is made with a unique name (mkstemp); a prediction named like the old fixed temporary
    name (".out.jsonl.tmp") is left alone."""
    pred = tmp_path / ".out.jsonl.tmp"
    pred.write_bytes(TS_PRED.read_bytes())
    code, _, err = _run(capsys, "tusimple", pred, TS_GT, "--per-image", tmp_path / "out.jsonl")
    assert code == 0, err
    assert pred.read_bytes() == TS_PRED.read_bytes() and (tmp_path / "out.jsonl").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [".out.jsonl.tmp", "out.jsonl"]  # no temporary left
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro").chmod(0o500)
    try:
        if not os.access(tmp_path / "ro", os.W_OK):  # root writes anywhere
            assert "cannot write" in _refused(capsys, "tusimple", pred, TS_GT, "--per-image", tmp_path / "ro" / "o")
    finally:
        (tmp_path / "ro").chmod(0o700)
    assert "is a folder" in _refused(capsys, "tusimple", pred, TS_GT, "--per-image", tmp_path / "ro")


def _die(*_: object, **__: object) -> None:
    os._exit(1)


def test_a_killed_jobs_worker_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from stamlane_eval import temporal, video

    pred, gt = _video_tree(tmp_path)
    _tree(pred, {"w/0.lines.txt": LANE})
    _tree(gt, {"w/0.lines.txt": LANE})
    monkeypatch.setattr(video, "evaluate_sequence", _die)
    monkeypatch.setattr(temporal, "evaluate_sequence", _die)
    for extra in ([], ["--temporal"]):
        err = _refused(capsys, "video", pred, gt, "--size", "640x360", "--jobs", "2", *extra)
        assert "worker process of --jobs 2 died" in err


def test_a_sizes_file_nested_too_deeply_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pred, gt = _video_tree(tmp_path)
    (tmp_path / "sizes.json").write_text("[" * 100000 + "]" * 100000)
    assert "nested too deeply" in _refused(capsys, "video", pred, gt, "--sizes", tmp_path / "sizes.json")


def test_too_many_thresholds_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Counts are kept per threshold for every image: a sweep of 100 is allowed, not an argv of 5,000."""
    pred, gt = _video_tree(tmp_path)
    many = [f"{i / 5000:.4f}" for i in range(5000)]
    assert "more than the limit of 100" in _refused(capsys, "culane", pred, gt, "--iou", *many)
    code, _, err = _run(capsys, "culane", pred, gt, "--iou", *[f"{i / 100:.2f}" for i in range(100)], "--json")
    assert code == 0, err


# ------------------------------------------------------------------- TuSimple records read as video frames
_H = [300, 310, 320]
_REC = {"raw_file": "clips/c/1.jpg", "lanes": [[100, 101, 102]], "h_samples": _H}
_REC2 = {**_REC, "raw_file": "clips/c/2.jpg"}


def _jsonl(path: Path, records: list[object]) -> Path:
    path.write_text("".join((r if isinstance(r, str) else json.dumps(r)) + "\n" for r in records))
    return path


VIDEO_TUSIMPLE_BAD = {  # case: (gt text or records, pred records, words of the one line)
    "gt_invalid_json": (["{oops"], [_REC], "invalid JSON"),
    "gt_list_of_numbers": ("[1, 2]", [_REC], "record 1: expected a JSON object"),
    "gt_empty_list": ("[]", [_REC], "non-empty JSON list"),
    "gt_nested_deep": ("[" * 100_000 + "]" * 100_000, [_REC], "nested too deeply"),
    "gt_no_folder": ([{**_REC, "raw_file": "1.jpg"}], [_REC], "names no folder"),
    "gt_same_frame_two_names": ([_REC, {**_REC, "raw_file": "clips/c/1.png"}], [_REC], "labelled twice"),
    "gt_same_raw_file": ([_REC, _REC], [_REC], "two labels for one image"),
    # one frame named twice, written two ways: the names are normalised once (stamlane_eval.io.image_key)
    "gt_dot_segment": ([_REC, {**_REC, "raw_file": "clips/c/./1.jpg"}], [_REC], "two labels for one image"),
    "gt_parent_segment": ([_REC, {**_REC, "raw_file": "clips/x/../c/1.jpg"}], [_REC], "two labels for one image"),
    "gt_double_slash": ([_REC, {**_REC, "raw_file": "clips//c/1.jpg"}], [_REC], "two labels for one image"),
    "pred_dot_segment_twice": ([_REC], [_REC, {**_REC, "raw_file": "clips/c/./1.jpg"}], "predicted twice"),
    "gt_boolean": ("[" + json.dumps(_REC).replace("100", "true") + "]", [_REC], "boolean"),
    "gt_nan": ([json.dumps(_REC).replace("100", "NaN")], [_REC], "not a pixel coordinate"),
    "gt_lane_length": ([{**_REC, "lanes": [[1, 2]]}], [_REC], "h_samples has 3"),
    "gt_no_h_samples": ([{"raw_file": "clips/c/1.jpg", "lanes": []}], [_REC], "h_samples"),
    "pred_string_x": ([_REC], [{**_REC, "lanes": [["1", 2, 3]]}], "not 3 JSON numbers"),
    "pred_boolean_x": ([_REC], [json.dumps(_REC).replace("100", "false")], "boolean"),
    "pred_infinite_x": ([_REC], [json.dumps(_REC).replace("100", "Infinity")], "non-finite"),
    "pred_short_lane": ([_REC], [{**_REC, "lanes": [[1, 2]]}], "not 3 JSON numbers"),
    "pred_bad_h_samples": ([_REC], [{**_REC, "h_samples": ["300", 310, 320]}], "h_samples must be"),
    "pred_infinite_h_samples": ([_REC], [json.dumps({**_REC, "h_samples": [float("inf"), 310, 320]})], "not finite"),
    "pred_twice": ([_REC, _REC2], [_REC, _REC2, _REC], "predicted twice"),
    "pred_too_many_lanes": ([_REC], [{**_REC, "lanes": [[1, 2, 3]] * (MAX_LANES + 1)}], "more than the limit"),
    "pred_no_raw_file": ([_REC], [{"lanes": [], "h_samples": _H}], "needs raw_file"),
    "pred_raw_file_number": ([_REC], [{**_REC, "raw_file": 7}], "needs raw_file"),
    "pred_not_object": ([_REC], ["[1]"], "JSON object"),
}


@pytest.mark.parametrize("case", sorted(VIDEO_TUSIMPLE_BAD))
@pytest.mark.parametrize("temporal", [False, True])
def test_video_tusimple_records_that_cannot_be_scored_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str, temporal: bool
) -> None:
    gt_recs, pred_recs, words = VIDEO_TUSIMPLE_BAD[case]
    gt = tmp_path / "gt.json"
    if isinstance(gt_recs, str):
        gt.write_text(gt_recs)
    else:
        _jsonl(gt, gt_recs)
    pred = _jsonl(tmp_path / "pred.json", pred_recs)
    err = _refused(capsys, "video", pred, gt, "--size", "640x360", *(["--temporal"] if temporal else []))
    assert words in err, err
    assert str(gt if case.startswith("gt") else pred) in err, err


def test_video_tusimple_setups_that_cannot_be_scored_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], no_hang: None
) -> None:
    """Predictions without h_samples against CULane text, a list naming an unlabelled frame, special files and
    links to outside among the records, an empty folder, a file past the size limit: one line, exit 2, unread."""
    gt = _jsonl(tmp_path / "gt.json", [_REC, _REC2])
    text_gt = _tree(tmp_path / "text", {"clips/c/1.lines.txt": LANE})
    bare = _jsonl(tmp_path / "bare.json", [{"raw_file": "clips/c/1.jpg", "lanes": [[1, 2, 3]], "run_time": 5}])
    assert "no h_samples" in _refused(capsys, "video", bare, text_gt, "--size", "640x360")
    err = _refused(capsys, "video", bare, gt)
    assert f"{gt}: frame clips/c/1: no image size: give --size" in err
    (tmp_path / "list.txt").write_text("clips/c/1.jpg\nclips/c/9.jpg\n")
    err = _refused(capsys, "video", bare, gt, "--size", "640x360", "--list", tmp_path / "list.txt")
    assert "clips/c/9 is not in" in err
    folder = tmp_path / "labels"
    folder.mkdir()
    assert "TuSimple records" in _refused(capsys, "video", bare, folder, "--size", "640x360")
    secret = tmp_path / "secret.txt"
    secret.write_text('{"raw_file": "the secret 12 34"}\n')
    (folder / "a.json").symlink_to(secret)
    err = _refused(capsys, "video", bare, folder, "--size", "640x360")
    assert "outside the folder" in err and "secret 12" not in err
    (folder / "a.json").unlink()
    os.mkfifo(folder / "a.json")
    assert "FIFO" in _refused(capsys, "video", bare, folder, "--size", "640x360")
    (folder / "a.json").unlink()
    (folder / "a.json").symlink_to("/dev/zero")
    _refused(capsys, "video", bare, folder, "--size", "640x360")
    os.mkfifo(tmp_path / "fifo")
    _refused(capsys, "video", tmp_path / "fifo", gt, "--size", "640x360")
    _refused(capsys, "video", bare, tmp_path / "fifo", "--size", "640x360")
    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.truncate(MAX_FILE_BYTES + 1)
    assert "larger than the limit" in _refused(capsys, "video", big, gt, "--size", "640x360")
    assert "larger than the limit" in _refused(capsys, "video", bare, big, "--size", "640x360")


@SETTINGS
@given(st.lists(_JSON_VALUES, min_size=1, max_size=3), st.lists(_JSON_VALUES, min_size=1, max_size=3))
def test_video_tusimple_malformed_records(
    tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], lanes: list, preds: list
) -> None:
    """Property: random JSON as the lanes of TuSimple frames (ground truth and predictions): numbers or one line,
    exit 2."""
    folder = tmp_path_factory.mktemp("vidts")
    gt = _jsonl(folder / "gt.json", [{**_REC, "raw_file": f"clips/c/{i}.jpg", "lanes": v} for i, v in enumerate(lanes)])
    pred = _jsonl(
        folder / "pred.json", [{**_REC, "raw_file": f"clips/c/{i}.jpg", "lanes": v} for i, v in enumerate(preds)]
    )
    for extra in ([], ["--temporal"]):
        code, out, err = _run(capsys, "video", pred, gt, "--size", "640x360", "--json", *extra)
        assert "Traceback" not in err and len(err.strip().splitlines()) <= 1, err
        assert code in (0, 2) and (code == 0) == bool(out), err


def test_frame_names_are_normalised_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``s1/./2.jpg`` is ``s1/2.jpg``: a prediction written so scores its frame (one sequence, not two), and a list
    naming the frame both ways is refused as naming it twice (it was a second sequence: F1 1.0 -> 0.857, exit 0)."""
    from stamlane_eval.io import image_key

    assert image_key("s1/./2.jpg") == image_key("s1/2.jpg") == image_key("s1//2.jpg") == "s1/2.jpg"
    assert image_key("s0/x/../2.jpg") == "s0/2.jpg" and image_key("/a/./b.jpg") == "/a/b.jpg"
    gt = _jsonl(tmp_path / "gt.json", [_REC, _REC2])
    pred = _jsonl(tmp_path / "pred.json", [{**_REC, "raw_file": "clips/c/./1.jpg"}, _REC2])
    code, out, err = _run(capsys, "video", pred, gt, "--size", "640x360", "--json")
    assert code == 0, err
    scores = json.loads(out)
    assert scores["0.5"]["f1"] == 1.0 and scores["sequences"] == 1 and scores["frames"] == 2, scores
    listing = tmp_path / "list.txt"
    listing.write_text("clips/c/1.jpg\nclips/c/./1.jpg\n")
    culane = tmp_path / "lines" / "c"
    culane.mkdir(parents=True)
    (culane / "1.lines.txt").write_text("100 300 101 310\n")
    err = _refused(capsys, "video", tmp_path / "lines", tmp_path / "lines", "--list", listing, "--size", "640x360")
    assert "name the same" in err, err
