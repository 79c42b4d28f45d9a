"""The rule of docs/evaluators.md ("What is scored and what is refused"), on both sides, for ``stamlane-eval
tusimple``: every submission the official lane.py scores to rates gets lane.py's numbers (at most one warning
line); a submission where lane.py crashes or returns numbers that are not rates is refused in one line, exit 2.

lane.py's results on each case are in ``golden/tusimple_rule_cases.json``, made by
``golden/make_tusimple_rule_cases.py`` with the official file (TuSimple/tusimple-benchmark ``evaluate/lane.py``,
sha256 recorded in the json); the submissions themselves are built by that script's ``CASES``.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType

import pytest
from stamlane_eval import tusimple
from stamlane_eval.cli import main
from stamlane_eval.io import read_tusimple

GOLDEN = Path(__file__).parent / "golden"


def _cases_module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_rule_cases", GOLDEN / "make_tusimple_rule_cases.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


MAKE = _cases_module()
LANE_PY = {c["name"]: c["lane_py"] for c in json.loads((GOLDEN / "tusimple_rule_cases.json").read_text())["cases"]}

# lane.py scores these and so do we, to its numbers
SCORED = sorted(n for n, r in LANE_PY.items() if r["status"] == "ok")
# lane.py gives a number; we refuse on purpose (docs): types are the format's
REFUSED_BY_THE_FORMAT = {
    "pred_x_true": "boolean",
}
# scored with one warning line: values that are no pixel coordinate, in either file
ODD = {
    *(n for n in LANE_PY if n.startswith("pred_x_") and n not in ("pred_x_fractional", "pred_x_true")),
    "run_time_NaN",
    "run_time_Infinity",
    "gt_x_1e9",
    "gt_x_NaN",
    "gt_x_150000_issue_59",
    "gt_x_minus_Infinity",
    "gt_x_1e308",
    "gt_x_Infinity_alone_on_its_lane",
    "gt_x_Infinity_early_return",
    "h_samples_150000",
    "h_samples_NaN_on_a_row_without_lane",
}
# lane.py's numbers are not rates
NOT_RATES = {
    "gt_duplicate_raw_file": "two labels for one image",
    "six_gt_lanes_accuracy_above_1": "accuracy would be 1.25, not a rate",
    "one_pred_matches_two_gt_fp_below_0": "fp would be -1.0, not a rate",
}
SCORED = [n for n in SCORED if n not in REFUSED_BY_THE_FORMAT and n not in NOT_RATES]
CRASHES = sorted(n for n, r in LANE_PY.items() if r["status"] == "error")


def test_every_case_is_classified() -> None:
    assert set(MAKE.CASES) == set(LANE_PY)
    assert len(SCORED) == 28 and len(CRASHES) == 7
    assert set(SCORED) | set(REFUSED_BY_THE_FORMAT) | set(NOT_RATES) | set(CRASHES) == set(LANE_PY)


def _run(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, *extra: str) -> tuple[int, str, str]:
    pred_text, gt_text = MAKE.CASES[name]()
    (tmp_path / "pred.json").write_text(pred_text)
    (tmp_path / "gt.json").write_text(gt_text)
    code = main(["tusimple", str(tmp_path / "pred.json"), str(tmp_path / "gt.json"), *extra])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("name", SCORED)
def test_scored_to_lane_py_numbers(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str) -> None:
    code, out, err = _run(tmp_path, capsys, name, "--json")
    assert code == 0, err
    got = json.loads(out)
    want = LANE_PY[name]
    assert (got["accuracy"], got["fp"], got["fn"]) == (want["accuracy"], want["fp"], want["fn"])
    assert len(err.splitlines()) <= 1 and "Traceback" not in err
    assert ("no pixel coordinate" in err) == (name in ODD), err


@pytest.mark.parametrize("name", sorted(REFUSED_BY_THE_FORMAT) + sorted(NOT_RATES) + CRASHES)
def test_refused_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str) -> None:
    code, out, err = _run(tmp_path, capsys, name)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    words = REFUSED_BY_THE_FORMAT.get(name) or NOT_RATES.get(name) or ""
    assert words in err, err


def test_a_wild_value_changes_only_its_image(shared_dir: Path) -> None:
    """The regression the rule fixed: one x = 1e9 among the 300 fixture images; every other image keeps lane.py's
    number, and that image is scored as lane.py scores it (the row is a miss)."""
    d = shared_dir / "fixtures" / "evaluators" / "tusimple"
    preds, gts = read_tusimple(d / "pred.json"), read_tusimple(d / "gt.json")
    expected = json.loads((d / "expected.json").read_text())["per_image"]
    k = next(i for i, e in enumerate(expected) if e["acc"] == 1.0 and e["fp"] == 0.0 and preds[i]["lanes"])
    row = next(r for r, x in enumerate(preds[k]["lanes"][0]) if x >= 0)
    preds[k]["lanes"][0][row] = 1e9
    with pytest.warns(UserWarning, match=r"1 prediction value\(s\) are no pixel coordinate"):
        res = tusimple.evaluate(preds, gts)
    got = [(r.acc, r.fp, r.fn) for r in res.per_image]
    want = [(e["acc"], e["fp"], e["fn"]) for e in expected]
    assert [i for i, (g, w) in enumerate(zip(got, want, strict=True)) if g != w] == [k]
    gt = next(g for g in gts if g["raw_file"] == preds[k]["raw_file"])
    alone = tusimple.evaluate_image(preds[k]["lanes"], gt["lanes"], gt["h_samples"], preds[k]["run_time"])
    assert got[k] == (alone.acc, alone.fp, alone.fn) and got[k][0] < 1.0


def test_a_huge_prediction_is_a_miss_and_a_negative_one_absent() -> None:
    h = list(range(160, 720, 10))
    gt = [[300.0] * 56]
    for wild, acc in ((1e9, 55 / 56), (-1e9, 55 / 56), (float("nan"), 55 / 56), (float("inf"), 55 / 56)):
        assert tusimple.evaluate_image([[wild] + [300.0] * 55], gt, h).acc == acc
    absent = [[-2.0] + [300.0] * 55]
    assert tusimple.evaluate_image([[-1e9] + [300.0] * 55], absent, h).acc == 1.0  # both absent: a hit
    assert tusimple.evaluate_image([[10**400] + [300.0] * 55], gt, h).acc == 55 / 56  # beyond the float range
