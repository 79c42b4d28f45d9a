"""``stamlane ablate``: a two-row table end to end on a tiny synthetic set, resumability, the settings lock,
and the bookkeeping (mean ± std, delta split, CSV / markdown / plot)."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable
from pathlib import Path

import cv2
import pytest
import torch
from stamlane_eval.tusimple import paper_f1

from stamlane.experiments import ablate
from stamlane.experiments.report import robustness_markdown, table_markdown
from stamlane.experiments.results import summarize
from stamlane.experiments.runner import RunSpec, cli_args
from stamlane.experiments.tables import PaperRow, PaperTable, load_tables

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "configs" / "paper"
torch.set_num_threads(1)

# the demo config shrunk for a test: 32x64 frames, width 1/8, fp32, no progress bar
SHRINK = [
    "--data.image_size=[32, 64]",
    "--data.batch_size=2",
    "--data.num_workers=0",
    "--data.align=true",  # the generator's exact homographies: no ORB in a unit test
    "--model.encoder.width=0.125",
    "--model.bf16=false",
    "--model.channels_last=false",
    "--trainer.enable_progress_bar=false",
]


pytestmark = pytest.mark.usefixtures("plain_argv")  # LightningCLI warns when sys.argv holds pytest's own args


@pytest.fixture(scope="module")
def tiny_set(tiny_synthetic: Callable[..., Path]) -> Path:
    """2 train, 1 val, 2 test and 2 challenging clips of 4 frames at 128x72."""
    return tiny_synthetic(128, 72, 4, train=2, val=1, test=2, challenging=2)


@pytest.fixture
def two_row_index(tmp_path: Path) -> Path:
    """A table index with one table of two real rows (1 frame without STAM, 2 frames with STAM)."""
    folder = tmp_path / "paper"
    (folder / "rows").mkdir(parents=True)
    for rid in ("f1_keyonly", "f2_mixed_cs_features"):
        (folder / "rows" / f"{rid}.yaml").write_text((PAPER / "rows" / f"{rid}.yaml").read_text())
    (folder / "tables.yaml").write_text(
        f"default_base: {REPO / 'configs' / 'demo.yaml'}\n"
        f"layers: [{PAPER / 'ablation.yaml'}]\n"
        "tables:\n"
        "  '9':\n"
        "    title: two rows\n"
        "    metrics: tusimple\n"
        "    rows:\n"
        "      - {id: f1_keyonly, label: 1 frame, paper: {f1: 0.9330}}\n"
        "      - {id: f2_mixed_cs_features, label: 2 frames, paper: {f1: 0.9641}}\n"
    )
    return folder / "tables.yaml"


def test_two_row_table_end_to_end_and_resume(
    tiny_set: Path, two_row_index: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "ablate"
    argv = ["--tables", str(two_row_index), "--table", "9", "--seeds", "0", "1", "--data-root", str(tiny_set)]
    argv += ["--max-steps", "2", "--out", str(out), "--", *SHRINK]
    assert ablate.main(argv) == 0, [p.read_text() for p in out.rglob("error.txt")]

    results = {}
    for rid in ("f1_keyonly", "f2_mixed_cs_features"):
        for seed in (0, 1):
            res = json.loads((out / "runs" / rid / f"seed{seed}" / "result.json").read_text())
            assert res["steps"] == 2 and res["seed"] == seed
            assert {"tusimple_f1", "tusimple_accuracy", "tusimple_fp", "tusimple_fn"} <= set(res["metrics"]["test"])
            test = res["metrics"]["test"]  # the logged F1 is the paper's F1 of the logged FP and FN rates
            assert test["tusimple_f1"] == pytest.approx(paper_f1(test["tusimple_fp"], test["tusimple_fn"]), abs=1e-6)
            assert "challenging" in res["metrics"] and res["challenging_labels"] == "challenging.json"
            results[rid, seed] = res
            assert not (out / "runs" / rid / f"seed{seed}" / "logs" / "run" / "checkpoints").exists()
    # the row's settings reached the model; the shrink arguments did not override them
    assert results["f1_keyonly", 0]["num_frames"] == 1
    assert results["f1_keyonly", 0]["fusion"].endswith("KeyFrameOnly")
    assert results["f2_mixed_cs_features", 0]["num_frames"] == 2
    assert results["f2_mixed_cs_features", 0]["fusion_args"]["history"] == "features"

    # the summary CSV holds the mean over both seeds
    lines = list(csv.DictReader((out / "table9.csv").open()))
    assert [r["row"] for r in lines] == ["f1_keyonly", "f2_mixed_cs_features"]
    for line in lines:
        f1 = [results[line["row"], s]["metrics"]["test"]["tusimple_f1"] for s in (0, 1)]
        assert float(line["test/tusimple_f1_mean"]) == pytest.approx(sum(f1) / 2, abs=1e-5)
        assert line["n_seeds"] == "2" and line["paper/tusimple_f1"]
    md = (out / "table9.md").read_text()
    assert "| 1 frame | `f1_keyonly` | 2 |" in md and "robustness" in md and "Command: `stamlane ablate" in md
    plot = cv2.imread(str(out / "table9.png"))
    assert plot is not None and plot.std() > 10 and min(plot.shape[:2]) > 200  # a real picture, not an empty file

    # second call: nothing runs again
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("result.json")}

    def no_run(spec: RunSpec) -> dict:
        raise AssertionError(f"re-ran {spec.row.stem} seed {spec.seed}")

    monkeypatch.setattr(ablate, "run", no_run)
    capsys.readouterr()
    assert ablate.main(argv) == 0
    assert "4 run(s) already finished" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in out.rglob("result.json")} == stamps

    # the same --out with another budget is refused (one line, status 2)
    other = [a if a != "2" else "3" for a in argv]
    assert ablate.main(other) == 2
    assert "other settings (max_steps" in capsys.readouterr().err


def test_bad_input_is_one_line_status_2(capsys: pytest.CaptureFixture, tmp_path: Path) -> None:
    for argv in (
        ["--table", "5"],
        ["--table", "1", "--rows", "f9_nothing"],
        ["--table", "1", "--max-steps", "0"],
        ["--table", "1", "--data-root", str(tmp_path / "missing")],
        ["--table", "1", "--max-steps", "5", "--minutes", "1"],
        ["--report-only", "--table", "1", "--out", str(tmp_path / "empty")],
        [],
    ):
        capsys.readouterr()
        assert ablate.main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and err.startswith("stamlane ablate"), (argv, err)


def test_cli_args_order_row_after_extra_runner_last(tmp_path: Path) -> None:
    spec = RunSpec(
        configs=(Path("base.yaml"), Path("layer.yaml")),
        row=Path("row.yaml"),
        seed=3,
        out_dir=tmp_path,
        max_steps=7,
        minutes=90.5,
        data_root="/d",
        extra=("--data.align=cache",),
    )
    args = cli_args(spec)
    assert args[:4] == ["--config=base.yaml", "--config=layer.yaml", "--data.align=cache", "--config=row.yaml"]
    assert "--seed_everything=3" in args and "--trainer.max_steps=7" in args and "--data.root=/d" in args
    assert "--trainer.max_time=00:01:30:30" in args


def test_summary_mean_std_and_delta() -> None:
    results = {
        0: {"metrics": {"test": {"tusimple_f1": 0.8, "tusimple_fp": 0.1}, "challenging": {"tusimple_f1": 0.7}}},
        1: {"metrics": {"test": {"tusimple_f1": 0.9, "tusimple_fp": 0.3}, "challenging": {"tusimple_f1": 0.6}}},
    }
    s = summarize("r", results)
    assert s.seeds == [0, 1]
    assert s.get("test", "tusimple_f1") == pytest.approx((0.85, math.sqrt(0.005)))
    assert s.get("delta", "tusimple_f1") == pytest.approx((-0.2, math.sqrt(0.02)))
    assert s.get("delta", "tusimple_fp") is None
    single = summarize("r", {0: results[0]})
    assert math.isnan(single.get("test", "tusimple_f1")[1])

    table = PaperTable("1", "t", "tusimple", (PaperRow("r", "row r", Path("r.yaml"), {"tusimple_f1": 0.9681}),))
    md = table_markdown(table, table.rows, {"r": s})
    assert "85.00 ± 7.07" in md and "96.81" in md and "0.2000 ± 0.1414" in md
    assert "-20.00 ± 14.14" in robustness_markdown(table, table.rows, {"r": s})
    assert "| 80.00 |" in table_markdown(table, table.rows, {"r": single})
    assert "not run" in table_markdown(table, table.rows, {})


def test_index_covers_the_paper_tables() -> None:
    index = load_tables(PAPER / "tables.yaml")
    assert list(index.tables) == ["1", "2", "3", "4", "7", "8"]
    sizes = {name: len(t.rows) for name, t in index.tables.items()}
    # paper rows: 6, 4, 5, 6, 4, 4; every STAM row except T = 1 comes in the literal and the features reading
    assert sizes == {"1": 10, "2": 6, "3": 10, "4": 7, "7": 7, "8": 6}
    for t in index.tables.values():
        for r in t.rows:
            assert t.f1_key in r.paper, (t.name, r.id)
    with pytest.raises(ValueError, match="no row"):
        index.table("3").select(["f1_keyonly"])
    # the paper measures Tables 2 and 8 from unaligned frames summed; the others have no baseline row
    assert {name: t.baseline for name, t in index.tables.items() if t.baseline} == {
        "2": "f4_noalign_add",
        "8": "f2_noalign_add",
    }


def test_a_baseline_must_be_a_row_of_its_table(tmp_path: Path) -> None:
    text = (PAPER / "tables.yaml").read_text().replace("baseline: f2_noalign_add", "baseline: f4_noalign_add")
    paper = tmp_path / "paper"  # the index, beside what it names
    paper.mkdir()
    (paper / "rows").symlink_to(PAPER / "rows")
    (paper / "ablation.yaml").write_text((PAPER / "ablation.yaml").read_text())
    (tmp_path / "demo.yaml").write_text((PAPER.parent / "demo.yaml").read_text())
    (paper / "tables.yaml").write_text(text)
    with pytest.raises(ValueError, match="table 8: baseline 'f4_noalign_add' is not one of its rows"):
        load_tables(paper / "tables.yaml")


def test_unfinished_run_resumes_from_its_last_checkpoint(tiny_set: Path, two_row_index: Path, tmp_path: Path) -> None:
    out = tmp_path / "ablate"
    save_every_step = [
        "--trainer.callbacks+=lightning.pytorch.callbacks.ModelCheckpoint",
        "--trainer.callbacks.save_last=true",
        "--trainer.callbacks.every_n_train_steps=1",
    ]
    argv = ["--tables", str(two_row_index), "--table", "9", "--rows", "f1_keyonly", "--seeds", "0"]
    argv += ["--data-root", str(tiny_set), "--max-steps", "2", "--out", str(out), "--keep-checkpoints"]
    argv += ["--", *SHRINK, *save_every_step]
    assert ablate.main(argv) == 0
    folder = out / "runs" / "f1_keyonly" / "seed0"
    first = json.loads((folder / "result.json").read_text())
    assert first["resumed"] is False and (folder / "logs" / "run" / "checkpoints" / "last.ckpt").is_file()
    (folder / "result.json").unlink()  # as if the process had been killed after its last checkpoint
    assert ablate.main(argv) == 0
    again = json.loads((folder / "result.json").read_text())
    assert again["resumed"] is True and again["steps"] == 2
    assert again["metrics"]["test"] == pytest.approx(first["metrics"]["test"], abs=1e-6)
