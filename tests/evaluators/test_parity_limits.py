"""The parity rule on the limits (#59): what the official tool scores, stamlane scores the same; a limit refuses only
what would exceed a size or time budget (``stamlane_eval.io.limits``), in one line, exit 2.

lane.py's numbers on the TuSimple cases are in ``golden/tusimple_rule_cases.json`` (made with the official file by
``golden/make_tusimple_rule_cases.py``; ``test_tusimple_rule`` checks every case of it); here the limits themselves.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from stamlane_eval import culane, temporal, tusimple
from stamlane_eval.cli import main
from stamlane_eval.io import (
    MAX_LANES,
    TuSimpleInputError,
    read_tusimple,
    read_vil100_json,
)

GOLDEN = Path(__file__).parent / "golden"
LANE_PY = {c["name"]: c["lane_py"] for c in json.loads((GOLDEN / "tusimple_rule_cases.json").read_text())["cases"]}


def _run(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _jsonl(path: Path, records: list[dict]) -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    return path


def test_the_issue_case_gt_x_150000_gets_lane_pys_numbers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """#59: a gt lane with x = 150,000 (lane.py: accuracy 0.95, FP 0.25, FN 0.25), with one warning line."""
    h = [400, 450, 500, 550, 600]
    pred = _jsonl(
        tmp_path / "p.json",
        [{"raw_file": "a.jpg", "lanes": [[100] * 5, [300] * 5, [500] * 5, [900] * 5], "run_time": 1}],
    )
    gt_lanes = [[100] * 5, [300] * 5, [500] * 5, [700, 700, 700, 700, 150000]]
    gt = _jsonl(tmp_path / "g.json", [{"raw_file": "a.jpg", "lanes": gt_lanes, "h_samples": h}])
    code, out, err = _run(capsys, "tusimple", pred, gt, "--json")
    got = json.loads(out)
    assert code == 0 and (got["accuracy"], got["fp"], got["fn"]) == (0.95, 0.25, 0.25)
    want = LANE_PY["gt_x_150000_issue_59"]
    assert (want["accuracy"], want["fp"], want["fn"]) == (0.95, 0.25, 0.25)  # what the official file returned
    assert len(err.strip().splitlines()) == 1 and "1 ground-truth value(s) are no pixel coordinate" in err
    # the far point makes lane.py's threshold wide (about 5,000 px): a prediction 4,000 px off on the other rows hits
    far = tusimple.evaluate_image([[4300, 4300, 4300, 4300, 300]], [[300, 300, 300, 300, 150000]], h)
    assert far.acc == 0.8


def test_the_issue_case_65_culane_lanes_are_scored(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """#59: 65 predicted lanes in one image, as the C++ tool scores them: 2 matched, 63 FP."""
    gt_text = "100 590 200 300\n1200 590 1100 300\n"
    pred_text = gt_text + "".join(f"{20 * k} 100 {20 * k + 5} 0\n" for k in range(63))  # far from both gt lanes
    for sub, text in (("pred", pred_text), ("anno", gt_text)):
        (tmp_path / sub / "d").mkdir(parents=True)
        (tmp_path / sub / "d" / "0.lines.txt").write_text(text)
    code, out, err = _run(capsys, "culane", tmp_path / "pred", tmp_path / "anno", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert [res[t]["tp"] for t in ("0.3", "0.5")] == [2, 2] and [res[t]["fp"] for t in ("0.3", "0.5")] == [63, 63]
    assert res["0.5"]["fn"] == 0
    (tmp_path / "pred" / "d" / "0.lines.txt").write_text(pred_text + "10 500 20 400\n" * (MAX_LANES - 64))
    code, out, err = _run(capsys, "culane", tmp_path / "pred", tmp_path / "anno", "--json")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert f"more than {MAX_LANES} lanes" in err and "0.lines.txt" in err and "time budget" in err


def test_tusimple_lane_counts_and_lengths_are_free_within_the_memory_budgets(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """lane.py scores any lane count and length: 70 predicted lanes (its early return) and lanes of 10,001 rows are
    scored; one image of more than MAX_COMPARED_CELLS comparisons, or a file whose padded lanes pass
    MAX_TUSIMPLE_VALUES, is refused in one line naming the line."""
    for name in ("pred_70_lanes_early_return", "lanes_of_10001_rows"):
        assert LANE_PY[name]["status"] == "ok"
    monkeypatch.setattr("stamlane_eval.tusimple.MAX_COMPARED_CELLS", 40 * 40 * 1000)  # the real one takes seconds
    rows = 1001
    rec = {"raw_file": "a.jpg", "lanes": [[5] * rows] * 40}
    pred = _jsonl(tmp_path / "p.json", [{**rec, "run_time": 1}])
    gt = _jsonl(tmp_path / "g.json", [{**rec, "h_samples": list(range(rows))}])
    code, out, err = _run(capsys, "tusimple", pred, gt)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "p.json: line 1" in err and "comparisons in one image, past the time budget" in err
    # the same lanes with 43 predictions: lane.py's early return scores the image (0, 0, 1) without comparing
    many = _jsonl(tmp_path / "p43.json", [{**rec, "lanes": [[5] * rows] * 43, "run_time": 1}])
    code, out, err = _run(capsys, "tusimple", many, gt, "--json")
    assert code == 0 and json.loads(out)["fn"] == 1.0, err
    monkeypatch.setattr("stamlane_eval.io.tusimple.MAX_TUSIMPLE_VALUES", 1000)  # a real one is a 100 MB file
    small = _jsonl(
        tmp_path / "g2.json", [{"raw_file": "a.jpg", "lanes": [[5] * 501] * 2, "h_samples": list(range(501))}]
    )
    code, out, err = _run(capsys, "tusimple", pred, small)
    assert code == 2 and "g2.json" in err and "too large to score in memory" in err
    assert len(err.strip().splitlines()) == 1


def test_tusimple_gt_values_lane_py_cannot_fit_are_refused_where_it_fits_them() -> None:
    """+inf in a gt lane: lane.py's angle fit raises when the lane has two or more rows with x >= 0 in an image
    it compares; alone on its lane, or in an image its early return scores, it is scored."""
    h = [400, 450, 500, 550, 600]
    inf = float("inf")
    with pytest.raises(TuSimpleInputError, match="angle fit"):
        tusimple.evaluate_image([[300] * 5], [[300, 300, 300, 300, inf]], h)
    assert tusimple.evaluate_image([[300] * 5], [[-2, -2, -2, -2, inf]], h).acc == 0.0
    early = tusimple.evaluate_image([[300] * 5] * 4, [[300, 300, 300, 300, inf]], h)
    assert (early.acc, early.fp, early.fn, early.early_return) == (0.0, 0.0, 1.0, True)
    with pytest.raises(TuSimpleInputError, match="angle fit"):  # two 1.7e308: the mean overflows in lstsq
        tusimple.evaluate_image([[300] * 5], [[300, 300, 300, 1.7e308, 1.7e308]], h)
    assert tusimple.evaluate_image([[300] * 5], [[300, 300, 300, 300, 1.7e308]], h).acc == 0.8  # lane.py: 0.8


def test_training_labels_keep_the_pixel_rule() -> None:
    """The training datasets' check (``tusimple_record_error``) still takes labels as pixel coordinates: a label
    at 150,000 px is no road in any image a model is trained on (not a parity case: no official tool reads them)."""
    from stamlane_eval.io import tusimple_record_error

    rec = {"raw_file": "a.jpg", "lanes": [[300, 300, 150000]], "h_samples": [400, 500, 600]}
    assert "not a pixel coordinate" in (tusimple_record_error(rec, "gt") or "")
    assert tusimple_record_error({**rec, "lanes": [[300, 300, 300]]}, "gt") is None


def test_far_labels_are_drawn_clipped_by_the_cpp_metrics(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A VIL-100 or TuSimple-format label at x = 150,000 is drawn clipped (nothing on the image), as the C++ tool
    draws it: an FN, not a refusal; the temporal metric scores it as RVLD's script does (drawn nowhere)."""
    doc = {
        "info": {"width": 640, "height": 360},
        "annotations": {"lane": [{"lane_id": 1, "points": [[150000, 350], [150010, 300]]}]},
    }
    (tmp_path / "gt" / "Json" / "v").mkdir(parents=True)
    (tmp_path / "gt" / "Json" / "v" / "00000.jpg.json").write_text(json.dumps(doc))
    lanes, _, _ = read_vil100_json(tmp_path / "gt" / "Json" / "v" / "00000.jpg.json")
    assert lanes[0][0, 0] == 150000.0
    res = culane.evaluate_image([np.array([[10.0, 350], [20, 300]])], lanes, size=(360, 640))
    assert res.counts[0.5] == (0, 1, 1)
    far = [np.array([[150000.0, 350], [150003, 200], [150010, 10]])]
    near = [np.array([[100.0, 350], [110, 200], [120, 10]])]
    frame = temporal.evaluate_frame(near, far, size=(360, 640))  # was refused as "not a pixel of an image"
    assert frame.anno_iou.tolist() == [0.0]
    gt = _jsonl(
        tmp_path / "g.json", [{"raw_file": "a.jpg", "lanes": [[150000, 150010, -2]], "h_samples": [350, 300, 250]}]
    )
    pred = _jsonl(tmp_path / "p.json", [{"raw_file": "a.jpg", "lanes": [[10, 20, -2]], "run_time": 1}])
    code, out, err = _run(capsys, "culane", pred, gt, "--size", "640x360", "--json")
    assert code == 0 and json.loads(out)["0.5"]["fn"] == 1, err


def test_video_tusimple_predictions_past_the_old_limits_are_scored(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """65 predicted lanes in a frame, a prediction row at y = 150,000: the C++ metric scores both."""
    h = [300, 310, 320]
    gt = _jsonl(tmp_path / "g.json", [{"raw_file": "clips/c/1.jpg", "lanes": [[100, 101, 102]], "h_samples": h}])
    pred = _jsonl(
        tmp_path / "p.json",
        [{"raw_file": "clips/c/1.jpg", "lanes": [[100, 101, 102]] + [[500, 501, 502]] * 64, "h_samples": h}],
    )
    code, out, err = _run(capsys, "video", pred, gt, "--size", "640x360", "--json")
    assert code == 0, err
    far = _jsonl(
        tmp_path / "far.json",
        [{"raw_file": "clips/c/1.jpg", "lanes": [[100, 101, 102]], "h_samples": [300, 310, 150000]}],
    )
    code, out, err = _run(capsys, "video", far, gt, "--size", "640x360", "--json")
    assert code == 0 and json.loads(out), err
    assert read_tusimple(far)[0]["h_samples"][2] == 150000


def test_any_line_width_the_cpp_tool_draws_is_scored(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``-w`` of the C++ tool takes any thickness OpenCV draws (up to 32,767): --width 2000 is scored (every lane
    covers the image: IoU 1), one past OpenCV's limit refused in one line."""
    from stamlane_eval.io import MAX_LANE_WIDTH

    for sub in ("pred", "anno"):
        (tmp_path / sub / "d").mkdir(parents=True)
        (tmp_path / sub / "d" / "0.lines.txt").write_text("100 590 200 300\n")
    (tmp_path / "pred" / "d" / "0.lines.txt").write_text("900 590 1000 300\n")
    code, out, err = _run(capsys, "culane", tmp_path / "pred", tmp_path / "anno", "--width", "2000", "--json")
    assert code == 0 and json.loads(out)["0.5"]["tp"] == 1, err
    code, out, err = _run(capsys, "culane", tmp_path / "pred", tmp_path / "anno", "--width", str(MAX_LANE_WIDTH + 1))
    assert code == 2 and out == "" and "lane width" in err and len(err.strip().splitlines()) == 1
