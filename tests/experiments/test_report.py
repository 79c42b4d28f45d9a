"""The report: the paper's tables from one or several run sets, replication, and the claims it makes."""

from __future__ import annotations

import numpy as np
from stamlane_eval.stats import seed_interval

from stamlane.experiments.paper_report import paper_tables, replication
from stamlane.experiments.plots import plot_reveal, reveal_points
from stamlane.experiments.summary import FORMAT, Difference, ModelEntry, Summary, Value
from stamlane.experiments.table_index import load_tables

SPLITS = ("test", "challenging")


def _value(mean: float, std: float | None = None) -> dict:
    return {"mean": mean, "std": std, "ci95": None, "seeds": 1, "images": 0}


def _difference(a: str, b: str, view: str, diff: float, metric: str = "tusimple_f1", **seeds: object) -> dict:
    """``a - b`` with the clip interval ``diff -+ 0.01``."""
    found = {"kind": "models", "a": a, "b": b, "view": view, "metric": metric, "diff": diff}
    return found | {"ci95": [diff - 0.01, diff + 0.01], **seeds}


def _summary(rows: dict[str, float], diffs: dict[tuple[str, str], float]) -> dict:
    """A summary with one seed: ``rows`` = paper row -> F1 (test = challenging), ``diffs`` = paired F1
    differences (interval +-0.01)."""
    models = [
        {
            "name": r,
            "label": r,
            "paper_row": r,
            "configs": [],
            "frames": 0,
            "steps": 0,
            "runs": [],
            "values": {"tusimple_f1": {split: _value(f) for split in SPLITS}},
        }
        for r, f in rows.items()
    ]
    differences = [_difference(a, b, split, d) for (a, b), d in diffs.items() for split in SPLITS]
    return {
        "data": "",
        "splits_sha256": {},
        "seeds": [0],
        "recipe": {},
        "bf16": False,
        "iou_width": None,
        "models": models,
        "differences": differences,
        "format": FORMAT,
    }


def test_paper_tables_from_two_run_sets_compare_each_row_inside_its_own_set() -> None:
    first = _summary(
        {"f1_keyonly": 0.90, "f4_mixed_cs_features": 0.92, "f4_add": 0.95},
        {
            ("f4_mixed_cs_features", "f1_keyonly"): 0.02,
            ("f4_add", "f1_keyonly"): 0.05,
            ("f4_add", "f4_mixed_cs_features"): 0.03,
        },
    )
    second = _summary(  # another run set: its own one frame and STAM, and a row the first has not got
        {"f1_keyonly": 0.80, "f4_mixed_cs_features": 0.81, "f4_parallel_features": 0.86},
        {("f4_parallel_features", "f1_keyonly"): 0.06, ("f4_parallel_features", "f4_mixed_cs_features"): 0.05},
    )
    index = load_tables()
    table = paper_tables([Summary.from_dict(first), Summary.from_dict(second)], index, ["3", "4"]).splitlines()
    row = {line.split("`")[1]: line for line in table if line.startswith("| ") and "`" in line}
    assert "| run set |" in table[2]
    # STAM, one frame and the sum come from set 1, the parallel mode from set 2, compared with set 2's rows
    assert "| 1 | 92.0 | 92.0 |" in row["f4_mixed_cs_features"]
    assert row["f4_add"].endswith(
        "| **+5.0 [+4.0, +6.0]** / **+5.0 [+4.0, +6.0]** | **+3.0 [+2.0, +4.0]** / **+3.0 [+2.0, +4.0]** | – |"
    )
    assert "| 2 | 86.0 | 86.0 |" in row["f4_parallel_features"]
    assert row["f4_parallel_features"].endswith(
        "| **+6.0 [+5.0, +7.0]** / **+6.0 [+5.0, +7.0]** | **+5.0 [+4.0, +6.0]** / **+5.0 [+4.0, +6.0]** | – |"
    )
    assert "|  | not run |" in row["f4_serial_cs_features"]
    # Table 3's rows are from set 2 and STAM (from set 1) is shown for both sets; Table 4's from set 1 only
    three = table[: table.index(next(line for line in table if line.startswith("**Table 4")))]
    stam = [line for line in three if "`f4_mixed_cs_features`" in line]
    assert len(stam) == 2 and "| 1 | 92.0 |" in stam[0] and "| 2 | 81.0 |" in stam[1]
    assert stam[0].endswith("| 1 | 92.0 | 92.0 | **+2.0 [+1.0, +3.0]** / **+2.0 [+1.0, +3.0]** | – | – |")
    assert stam[1].endswith("| 2 | 81.0 | 81.0 | – / – | – | – |")  # set 2 compared no STAM with one frame
    # the rows trained in both sets, set beside set; a row of one set only is not listed
    both = [
        line
        for line in replication([Summary.from_dict(first), Summary.from_dict(second)], index).splitlines()[2:]
        if "`" in line
    ]
    assert [line.split("`")[1] for line in both] == ["f1_keyonly"] * 2 + ["f4_mixed_cs_features"] * 2
    assert both[2].startswith("| 4 frames (features) (`f4_mixed_cs_features`) | 1 | 92.0 | 92.0 | **+2.0")
    assert both[3].endswith("| 2 | 81.0 | 81.0 | – / – |")
    # one summary: no run-set column
    assert "run set" not in paper_tables([Summary.from_dict(first)], index, ["4"])


def test_paper_tables_show_the_interval_over_seeds_and_claim_only_what_both_intervals_support() -> None:
    seed_diffs = [0.03, 0.0, 0.03]  # per seed, 3 points, 0, 3 points
    seeds = {"seed_diffs": seed_diffs, "seed_ci95": list(seed_interval(seed_diffs).interval)}
    summary = _summary({"f1_keyonly": 0.9, "f4_mixed_cs_features": 0.9}, {})
    summary["seeds"] = [0, 1, 2]
    summary["differences"] = [
        _difference("f4_mixed_cs_features", "f1_keyonly", split, 0.02, **seeds) for split in SPLITS
    ]
    index = load_tables()
    line = next(
        ln for ln in paper_tables([Summary.from_dict(summary)], index, ["1"]).splitlines() if "`f4_mixed_cs_f" in ln
    )
    # mean 2.0, std 1.732, t(0.975, 2) = 4.303: 2.0 -+ 4.30 -> [-2.3, +6.3]; the clip interval alone excludes 0
    assert line.endswith("| +2.0 [+1.0, +3.0] s[-2.3, +6.3] / +2.0 [+1.0, +3.0] s[-2.3, +6.3] | – | – |")


def test_paper_iou_tables_come_at_both_thresholds_with_the_difference_from_the_baseline() -> None:
    summary = _summary({"f1_keyonly": 0.90, "f4_mixed_cs_features": 0.92, "f2_noalign_add": 0.91, "f2_add": 0.93}, {})
    for m, f1 in zip(summary["models"], (0.40, 0.45, 0.42, 0.47)):
        for key, more in (("culane_f1@0.5", 0.0), ("culane_f1@0.3", 0.2)):
            m["values"][key] = {split: _value(f1 + more) for split in SPLITS}
    summary["differences"] = [
        _difference("f2_add", "f2_noalign_add", split, d, metric=key)
        for key, d in (("culane_f1@0.5", 0.05), ("culane_f1@0.3", -0.02))
        for split in SPLITS
    ]
    index = load_tables()
    table = paper_tables([Summary.from_dict(summary)], index, ["8"]).splitlines()
    headings = [line for line in table if line.startswith("**Table 8")]
    assert [h.split("**")[2].split(" (")[0] for h in headings] == [", IoU F1 @0.5", ", IoU F1 @0.3"]
    assert "| row | paper IoU F1 @0.5 |" in table[2] and table[2].endswith(
        "| − baseline (test / chall.) | history use (test / chall.) |"
    )
    at_05, at_03 = (line for line in table if "`f2_add`" in line)
    assert at_05.startswith("| alignment, sum (`f2_add`) | 50.12 | 47.0 | 47.0 |")  # the paper's 0.5012
    assert at_05.endswith("| **+5.0 [+4.0, +6.0]** / **+5.0 [+4.0, +6.0]** | – |")
    assert at_03.startswith("| alignment, sum (`f2_add`) | 67.12 | 67.0 | 67.0 |")
    assert at_03.endswith("| **-2.0 [-3.0, -1.0]** / **-2.0 [-3.0, -1.0]** | – |")
    assert "| not run |" in next(line for line in table if "`f2_noalign_mixed_cs_gates`" in line)
    # a summary without the IoU F1: its rows are not in the IoU tables
    old = _summary({"f1_keyonly": 0.90, "f2_add": 0.93}, {})
    assert "(0 of 6 rows run" in paper_tables([Summary.from_dict(old)], index, ["8"])


def test_replication_says_how_far_two_run_sets_agree() -> None:
    rows = ("f4_add", "f4_cosine", "f4_stpsa")
    first = _summary(
        {"f1_keyonly": 0.9, **dict.fromkeys(rows, 0.9)},
        dict(zip(((r, "f1_keyonly") for r in rows), (0.05, 0.02, -0.01))),
    )
    second = _summary(
        {"f1_keyonly": 0.9, **dict.fromkeys(rows, 0.9)},
        dict(zip(((r, "f1_keyonly") for r in rows), (0.04, -0.03, -0.02))),
    )
    index = load_tables()
    last = replication([Summary.from_dict(first), Summary.from_dict(second)], index).splitlines()[-1]
    r = np.corrcoef([0.05, 0.02, -0.01], [0.04, -0.03, -0.02])[0, 1]
    assert last.startswith("Rows trained in run sets 1 and 2: 3.") and f"correlation {r:+.2f}" in last
    # the sum: claimed in both, same sign; the weighted sum: claimed in both, opposite signs; ST-PSA: in set 2 only
    assert "the same sign in 2 of 3, and 1 of 3 differences claimed in one set" in last


def test_history_use_is_placed_against_the_headroom_of_each_models_own_clip_length(tmp_path) -> None:
    view, metric = "reveal:key_flash", "tusimple_f1"

    def difference(kind: str, a: str, b: str, diff: float) -> Difference:
        return Difference(kind, a, b, view, metric, diff, [diff - 0.01, diff + 0.01])

    def model(name: str, frames: int) -> ModelEntry:
        values = {metric: {view: Value(0.8, None, None, 1, 30)}}
        return ModelEntry(name, name, None, [], frames, 300, [], values, probes={"key": values})

    summary = Summary("", {}, [0], {}, False, None, [model("two", 2), model("four", 4), model("single", 1)])
    summary.models[2].probes = {}
    summary.differences = [
        difference("headroom", "oracle:history-2f", "oracle:key", 0.10),  # one history frame shows less
        difference("headroom", "oracle:history-4f", "oracle:key", 0.30),
        difference("history_key", "two", "two@key", 0.05),
        difference("history_key", "four", "four@key", 0.20),
    ]
    points = {p.model: p for p in reveal_points(summary)}
    assert set(points) == {"two", "four"}  # the single frame has no history to use
    assert (points["two"].frames, points["two"].headroom.diff, points["two"].use.diff) == (2, 0.10, 0.05)
    assert (points["four"].frames, points["four"].headroom.diff, points["four"].use.diff) == (4, 0.30, 0.20)
    assert plot_reveal(summary, tmp_path / "reveal.png").stat().st_size > 0
