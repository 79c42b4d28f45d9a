"""The benchmark scripts as users run them keep stamlane's contract for bad input (benchmarks/_harness.py): one line
on stderr naming the file or option, exit status 2, nothing written, nothing read outside the folder given.

``card_intervals.py``, ``scale.py`` and ``paper_learns.py``; none of these cases trains or times anything."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.benchmarks.scripts import REPO, benchmark_module

H = [200, 210, 220, 230]
LANES = [[100, 110, 120, 130], [300, 310, 320, 330]]


@pytest.fixture(scope="module")
def card():
    with benchmark_module("card_intervals") as module:
        yield module


@pytest.fixture(scope="module")
def scale():
    with benchmark_module("scale") as module:
        yield module


@pytest.fixture(scope="module")
def learns():
    with benchmark_module("paper_learns") as module:
        yield module


def _jsonl(path: Path, records: list[dict]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    return path


def _split(root: Path, names: list[str]) -> tuple[Path, Path]:
    gt = _jsonl(root / "test.json", [{"raw_file": n, "lanes": LANES, "h_samples": H} for n in names])
    pred = _jsonl(root / "run" / "predictions.json", [{"raw_file": n, "lanes": LANES, "run_time": 5} for n in names])
    return gt, pred


NAMES = [f"clips/c{c}/{f}.jpg" for c in range(3) for f in (8, 20)]


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _one_line(capsys: pytest.CaptureFixture[str], code: int, *words: str) -> str:
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in err, (word, err)
    return err


# ---------------------------------------------------------------------------------------------- card_intervals
@pytest.mark.parametrize(
    ("case", "words"),
    [
        ("gt not json lines", ["test.json", "line 2", "invalid JSON"]),
        ("pred not json lines", ["predictions.json", "line 1", "invalid JSON"]),
        ("one clip", ["test.json", "1 clip", "at least 2 clips"]),
        ("same frame twice", ["test.json", "two labels for one image"]),
        ("same frame twice, respelled", ["test.json", "two labels for one image"]),
        ("dataset.json without its config", ["dataset.json", "no frame size", "'config'"]),
        ("dataset.json of 0x0 frames", ["dataset.json", "no frame size", "1..16384"]),
        ("--size 0x0", ["--size", "0x0"]),
    ],
)
def test_card_intervals_bad_input(card, tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str, words) -> None:
    root = tmp_path / "set"
    gt, pred = _split(root, NAMES)
    extra: list[str] = []
    if case == "gt not json lines":
        gt.write_text(gt.read_text().replace("\n", "\nnot json\n", 1))
    elif case == "pred not json lines":
        pred.write_text("{oops\n")
    elif case == "one clip":
        gt, pred = _split(root, [n for n in NAMES if "/c0/" in n])
    elif case.startswith("same frame twice"):
        again = "clips/c0/8.jpg" if case == "same frame twice" else "clips/c0/./8.jpg"
        gt, pred = _split(root, [*NAMES, again])
    elif case.startswith("dataset.json"):
        config = {"seed": 0} if "without" in case else {"config": {"height": 0, "width": 0}}
        (root / "dataset.json").write_text(json.dumps(config))
        extra = ["--iou", "0.5"]
    else:
        extra = ["--iou", "0.5", "--size", "0x0"]
    before = _snapshot(tmp_path)
    _one_line(capsys, card.main([str(gt), str(pred), *extra]), *words)
    assert _snapshot(tmp_path) == before


def test_card_intervals_never_reads_a_frame_outside_the_set(
    card, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A first label whose raw_file climbs out of the set with ``..`` names a real image beside the set: its size
    was read and scored before; now the line is refused before any frame is opened."""
    import cv2

    cv2.imwrite(str(tmp_path / "outside.png"), np.zeros((24, 32, 3), np.uint8))
    names = ["../outside.png", *NAMES]
    gt, pred = _split(tmp_path / "set", names)
    err = _one_line(capsys, card.main([str(gt), str(pred), "--iou", "0.5"]), "test.json: line 1", "outside")
    assert "../outside.png" in err
    assert card.main([str(gt), str(pred), "--iou", "0.5", "--size", "32x24", "--resamples", "100"]) == 0  # given


# ------------------------------------------------------------------------------------------------------ scale
@pytest.mark.parametrize(
    ("case", "words"),
    [
        ("--out a folder", ["is a folder, not a file"]),
        ("--out under a file", ["a file, not a folder"]),
        ("--replot of a file that is not JSON", ["is not JSON"]),
        ("--replot of a JSON list", ["holds a JSON list"]),
        ("--replot of another script's JSON", ["has no 'centre'"]),
        ("--replot of a broken result", ["is not a scale.py result"]),
        ("--replot of no file", ["does not exist"]),
    ],
)
def test_scale_bad_out(scale, tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str, words) -> None:
    out = tmp_path / "scale.json"
    argv = ["--replot"] if case.startswith("--replot") else ["--quick"]
    if case == "--out a folder":
        out.mkdir()
    elif case == "--out under a file":
        (tmp_path / "file").write_text("x")
        out = tmp_path / "file" / "scale.json"
    elif case == "--replot of a file that is not JSON":
        out.write_text("steps: 2\n")
    elif case == "--replot of a JSON list":
        out.write_text("[1, 2]")
    elif case == "--replot of another script's JSON":
        out.write_text(json.dumps({"runs": {}}))
    elif case == "--replot of a broken result":
        out.write_text(json.dumps({"centre": {"width": 1}, "device": "cpu", "cpu": "x", "cores": 2, "threads": 1}))
    before = _snapshot(tmp_path)
    _one_line(capsys, scale.main([*argv, "--out", str(out)]), str(out), *words)
    assert _snapshot(tmp_path) == before  # no .md, no .png, nothing beside it


# ---------------------------------------------------------------------------------------------- paper_learns
@pytest.mark.parametrize(
    ("case", "words"),
    [
        ("--out a file", ["is a file, not a folder"]),
        ("--out inside --root", ["would overwrite or write into the input"]),
        ("--size 0x0", ["--size", "0x0"]),
        ("--root a file", ["--root", "is a file, not a folder"]),
        ("dataset.json without its config", ["dataset.json", "has no 'config'"]),
        ("a broken run file to combine", ["run file", "paper-quick.json", "is not JSON"]),
        ("another script's run file", ["run file", "stable-quick.json", "not this script's"]),
        ("nothing to combine", ["no run file to combine"]),
    ],
)
def test_paper_learns_bad_input(learns, tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str, words) -> None:
    root, out = tmp_path / "set", tmp_path / "out"
    argv = ["--quick"]
    if case == "--out a file":
        out.write_text("x")
    elif case == "--out inside --root":
        out = root / "results"
    elif case == "--size 0x0":
        argv = ["--size", "0x0"]
    elif case == "--root a file":
        root.write_text("x")
    elif case == "dataset.json without its config":
        root.mkdir()
        (root / "dataset.json").write_text(json.dumps({"seed": 0}))
    elif case == "a broken run file to combine":
        argv = ["--combine-only"]
        out.mkdir()
        (out / "paper-quick.json").write_text('{"rows": [')
    elif case == "another script's run file":
        argv = ["--combine-only"]
        out.mkdir()
        (out / "stable-quick.json").write_text(json.dumps({"rows": [{"step": 1}], "summary": {}}))
    elif case == "nothing to combine":
        argv = ["--combine-only"]
        out.mkdir()
    before = _snapshot(tmp_path)
    _one_line(capsys, learns.main([*argv, "--root", str(root), "--out", str(out)]), *words)
    assert _snapshot(tmp_path) == before
    if case not in ("--out a file", "--out inside --root") and not argv[0].startswith("--combine"):
        assert not out.exists()  # refused before the output folder is made


def test_paper_learns_passes_a_refusal_of_stamlane_through(
    learns, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A ``stamlane synth`` / ``fit`` that refuses its input (exit 2, one line) ends the script with that line and
    status 2; one that crashes ends it with status 1 and what it printed."""

    def refuse(root: Path, *_: object) -> None:
        raise learns.StepFailed("stamlane synth", 2, "noise\nstamlane synth: error: --size: sides in 16..4096\n")

    monkeypatch.setattr(learns, "make_set", refuse)
    code = learns.main(["--quick", "--root", str(tmp_path / "set"), "--out", str(tmp_path / "out")])
    _one_line(capsys, code, "stamlane synth failed (2)", "sides in 16..4096")

    def crash(root: Path, *_: object) -> None:
        raise learns.StepFailed("stamlane synth", 1, "Traceback (most recent call last):\nBoom\n")

    monkeypatch.setattr(learns, "make_set", crash)
    assert learns.main(["--quick", "--root", str(tmp_path / "set"), "--out", str(tmp_path / "out")]) == 1
    assert "Boom" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------ as users run them
@pytest.mark.parametrize(
    ("script", "args", "words"),
    [
        ("card_intervals.py", ["{gt}", "{pred}", "--iou", "0.5", "--size", "0x0"], "--size"),
        ("scale.py", ["--out", "{folder}"], "is a folder, not a file"),
        ("paper_learns.py", ["--combine-only", "--out", "{folder}"], "no run file to combine"),
    ],
)
def test_the_scripts_from_the_command_line(tmp_path: Path, script: str, args: list[str], words: str) -> None:
    """``python benchmarks/<script> ...`` (the `_harness` import from the script's folder): one line, exit 2."""
    gt, pred = _split(tmp_path / "set", NAMES)
    (tmp_path / "folder").mkdir()
    fill = {"gt": gt, "pred": pred, "folder": tmp_path / "folder"}
    argv = [a.format(**fill) for a in args]
    done = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / script), *argv], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and words in done.stderr, done.stderr


def test_the_shared_frame_size_reads_only_inside_the_set(tmp_path: Path) -> None:
    """`stamlane.experiments.split_scores.image_size` (card_intervals' and the experiments' frame size): the set's
    ``dataset.json``, else the first labelled frame, never one outside the folder given."""
    import cv2

    from stamlane.experiments.split_scores import image_size

    root = tmp_path / "set"
    (root / "clips" / "c0").mkdir(parents=True)
    cv2.imwrite(str(root / "clips" / "c0" / "8.png"), np.zeros((24, 32, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "outside.png"), np.zeros((48, 64, 3), np.uint8))
    _jsonl(root / "test.json", [{"raw_file": "clips/c0/8.png", "lanes": [], "h_samples": H}])
    assert image_size(root, "test") == (24, 32)
    _jsonl(root / "out.json", [{"raw_file": "clips/../../outside.png", "lanes": [], "h_samples": H}])
    with pytest.raises(ValueError, match="outside the data root"):
        image_size(root, "out")
    (root / "dataset.json").write_text(json.dumps({"config": {"height": 720, "width": 1280}}))
    assert image_size(root, "out") == (720, 1280)  # a synthetic set's size, no frame read
    for bad in ({"config": {"height": True, "width": 1280}}, {"config": {"height": 720}}, {"config": [720, 1280]}):
        (root / "dataset.json").write_text(json.dumps(bad))
        with pytest.raises(ValueError, match=r"dataset\.json: no frame size"):
            image_size(root, "test")


# ----------------------------------------------------------------------------- every other script's --out
OUT_FILE_SCRIPTS = {  # script: the arguments besides --out it needs to parse
    "align": [],
    "align_presets": [],
    "eval_speed": [],
    "frame_store": [],
    "fusion_share": ["some-run"],
    "model": [],
    "pipeline_side_by_side": [],
    "postprocess": [],
    "profile_pipeline": [],
    "soak": ["eval"],
    "stream": [],
    "stream_overlap": [],
    "synth": [],
    "synth_align": [],
    "video_speed": [],
}
OUT_FOLDER_SCRIPTS = {"demo_transfer": [], "history_recipe": [], "run_passes": []}


@pytest.mark.parametrize("script", sorted({**OUT_FILE_SCRIPTS, **OUT_FOLDER_SCRIPTS}))
def test_every_script_refuses_an_out_it_cannot_write_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], script: str
) -> None:
    """A file script given a folder as --out, a folder script given a file: one line, exit 2, nothing made."""
    folder = script in OUT_FOLDER_SCRIPTS
    out = tmp_path / ("file.json" if folder else "folder")
    if folder:
        out.write_text("{}")
    else:
        out.mkdir()
    argv = [*{**OUT_FILE_SCRIPTS, **OUT_FOLDER_SCRIPTS}[script], "--out", str(out)]
    before = _snapshot(tmp_path)
    with benchmark_module(script) as module:
        code = module.main(argv)
    _one_line(capsys, code, f"{script}.py", str(out), "is a file, not a folder" if folder else "is a folder")
    assert _snapshot(tmp_path) == before and sorted(p.name for p in tmp_path.iterdir()) == [out.name]


@pytest.mark.parametrize("script", ["soak", "pipeline_side_by_side"])
def test_results_merged_into_out_are_checked_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], script: str
) -> None:
    """The scripts that keep --out's earlier results refuse an --out that is not JSON before any work."""
    out = tmp_path / "results.json"
    out.write_text("not json")
    argv = ["eval", "--out", str(out)] if script == "soak" else ["--skip", "render", "--out", str(out)]
    with benchmark_module(script) as module:
        _one_line(capsys, module.main(argv), f"{script}.py", "is not JSON")
    assert out.read_text() == "not json"


def test_adapt_intervals_bad_input_is_one_line_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``adapt_intervals.py``: a missing or non-JSON real_roads.py file, frames that differ between the files, and
    an --out it cannot write: one line, exit 2, nothing written."""
    record = {"labelled_frames": {"per_image": [{"raw_file": "a.jpg", "fp": 0.0, "fn": 0.0, "accuracy": 1.0}]}}
    before, other = tmp_path / "before.json", tmp_path / "other.json"
    before.write_text(json.dumps(record))
    other.write_text(json.dumps({"labelled_frames": {"per_image": [{"raw_file": "b.jpg", "fp": 0, "fn": 0}]}}))
    (tmp_path / "broken.json").write_text("{oops")
    (tmp_path / "folder").mkdir()
    out = str(tmp_path / "table.json")
    cases = [
        ([str(tmp_path / "missing.json"), "--out", out], "missing.json"),
        ([str(tmp_path / "broken.json"), "--out", out], "not JSON"),
        ([str(other), "--out", out], "scored on other frames"),
        ([str(before), "--out", str(tmp_path / "folder")], "is a folder"),
    ]
    snapshot = _snapshot(tmp_path)
    with benchmark_module("adapt_intervals") as module:
        for after, words in cases:
            _one_line(capsys, module.main([str(before), *after]), "adapt_intervals", words)
    assert _snapshot(tmp_path) == snapshot
