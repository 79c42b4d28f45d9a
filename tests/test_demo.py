"""``stamlane demo``: the quick smoke run writes every artefact; bad input is one line and exit status 2."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import torch
from stamlane_eval.tusimple import paper_f1

from stamlane.cli import main

torch.set_num_threads(1)


def test_demo_quick_writes_summary_plot_predictions(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    models = {m["name"]: m for m in summary["models"]}
    assert list(models) == ["stam4", "single"]  # --quick leaves the no-alignment ablation out
    assert [models[n]["frames"] for n in models] == [4, 1]
    assert summary["steps"] == 3 and summary["seeds"] == [0]
    for entry in models.values():
        (run,) = entry["runs"]
        assert Path(run["last_ckpt"]).is_file()
        for split in ("test", "challenging"):
            scores = run[split]
            assert scores["images"] == 2
            pred = out / "predictions" / f"{entry['name']}-s0" / split
            assert len((pred / "predictions.json").read_text().splitlines()) == 2
            assert len(list((pred / "overlays").rglob("*.jpg"))) == 2
            per_image = [json.loads(line) for line in (pred / "per_image.jsonl").read_text().splitlines()]
            assert len(per_image) == 2 and {r["clip"] for r in per_image} == {
                f"clips/{split}-0000",
                f"clips/{split}-0001",
            }
            # the run's F1 is the paper's F1 of the per-image rates the file holds
            fp = sum(r["fp"] for r in per_image) / 2
            fn = sum(r["fn"] for r in per_image) / 2
            assert scores["f1"] == pytest.approx(paper_f1(fp, fn))
            agg = entry[split]
            assert agg["f1_mean"] == pytest.approx(scores["f1"]) and agg["f1_std"] is None
            assert agg["f1_ci95"][0] <= agg["f1_mean"] + 1e-9 and agg["f1_ci95"][1] >= agg["f1_mean"] - 1e-9
    pairs = {(c["a"], c["b"], c["split"]) for c in summary["comparisons"]}
    assert pairs == {("stam4", "single", "test"), ("stam4", "single", "challenging")}
    assert (out / "val_f1.png").stat().st_size > 1000
    assert (out / "comparison.jpg").stat().st_size > 1000
    table = capsys.readouterr().out
    assert "1 frame (baseline)" in table and "challenging F1 % [95% CI]" in table and "stam4 - single" in table


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--minutes-per-model", "0"], "--minutes-per-model must be > 0, got 0.0"),
        (["--data", __file__], "is not a folder"),
        (["--steps", "0"], "--steps must be >= 1, got 0"),
        (["--seeds", "0"], "--seeds must be >= 1, got 0"),
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
