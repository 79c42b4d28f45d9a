"""``stamlane demo``: the quick smoke run writes every artefact; bad input is one line and exit status 2."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import torch

from stamlane.cli import main

torch.set_num_threads(1)


def test_demo_quick_writes_summary_plot_predictions(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    models = {m["name"]: m for m in summary["models"]}
    assert list(models) == ["stam4", "single"]  # --quick leaves the no-alignment ablation out
    assert [models[n]["frames"] for n in models] == [4, 1]
    assert summary["steps"] == 3
    for entry in models.values():
        for split in ("val", "challenging"):
            scores = entry[split]
            assert scores["images"] == 2 and 0.0 <= scores["f1"] <= 1.0 and 0.0 <= scores["accuracy"] <= 1.0
            pred = out / "predictions" / entry["name"] / split
            assert len((pred / "predictions.json").read_text().splitlines()) == 2
            assert len(list((pred / "overlays").rglob("*.jpg"))) == 2
    assert (out / "val_f1.png").stat().st_size > 1000
    assert (out / "comparison.jpg").stat().st_size > 1000
    table = capsys.readouterr().out
    assert "1 frame (baseline)" in table and "challenging acc" in table


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--minutes-per-model", "0"], "--minutes-per-model must be > 0, got 0.0"),
        (["--data", __file__], "is not a folder"),
        (["--steps", "0"], "--steps must be >= 1, got 0"),
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
