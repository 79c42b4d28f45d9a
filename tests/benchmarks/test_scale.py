"""``benchmarks/scale.py``: its quickest mode runs every kind of measurement (a training step per axis, loading a
sample with the cache and on the fly, the workers that keep a step fed) and writes its json and table."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.benchmarks.scripts import load_script

scale = load_script("scale")  # registered: the forked step processes find it by name


def test_workers_to_feed_a_step():
    assert scale.workers_to_feed(load_s=0.1, step_s=1.0, batch=4) == 1
    assert scale.workers_to_feed(load_s=0.5, step_s=1.0, batch=4) == 2
    assert scale.workers_to_feed(load_s=0.3, step_s=0.1, batch=8) == 24


def test_the_sweep_varies_one_axis_at_a_time_around_the_paper_model():
    configs = scale._sweep(scale.PAPER, scale.FULL, [2, 4])
    assert configs[0] == scale.PAPER and len(configs) == len({json.dumps(c, sort_keys=True) for c in configs})
    for config in configs[1:]:
        assert sum(config[k] != scale.PAPER[k] for k in scale.PAPER) == 1, config
    assert {c["size"] for c in configs} == {(80, 256), (256, 512), (368, 640)}
    assert {c["frames"] for c in configs} == {1, 2, 3, 4, 5} and {c["batch"] for c in configs} == {1, 2, 4}


def test_quick_mode_measures_everything(tmp_path: Path, capsys: pytest.CaptureFixture):
    out = tmp_path / "scale.json"
    assert scale.main(["--quick", "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    rows = result["steps_table"]
    assert len(rows) == 4 and all(r["step_s"] > 0 and r["peak_rss_mb"] > 100 for r in rows)
    assert {tuple(r["size"]) for r in rows} == {(64, 128), (32, 64)} and {r["frames"] for r in rows} == {1, 2}
    for align in ("cache", "fly"):
        loading = result["loading"][align]
        assert loading["samples"] == 2 and loading["failures"] == 0 and loading["load_s"] > 0
        assert loading["workers_to_feed"]["1"] >= 1
    table = out.with_suffix(".md").read_text()
    assert "| 0.25 | 2 | 64x128 | 1 |" in table and "CPU seconds" in table and "| alignment fly |" in table
    assert out.with_suffix(".png").stat().st_size > 1000
    before = table
    out.with_suffix(".md").unlink()
    assert scale.main(["--replot", "--out", str(out)]) == 0 and out.with_suffix(".md").read_text() == before
    assert "workers to keep a step fed" in capsys.readouterr().out


def test_bad_arguments_and_a_missing_gpu_are_one_line_and_status_2(capsys: pytest.CaptureFixture):
    import torch

    assert scale.main(["--steps", "0"]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    if not torch.cuda.is_available():
        assert scale.main(["--device", "cuda"]) == 2
        assert "no CUDA device" in capsys.readouterr().err
