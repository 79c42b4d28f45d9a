"""``stamlane ablate``: the experiment engine on a two-row table of a tiny synthetic set, resuming, the settings
lock, the reports; and the table index."""

from __future__ import annotations

import csv
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import cv2
import pytest
import torch

from stamlane.experiments import ablate
from stamlane.experiments.summary import Summary
from stamlane.experiments.table_index import load_tables

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "configs" / "paper"
torch.set_num_threads(1)

# the demo config shrunk for a test: 32x64 frames, width 1/8, no progress bar
SHRINK = [
    "--data.clip.image_size=[32, 64]",
    "--data.loader.batch_size=2",
    "--data.loader.num_workers=0",
    "--data.clip.align=true",  # the generator's exact homographies: no ORB in a unit test
    "--model.encoder.width=0.125",
    "--model.channels_last=false",
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


def test_two_row_table_end_to_end_resume_and_lock(
    tiny_set: Path, two_row_index: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "ablate"
    argv = ["--tables", str(two_row_index), "--table", "9", "--seeds", "0", "1", "--data", str(tiny_set)]
    argv += ["--steps", "2", "--bf16", "false", "--out", str(out), "--", *SHRINK]
    assert ablate.main(argv) == 0
    summary = Summary.read(out / "summary.json")
    assert summary.recipe == {"name": "paper", "pretrain_steps": 0, "steps": 2, "row_args": [], "pretrain_args": []}
    assert summary.seeds == [0, 1]
    assert {m.name: m.frames for m in summary.models} == {"f1_keyonly": 1, "f2_mixed_cs_features": 2}
    assert not (out / "pretrain-s0").exists()  # one stage: every row from scratch
    # the row's settings reached the model; the shrink arguments (given after the base) did not override them
    config = (out / "f2_mixed_cs_features-s0" / "run" / "config.yaml").read_text()
    assert "reading: features" in config and "num_frames: 2" in config and "width: 0.125" in config
    assert "KeyFrameOnly" in (out / "f1_keyonly-s1" / "run" / "config.yaml").read_text()
    # the two-frame row against one frame, and its history probed, with intervals over the two seeds
    diff = summary.difference("f2_mixed_cs_features", "f1_keyonly", "test", "tusimple_f1")
    assert diff is not None and len(diff.seed_diffs) == 2 and diff.seed_ci95 is not None
    assert summary.difference("f2_mixed_cs_features", "f2_mixed_cs_features@key", "challenging", "tusimple_f1")
    table = capsys.readouterr().out
    assert "**Table 9: two rows**" in table and "| 2 frames (`f2_mixed_cs_features`) | 96.41 |" in table
    md = (out / "tables.md").read_text()
    assert md.startswith("**Table 9") and "History use" in md
    lines = list(csv.DictReader((out / "summary.csv").open()))
    kinds = {line["kind"] for line in lines}
    assert {"value", "models", "history_key"} <= kinds
    assert "history_other" not in kinds  # another clip's history is probed on the reveal splits only
    plot = cv2.imread(str(out / "history_use.png"))
    assert plot is not None and plot.std() > 10
    # a second call trains nothing: every run is reused
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("last.ckpt")}
    capsys.readouterr()
    assert ablate.main(argv) == 0
    assert "done before, reused" in capsys.readouterr().out
    assert {p: p.stat().st_mtime_ns for p in out.rglob("last.ckpt")} == stamps
    # --report-only reads the summary back
    assert ablate.main(["--tables", str(two_row_index), "--table", "9", "--report-only", "--out", str(out)]) == 0
    assert "**Table 9" in capsys.readouterr().out
    # the same --out with another budget is refused (one line, status 2)
    assert ablate.main([a if a != "2" else "3" for a in argv]) == 2
    assert "was made with other settings" in capsys.readouterr().err


def test_a_killed_run_goes_on_from_its_last_checkpoint(tiny_set: Path, two_row_index: Path, tmp_path: Path) -> None:
    out = tmp_path / "ablate"
    argv = ["--tables", str(two_row_index), "--table", "9", "--rows", "f1_keyonly", "--seeds", "0"]
    argv += ["--data", str(tiny_set), "--steps", "2", "--bf16", "false", "--out", str(out), "--", *SHRINK]
    assert ablate.main(argv) == 0
    folder = out / "f1_keyonly-s0"
    first = json.loads((folder / "done.json").read_text())
    (folder / "done.json").unlink()  # as if the process had been killed after its final checkpoint
    assert ablate.main(argv) == 0
    again = json.loads((folder / "done.json").read_text())
    assert again["scores"]["test"]["f1"] == pytest.approx(first["scores"]["test"]["f1"], abs=1e-9)
    assert again["last_ckpt_sha256"] == first["last_ckpt_sha256"]  # the finished weights, not a new training


@pytest.fixture
def tusimple_layout(tiny_synthetic: Callable[..., Path], tmp_path: Path) -> Path:
    """A set of real frames as TuSimple lays them out, made from a synthetic one: clips of numbered frames under
    ``clips/<date>/<id>/``, label files ``train.json``, ``val.json`` and ``test_label.json`` naming the last frame
    of each clip, and nothing else (no ``dataset.json``, visibility masks, factors or homographies)."""
    synthetic = tiny_synthetic(128, 72, 4, train=2, val=1, test=2, challenging=0)
    root = tmp_path / "tusimple"
    clips = 0
    for source, target in (("train", "train"), ("val", "val"), ("test", "test_label")):
        lines = []
        for line in (synthetic / f"{source}.json").read_text().splitlines():
            label = json.loads(line)
            clip, frame = label["raw_file"].removeprefix("clips/").rsplit("/", 1)
            folder = f"clips/0530/{1492626047222176976 + clips}_0"
            shutil.copytree(synthetic / "clips" / clip, root / folder)
            lines.append(json.dumps(label | {"raw_file": f"{folder}/{frame}"}))
            clips += 1
        (root / f"{target}.json").write_text("\n".join(lines) + "\n")
    return root


def test_a_tusimple_layout_trains_and_scores(
    tusimple_layout: Path, two_row_index: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """``ablate --data`` on real frames: every row trained and scored, its history probed; the views and oracles
    of a synthetic set (factors, visibility, reveal splits) are absent, not an error."""
    out = tmp_path / "ablate"
    argv = ["--tables", str(two_row_index), "--table", "9", "--seeds", "0", "--data", str(tusimple_layout)]
    argv += ["--splits", "test_label", "--steps", "2", "--bf16", "false", "--out", str(out), "--"]
    argv += [a for a in SHRINK if "align" not in a] + ["--data.clip.align=fly"]  # ORB: no exact homographies
    assert ablate.main(argv) == 0, capsys.readouterr().err
    summary = Summary.read(out / "summary.json")
    assert summary.iou_width == 2 and list(summary.splits_sha256) == ["test_label"]  # 30 px at 128 of 1640: the
    # frames' own size, read from the first one (a synthetic set says it in its dataset.json)
    two = summary.model("f2_mixed_cs_features")
    assert two.runs[0].scores["test_label"]["images"] == 2 and "test_label@key" in two.runs[0].scores
    assert summary.value("f2_mixed_cs_features", "tusimple_f1", "test_label") is not None
    assert summary.difference("f2_mixed_cs_features", "f1_keyonly", "test_label", "tusimple_f1") is not None
    assert summary.views() == ["test_label"] and not summary.oracles  # no factors, no visibility masks
    assert "recall_visible" not in two.values


def test_bad_input_is_one_line_status_2(capsys: pytest.CaptureFixture, tmp_path: Path) -> None:
    for argv in (
        ["--table", "5"],
        ["--table", "1", "--rows", "f9_nothing"],
        ["--table", "1", "--steps", "0"],
        ["--table", "1", "--data", str(tmp_path / "missing")],
        ["--table", "1", "--pretrain-steps", "5"],
        ["--table", "1", "--seeds", "1", "1"],
        ["--report-only", "--table", "1", "--out", str(tmp_path / "empty")],
        [],
        ["--table", "1", "--out", str(tmp_path / "bad-fit"), "--", "--trainer.nope=1"],  # before the data are made
    ):
        capsys.readouterr()
        assert ablate.main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and err.startswith("stamlane ablate"), (argv, err)
    assert not (tmp_path / "bad-fit").exists()


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
