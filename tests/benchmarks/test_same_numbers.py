"""``benchmarks/same_numbers.py``: two experiment folders compared bit for bit (weights, lanes, per-image values),
the machine's timings left out."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from tests.benchmarks.scripts import load_script

same_numbers = load_script("same_numbers")


def _experiment(root: Path, weight: torch.Tensor, run_time: float, acc: float) -> Path:
    ckpt = root / "stam4-s0" / "run" / "checkpoints" / "last.ckpt"
    ckpt.parent.mkdir(parents=True)
    state = {"encoder.w": weight, "head.b": torch.zeros(2, dtype=torch.float64), "bn.steps": torch.tensor(7)}
    torch.save({"state_dict": state}, ckpt)  # a 0-d long tensor too, as batch norms count their batches
    pred = root / "predictions" / "stam4-s0" / "test"
    pred.mkdir(parents=True)
    line = {"raw_file": "clips/a/8.jpg", "lanes": [[1.5, 2.0]], "h_samples": [10, 20], "run_time": run_time}
    (pred / "predictions.json").write_text(json.dumps(line) + "\n")
    (pred / "per_image.jsonl").write_text(json.dumps({"raw_file": "clips/a/8.jpg", "acc": acc}) + "\n")
    return root


def test_equal_folders_pass_whatever_the_timings(tmp_path: Path, capsys: pytest.CaptureFixture):
    w = torch.arange(6, dtype=torch.float32).reshape(2, 3)
    a = _experiment(tmp_path / "a", w, run_time=3.0, acc=0.5)
    b = _experiment(tmp_path / "b", w.clone(), run_time=9.0, acc=0.5)
    assert same_numbers.main([str(a), str(b)]) == 0
    assert "1 final checkpoints and 1 prediction folders compared: every tensor" in capsys.readouterr().out


def test_a_last_bit_a_dtype_or_a_per_image_value_is_a_difference(tmp_path: Path, capsys: pytest.CaptureFixture):
    w = torch.ones(4, dtype=torch.float32)
    nudged = w.clone()
    nudged[2] = torch.nextafter(nudged[2], torch.tensor(2.0))  # one ulp
    a = _experiment(tmp_path / "a", w, run_time=1.0, acc=0.5)
    b = _experiment(tmp_path / "b", nudged, run_time=1.0, acc=0.5000001)
    assert same_numbers.main([str(a), str(b), "--json", str(tmp_path / "r.json")]) == 1
    out = capsys.readouterr().out
    assert "stam4-s0: 1 tensors differ (encoder.w" in out and "per_image.jsonl differ" in out
    assert json.loads((tmp_path / "r.json").read_text())["weights"] == {"stam4-s0": ["encoder.w"]}
    c = _experiment(tmp_path / "c", w.double(), run_time=1.0, acc=0.5)
    assert same_numbers.compare(a, c)["weights"] == {"stam4-s0": ["encoder.w"]}


def test_a_folder_in_one_only_is_listed_and_a_missing_folder_is_bad_input(tmp_path: Path, capsys):
    w = torch.ones(1)
    a = _experiment(tmp_path / "a", w, 1.0, 0.5)
    b = _experiment(tmp_path / "b", w, 1.0, 0.5)
    (b / "predictions" / "stam4-s0" / "test@key").mkdir()
    (b / "predictions" / "stam4-s0" / "test@key" / "predictions.json").write_text("")
    assert same_numbers.main([str(a), str(b)]) == 0
    assert "only in one of the two: predictions/stam4-s0/test@key" in capsys.readouterr().out
    assert same_numbers.main([str(a), str(tmp_path / "nowhere")]) == 2
