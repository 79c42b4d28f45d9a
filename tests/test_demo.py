"""``stamlane demo``: the quick smoke run writes every artefact; bad input is one line and exit status 2."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import yaml
from stamlane_eval.stats import seed_interval
from stamlane_eval.tusimple import paper_f1

from stamlane.cli import main
from stamlane.demo import SCORING, _pairs, iou_width, score_split
from stamlane.synth.generator import FACTORS

torch.set_num_threads(1)
REPO = Path(__file__).resolve().parents[1]


def test_demo_quick_writes_summary_plot_predictions(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    models = {m["name"]: m for m in summary["models"]}
    assert list(models) == ["stam4", "single"]  # --quick leaves the no-alignment ablation out
    assert [models[n]["frames"] for n in models] == [4, 1]
    assert summary["steps"] == 3 + 2 and summary["seeds"] == [0]
    # stage 2 starts from the final weights of stage 1
    assert (
        "init_weights: " + str(out / "pretrain-s0" / "run" / "checkpoints" / "last.ckpt")
        in (out / "stam4-s0" / "run" / "config.yaml").read_text()
    )
    for entry in models.values():
        (run,) = entry["runs"]
        assert Path(run["last_ckpt"]).is_file()
        for split, images in (("test", 2), ("challenging", 2 * len(FACTORS))):
            scores = run[split]
            assert scores["images"] == images
            pred = out / "predictions" / f"{entry['name']}-s0" / split
            assert len((pred / "predictions.json").read_text().splitlines()) == images
            assert len(list((pred / "overlays").rglob("*.jpg"))) == min(images, 12)  # --max-overlays 12
            per_image = [json.loads(line) for line in (pred / "per_image.jsonl").read_text().splitlines()]
            assert [r["clip"] for r in per_image] == [f"clips/{split}-{i:04d}" for i in range(images)]
            # the run's F1 is the paper's F1 of the per-image rates the file holds
            fp = sum(r["fp"] for r in per_image) / images
            fn = sum(r["fn"] for r in per_image) / images
            assert scores["f1"] == pytest.approx(paper_f1(fp, fn))
            agg = entry[split]
            assert agg["f1_mean"] == pytest.approx(scores["f1"]) and agg["f1_std"] is None
            assert agg["f1_ci95"][0] <= agg["f1_mean"] + 1e-9 and agg["f1_ci95"][1] >= agg["f1_mean"] - 1e-9
        # per factor: the F1 of the factor's two clips, from the same per-image rates
        per_image = [
            json.loads(line)
            for line in (out / "predictions" / f"{entry['name']}-s0" / "challenging" / "per_image.jsonl")
            .read_text()
            .splitlines()
        ]
        assert list(entry["factors"]) == list(FACTORS)
        for k, factor in enumerate(FACTORS):
            rows = [per_image[k], per_image[k + len(FACTORS)]]  # clip i has factor i % len(FACTORS)
            fp, fn = (sum(r[key] for r in rows) / 2 for key in ("fp", "fn"))
            found = entry["factors"][factor]
            assert found["images"] == 2 and found["f1_mean"] == pytest.approx(paper_f1(fp, fn))
            assert found["f1_ci95"] is not None
        # the IoU F1 of each split: the run's own totals (one seed), at both thresholds
        for key, t in (("iou@0.5", "0.5"), ("iou@0.3", "0.3")):
            for split in ("test", "challenging"):
                assert entry[key][split]["f1_mean"] == pytest.approx(run[split]["iou"][t]["f1"], abs=1e-12)
            assert list(entry[key]["factors"]) == list(FACTORS)
    pairs = {(c["a"], c["b"], c["split"]) for c in summary["comparisons"]}
    views = ["test", "challenging", *(f"challenging:{f}" for f in FACTORS)]
    assert pairs == {("stam4", "single", view) for view in views}
    assert {(c["metric"], c["split"]) for c in summary["iou_comparisons"]} == {
        (metric, view) for metric in ("iou@0.5", "iou@0.3") for view in views
    }
    assert summary["iou_width"] == 5  # 30 px at 1640 px wide, at the quick set's 256
    plot = cv2.imread(str(out / "val_f1.png"))
    assert plot.shape == (480, 720, 3) and plot.std() > 10  # 6x4 in at 120 dpi, not a blank page
    grid = cv2.imread(str(out / "comparison.jpg"))  # 2 challenging key frames (rows) x 2 models (columns)
    assert grid.shape == (3 * 144, 2 * 256, 3) and grid.std() > 10
    table = capsys.readouterr().out
    assert "1 frame (baseline)" in table and "challenging F1 % [95% CI]" in table and "stam4 - single" in table
    assert "IoU F1 % (CULane-style, 5 px lines)" in table
    assert "challenging split per factor" in table and all(f in table for f in FACTORS)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--pretrain-steps", "0"], "--pretrain-steps must be >= 1, got 0"),
        (["--finetune-steps", "-1"], "--finetune-steps must be >= 1, got -1"),
        (["--data", __file__], "is not a folder"),
        (["--seeds", "0"], "--seeds must be >= 1, got 0"),
        (["--rows", "f4_nope"], "no paper row 'f4_nope'; known rows: f1_cbam"),
        (["--quick", "--out", __file__], "is a file, not a folder"),
    ],
)
def test_demo_bad_input(argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["demo", "--out", str(tmp_path), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err


def test_demo_needs_the_other_pieces(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys) -> None:
    monkeypatch.setitem(sys.modules, "stamlane.losses", None)  # as if the losses were not there yet
    assert main(["demo", "--quick", "--out", str(tmp_path)]) == 2
    assert "needs pieces that are not installed yet: stamlane.losses" in capsys.readouterr().err


def test_demo_reuses_finished_runs_and_refuses_other_settings(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--out", str(out)]) == 0
    first = json.loads((out / "stam4-s0" / "done.json").read_text())
    capsys.readouterr()
    assert main(["demo", "--quick", "--seeds", "2", "--out", str(out)]) == 0  # seed 0 reused, seed 1 trained
    printed = capsys.readouterr().out
    assert "seed 0, stage 1: done before, reused" in printed and "seed 1, stage 1: 1 frame" in printed
    assert json.loads((out / "stam4-s0" / "done.json").read_text()) == first  # not retrained
    summary = json.loads((out / "summary.json").read_text())
    runs = {m["name"]: m["runs"] for m in summary["models"]}
    assert [r["seed"] for r in runs["stam4"]] == [0, 1]
    assert runs["stam4"][0]["test"] == first["test"]
    assert summary["models"][0]["test"]["f1_std"] is not None  # two seeds: a spread
    # the difference per seed is that of the two runs' own scores; its interval is the t interval over seeds
    diff = next(c for c in summary["comparisons"] if (c["a"], c["b"], c["split"]) == ("stam4", "single", "test"))
    f1 = {(m, s): runs[m][s]["test"]["f1"] for m in ("stam4", "single") for s in (0, 1)}
    assert diff["seed_diffs"] == pytest.approx([f1["stam4", s] - f1["single", s] for s in (0, 1)], abs=1e-12)
    assert diff["seed_ci95"] == pytest.approx(list(seed_interval(diff["seed_diffs"]).interval), abs=1e-12)
    # the same folder with another budget: one line, exit 2, nothing overwritten
    assert main(["demo", "--out", str(out), "--data", str(out / "quick_data"), "--finetune-steps", "7"]) == 2
    err = capsys.readouterr().err.strip()
    assert "was made with other settings" in err and len(err.splitlines()) == 1
    assert json.loads((out / "stam4-s0" / "done.json").read_text()) == first


def test_demo_precision_is_passed_recorded_and_never_mixed(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--no-noalign", "--bf16", "true", "--out", str(out)]) == 0
    assert json.loads((out / "summary.json").read_text())["bf16"] is True
    for run in ("pretrain-s0", "stam4-s0", "single-s0"):
        assert "  bf16: true" in (out / run / "run" / "config.yaml").read_text().splitlines()
        assert json.loads((out / run / "done.json").read_text())["bf16"] is True
    capsys.readouterr()
    # float32 results are not mixed into a bfloat16 folder: one line, exit 2
    assert main(["demo", "--quick", "--no-noalign", "--bf16", "false", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "was made with other settings" in err and "'bf16': True" in err and len(err.splitlines()) == 1


def test_demo_scores_a_finished_run_again_when_a_split_changes(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--out", str(out)]) == 0
    first = json.loads((out / "single-s0" / "done.json").read_text())
    labels = out / "quick_data" / "challenging.json"
    kept = labels.read_text().splitlines()[: len(FACTORS)]  # a newer generator wrote another split
    labels.write_text("".join(line + "\n" for line in kept))
    # a run scored under older rules (the 200 ms rule on) is scored again from its predictions, not predicted
    done = out / "stam4-s0" / "done.json"
    before = json.loads(done.read_text())
    done.write_text(json.dumps({k: v for k, v in before.items() if k != "scoring"}))
    preds = out / "predictions" / "stam4-s0" / "test" / "predictions.json"
    records = [json.loads(line) for line in preds.read_text().splitlines()]
    records[0]["run_time"] = 500.0  # a busy machine
    preds.write_text("".join(json.dumps(r) + "\n" for r in records))
    capsys.readouterr()
    # and rows of the tables: f4_add is trained, f4_mixed_cs_features IS the demo's stam4 and is not trained again
    assert main(["demo", "--quick", "--out", str(out), "--rows", "f4_add", "f4_mixed_cs_features"]) == 0
    printed = capsys.readouterr().out
    assert "single-s0: the challenging labels changed, scoring them again" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert not (out / "f4_mixed_cs_features-s0").exists()
    assert {m["name"]: m["paper_row"] for m in summary["models"]} == {
        "stam4": "f4_mixed_cs_features",
        "single": "f1_keyonly",
        "f4_add": "f4_add",
    }
    row = next(m for m in summary["models"] if m["name"] == "f4_add")
    assert row["configs"][-1] == "configs/paper/rows/f4_add.yaml" and row["frames"] == 4
    assert "SimpleAdd" in (out / "f4_add-s0" / "run" / "config.yaml").read_text()
    assert {(c["a"], c["b"]) for c in summary["comparisons"] if c["split"] == "test"} == {
        ("stam4", "single"),
        ("f4_add", "single"),
        ("f4_add", "stam4"),
    }
    assert "test labels changed" not in printed
    again = json.loads((out / "single-s0" / "done.json").read_text())
    assert again["challenging"]["images"] == len(FACTORS) and again["test"] == first["test"]
    assert again["labels"]["test"] == first["labels"]["test"] != again["labels"]["challenging"]
    rescored = json.loads(done.read_text())
    assert rescored["scoring"] == SCORING and rescored["test"]["late"] == 1
    assert json.loads(preds.read_text().splitlines()[0])["run_time"] == 500.0  # not predicted again
    assert rescored["test"]["f1"] == before["test"]["f1"] and before["test"]["late"] == 0
    # the paper's Table 4 from this summary (benchmarks/demo_tables.py, as docs/results.md is made)
    demo_tables = _demo_tables()
    index = yaml.safe_load((REPO / "configs" / "paper" / "tables.yaml").read_text())
    table = demo_tables.paper_tables(summary, index, ["4"]).splitlines()
    assert "(2 of 7 rows run, 1 seed)" in table[0]
    add = next(line for line in table if "`f4_add`" in line)
    assert f"{100 * row['test']['f1_mean']:.1f}" in add and add.count("[") >= 4  # F1 and both paired differences
    assert "| not run |" in next(line for line in table if "`f4_convlstm`" in line)
    stam = next(line for line in table if "`f4_mixed_cs_features`" in line)
    assert "not run" not in stam and stam.endswith("| – |")  # STAM against itself: no difference


def _demo_tables():
    spec = importlib.util.spec_from_file_location("demo_tables", REPO / "benchmarks" / "demo_tables.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _summary(rows: dict[str, float], diffs: dict[tuple[str, str], float]) -> dict:
    """A demo summary with one seed: ``rows`` = paper row -> F1 (test = challenging), ``diffs`` = paired F1
    differences (interval +-0.01)."""
    score = {"f1_mean": 0.0, "f1_std": None, "f1_ci95": None}
    models = [
        {"name": r, "paper_row": r, "test": score | {"f1_mean": f}, "challenging": score | {"f1_mean": f}}
        for r, f in rows.items()
    ]
    comparisons = [
        {"a": a, "b": b, "split": split, "f1_diff": d, "ci95": [d - 0.01, d + 0.01]}
        for (a, b), d in diffs.items()
        for split in ("test", "challenging")
    ]
    return {"seeds": [0], "models": models, "comparisons": comparisons}


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
    index = yaml.safe_load((REPO / "configs" / "paper" / "tables.yaml").read_text())
    table = _demo_tables().paper_tables([first, second], index, ["3", "4"]).splitlines()
    row = {line.split("`")[1]: line for line in table if line.startswith("| ") and "`" in line}
    assert "| run set |" in table[2]
    # STAM, one frame and the sum come from set 1, the parallel mode from set 2, compared with set 2's rows
    assert "| 1 | 92.0 | 92.0 |" in row["f4_mixed_cs_features"]
    assert row["f4_add"].endswith(
        "| **+5.0 [+4.0, +6.0]** / **+5.0 [+4.0, +6.0]** | **+3.0 [+2.0, +4.0]** / **+3.0 [+2.0, +4.0]** |"
    )
    assert "| 2 | 86.0 | 86.0 |" in row["f4_parallel_features"]
    assert row["f4_parallel_features"].endswith(
        "| **+6.0 [+5.0, +7.0]** / **+6.0 [+5.0, +7.0]** | **+5.0 [+4.0, +6.0]** / **+5.0 [+4.0, +6.0]** |"
    )
    assert "| | not run |" in row["f4_serial_cs_features"]
    # Table 3's rows are from set 2 and STAM (from set 1) is shown for both sets; Table 4's from set 1 only
    three = table[: table.index(next(line for line in table if line.startswith("**Table 4")))]
    stam = [line for line in three if "`f4_mixed_cs_features`" in line]
    assert len(stam) == 2 and "| 1 | 92.0 |" in stam[0] and "| 2 | 81.0 |" in stam[1]
    assert stam[0].endswith("| 1 | 92.0 | 92.0 | **+2.0 [+1.0, +3.0]** / **+2.0 [+1.0, +3.0]** | – |")
    assert stam[1].endswith("| 2 | 81.0 | 81.0 | – / – | – |")  # set 2 compared no STAM with one frame
    # the rows trained in both sets, set beside set; a row of one set only is not listed
    both = [line for line in _demo_tables().replication([first, second], index).splitlines()[2:] if "`" in line]
    assert [line.split("`")[1] for line in both] == ["f1_keyonly"] * 2 + ["f4_mixed_cs_features"] * 2
    assert both[2].startswith("| 4 frames (features) (`f4_mixed_cs_features`) | 1 | 92.0 | 92.0 | **+2.0")
    assert both[3].endswith("| 2 | 81.0 | 81.0 | – / – |")
    # one summary: no run-set column
    assert "run set" not in _demo_tables().paper_tables(first, index, ["4"])


def test_paper_tables_show_the_interval_over_seeds_and_claim_only_what_both_intervals_support() -> None:
    """A summary written before the demo kept per-seed differences: the interval over seeds comes from its runs."""
    runs = {"f1_keyonly": [0.90, 0.91, 0.92], "f4_mixed_cs_features": [0.93, 0.91, 0.95]}  # diffs 3, 0, 3 points
    score = {"f1_mean": 0.9, "f1_std": 0.01, "f1_ci95": None}
    summary = {
        "seeds": [0, 1, 2],
        "models": [
            {
                "name": row,
                "paper_row": row,
                "test": score,
                "challenging": score,
                "runs": [{"seed": s, "test": {"f1": f}, "challenging": {"f1": f}} for s, f in enumerate(f1)],
            }
            for row, f1 in runs.items()
        ],
        "comparisons": [
            {"a": "f4_mixed_cs_features", "b": "f1_keyonly", "split": split, "f1_diff": 0.02, "ci95": [0.01, 0.03]}
            for split in ("test", "challenging")
        ],
    }
    index = yaml.safe_load((REPO / "configs" / "paper" / "tables.yaml").read_text())
    line = next(ln for ln in _demo_tables().paper_tables(summary, index, ["1"]).splitlines() if "`f4_mixed_cs_f" in ln)
    # mean 2.0, std 1.732, t(0.975, 2) = 4.303: 2.0 -+ 4.30 -> [-2.3, +6.3]; the clip interval alone excludes 0
    assert line.endswith("| +2.0 [+1.0, +3.0] s[-2.3, +6.3] / +2.0 [+1.0, +3.0] s[-2.3, +6.3] | – |")
    assert "seed_ci95" not in summary["comparisons"][0]  # the caller's summary is left as it was


def test_score_split_iou_is_what_stamlane_eval_culane_says(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The demo's IoU F1 of a split equals ``stamlane-eval culane pred.json gt.json`` at the demo's line width,
    per image and in total; a lane moved by a line width is no longer a match, one moved by a pixel still is."""
    from stamlane_eval.cli import main as eval_main

    root = tmp_path / "set"
    root.mkdir()
    (root / "dataset.json").write_text(json.dumps({"config": {"height": 360, "width": 640}}))
    rows = list(range(160, 360, 10))
    gts, preds = [], []
    for i in range(6):
        lanes = [[100 + 20 * i + k * (j - 10) for j in range(len(rows))] for k in (-3, 0, 3)]
        lanes[0][:4] = [-2] * 4  # a lane absent on the far rows
        gts.append({"raw_file": f"clips/test-{i:04d}/8.jpg", "lanes": lanes, "h_samples": rows})
        moved = {0: 0, 1: 1, 2: 14, 3: 40}.get(i, 0)  # px
        found = [[x + moved if x >= 0 else x for x in lane] for lane in lanes]
        if i == 4:
            found = found[1:]  # a lane missed
        elif i == 5:
            found.append([600] * len(rows))  # a lane too many
        preds.append({"raw_file": gts[-1]["raw_file"], "lanes": found, "h_samples": rows, "run_time": 10.0})
    (root / "test.json").write_text("".join(json.dumps(g) + "\n" for g in gts))
    pred_dir = tmp_path / "pred"
    pred_dir.mkdir()
    (pred_dir / "predictions.json").write_text("".join(json.dumps(p) + "\n" for p in preds))
    scores, per_image, clips = score_split(pred_dir, root / "test.json")
    assert iou_width((360, 640)) == scores["iou_width"] == 12
    assert clips == [f"clips/test-{i:04d}" for i in range(6)]
    tp5 = [int(r[0]) for r in per_image["iou@0.5"]]
    assert tp5[:2] == [3, 3] and tp5[3] == 0 and tp5[4] == 2  # 1 px: still a match; 40 px: none is
    capsys.readouterr()
    argv = ["culane", str(pred_dir / "predictions.json"), str(root / "test.json"), "--size", "640x360"]
    assert eval_main([*argv, "--width", "12", "--format", "json", "--per-image", str(tmp_path / "cu.jsonl")]) == 0
    official = json.loads(capsys.readouterr().out)
    for t in ("0.3", "0.5"):
        totals = {k: official[t][k] for k in ("tp", "fp", "fn", "precision", "recall", "f1")}
        assert {k: scores["iou"][t][k] for k in totals} == totals
    cu = [json.loads(line) for line in (tmp_path / "cu.jsonl").read_text().splitlines()]
    assert [r["0.5"] for r in cu] == per_image["iou@0.5"].astype(int).tolist()
    assert [r["0.3"] for r in cu] == per_image["iou@0.3"].astype(int).tolist()
    saved = [json.loads(line) for line in (pred_dir / "per_image.jsonl").read_text().splitlines()]
    assert [r["iou"]["0.5"] for r in saved] == [r["0.5"] for r in cu]


def test_rows_of_a_table_with_a_baseline_are_compared_with_it() -> None:
    """Table 8's rows against its baseline (2 unaligned frames summed) besides one frame and STAM; the baseline
    itself and rows of tables without one are not."""
    models = {
        "stam4": "f4_mixed_cs_features",
        "single": "f1_keyonly",
        "f2_noalign_add": "f2_noalign_add",
        "f2_add": "f2_add",
        "f2_mixed_cs_gates": "f2_mixed_cs_gates",
        "f4_stpsa": "f4_stpsa",
    }
    pairs = _pairs(models)
    assert [p for p in pairs if p[1] == "f2_noalign_add"] == [
        ("f2_add", "f2_noalign_add"),
        ("f2_mixed_cs_gates", "f2_noalign_add"),
    ]
    assert ("f4_stpsa", "single") in pairs and ("f4_stpsa", "stam4") in pairs and len(pairs) == 1 + 4 * 2 + 2
    assert ("stam4", "f4_noalign_add") not in _pairs(models)  # Table 2's baseline was not trained


def test_paper_iou_tables_come_at_both_thresholds_with_the_difference_from_the_baseline() -> None:
    summary = _summary({"f1_keyonly": 0.90, "f4_mixed_cs_features": 0.92, "f2_noalign_add": 0.91, "f2_add": 0.93}, {})
    for m, f1 in zip(summary["models"], (0.40, 0.45, 0.42, 0.47)):
        for key, more in (("iou@0.5", 0.0), ("iou@0.3", 0.2)):
            m[key] = {
                split: {"f1_mean": f1 + more, "f1_std": None, "f1_ci95": None} for split in ("test", "challenging")
            }
    summary["iou_comparisons"] = [
        {
            "a": "f2_add",
            "b": "f2_noalign_add",
            "split": split,
            "metric": key,
            "f1_diff": d,
            "ci95": [d - 0.01, d + 0.01],
        }
        for key, d in (("iou@0.5", 0.05), ("iou@0.3", -0.02))
        for split in ("test", "challenging")
    ]
    index = yaml.safe_load((REPO / "configs" / "paper" / "tables.yaml").read_text())
    table = _demo_tables().paper_tables(summary, index, ["8"]).splitlines()
    headings = [line for line in table if line.startswith("**Table 8")]
    assert [h.split("**")[2].split(" (")[0] for h in headings] == [", IoU F1 @0.5", ", IoU F1 @0.3"]
    assert "| row | paper IoU F1 @0.5 |" in table[2] and table[2].endswith("| − baseline (test / chall.) |")
    at_05, at_03 = (line for line in table if "`f2_add`" in line)
    assert at_05.startswith("| alignment, sum (`f2_add`) | 50.12 | 47.0 | 47.0 |")  # the paper's 0.5012
    assert at_05.endswith("| **+5.0 [+4.0, +6.0]** / **+5.0 [+4.0, +6.0]** |")
    assert at_03.startswith("| alignment, sum (`f2_add`) | 67.12 | 67.0 | 67.0 |")
    assert at_03.endswith("| **-2.0 [-3.0, -1.0]** / **-2.0 [-3.0, -1.0]** |")
    assert "| not run |" in next(line for line in table if "`f2_noalign_mixed_cs_gates`" in line)
    # a summary written before the demo scored IoU: its rows are not in the IoU tables
    old = _summary({"f1_keyonly": 0.90, "f2_add": 0.93}, {})
    assert "(0 of 6 rows run" in _demo_tables().paper_tables(old, index, ["8"])


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
    index = yaml.safe_load((REPO / "configs" / "paper" / "tables.yaml").read_text())
    last = _demo_tables().replication([first, second], index).splitlines()[-1]
    r = np.corrcoef([0.05, 0.02, -0.01], [0.04, -0.03, -0.02])[0, 1]
    assert last.startswith("Rows trained in run sets 1 and 2: 3.") and f"correlation {r:+.2f}" in last
    # the sum: claimed in both, same sign; the weighted sum: claimed in both, opposite signs; ST-PSA: in set 2 only
    assert "the same sign in 2 of 3, and 1 of 3 differences claimed in one set" in last
