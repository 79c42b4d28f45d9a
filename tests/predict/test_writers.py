"""stamlane.predict.writers: TuSimple json-lines and CULane .lines.txt, scored by stamlane-eval unconverted."""

from __future__ import annotations

import json

import numpy as np
import pytest
from stamlane_eval.cli import main as eval_main
from stamlane_eval.io import culane_lines_path, read_culane_lines, read_tusimple

from stamlane.predict.writers import TusimpleWriter, format_culane_lines, tusimple_record, write_culane_lines

H_SAMPLES = list(range(240, 720, 10))


def _lanes(shift: float = 0.0) -> list[np.ndarray]:
    ys = np.arange(300.0, 711.0, 5.0)
    return [np.stack([x0 + k * (ys - 300) + shift, ys], 1) for x0, k in ((500.0, -0.8), (700.0, 0.9))]


def test_tusimple_round_trip_scores_perfectly(tmp_path, capsys) -> None:
    gt_path, pred_path = tmp_path / "gt.json", tmp_path / "pred.json"
    with gt_path.open("w") as f:
        for i in range(3):
            xs = [[float(x) if x >= 0 else -2 for x in lane] for lane in _xs(_lanes())]
            f.write(json.dumps({"raw_file": f"clips/{i}/20.jpg", "lanes": xs, "h_samples": H_SAMPLES}) + "\n")
    with TusimpleWriter(pred_path) as writer:
        for i in range(3):
            writer.write(f"clips/{i}/20.jpg", _lanes(shift=3.0), H_SAMPLES, run_time=12.5)
    assert writer.count == 3
    records = read_tusimple(pred_path)
    assert [r["raw_file"] for r in records] == [f"clips/{i}/20.jpg" for i in range(3)]
    assert records[0]["run_time"] == 12.5 and records[0]["h_samples"] == H_SAMPLES
    lane = records[0]["lanes"][0]
    assert lane[:6] == [-2] * 6 and lane[6] == 503.0  # rows above the lane are -2; y=300 -> x=500+3
    assert eval_main(["tusimple", str(pred_path), str(gt_path), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["accuracy"] == 1.0 and result["f1"] == 1.0


def _xs(lanes: list[np.ndarray]) -> list[list[float]]:
    return tusimple_record("x", lanes, H_SAMPLES, 0.0)["lanes"]


def test_tusimple_record_checks() -> None:
    with pytest.raises(ValueError, match=r"h_samples of 'a\.jpg' is empty"):
        tusimple_record("a.jpg", _lanes(), [], 1.0)
    assert tusimple_record("a.jpg", [], H_SAMPLES, 1.0)["lanes"] == []


def test_culane_round_trip_scores_perfectly(tmp_path, capsys) -> None:
    gt_dir, pred_dir = tmp_path / "gt", tmp_path / "pred"
    names = ["driver_1/a.MP4/00000.jpg", "/driver_1/a.MP4/00030.jpg"]
    for name in names:
        write_culane_lines(gt_dir, name, _lanes())
        path = write_culane_lines(pred_dir, name, _lanes(shift=1.0))
        assert path == culane_lines_path(pred_dir, name) and path.name.endswith(".lines.txt")
    back = read_culane_lines(culane_lines_path(pred_dir, names[0]))
    assert len(back) == 2 and np.allclose(back[1], _lanes(shift=1.0)[1], atol=0.005)
    assert eval_main(["culane", str(pred_dir), str(gt_dir), "--size", "1280x720", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["images"] == 2 and result["0.5"]["tp"] == 4 and result["0.5"]["f1"] == 1.0


def test_culane_format_checks(tmp_path) -> None:
    assert format_culane_lines([np.array([[1.0, 2.0]])]) == ""  # a 1-point lane is not written
    with pytest.raises(ValueError, match=r"expected a lane of shape \(N, 2\), got \(3,\)"):
        format_culane_lines([np.zeros(3)])
    with pytest.raises(ValueError, match="leaves the folder"):  # the writer refuses what the evaluator would
        write_culane_lines(tmp_path, "a/../../b.jpg", [np.zeros((2, 2))])
