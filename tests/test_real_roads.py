"""The real-road check (``benchmarks/real_roads.py``): its stability numbers on lanes made by hand, and a short run
of a shipped model on two real labelled frames and the first frames of the real video (``../shared``)."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_real_roads", REPO / "benchmarks" / "real_roads.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_real_roads"] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("bench_real_roads", None)


ROWS = np.arange(100.0, 200.0, 10.0)


def _lane(x_bottom: float, x_top: float) -> np.ndarray:
    return np.stack([np.linspace(x_top, x_bottom, len(ROWS)), ROWS], axis=1)


def test_stability_counts_changes_and_measures_the_jitter_of_matched_lanes(bench):
    frames = [
        [_lane(100, 150), _lane(300, 250)],
        [_lane(103, 153), _lane(300, 250)],  # the left lane moved 3 px, the right one stayed
        [_lane(103, 153), _lane(300, 250), _lane(600, 400)],  # a lane appears: a count change, unmatched
    ]
    out = bench.stability(frames, ROWS, width=640)
    assert out["count_changes"] == 1
    assert out["jitter_px"] == pytest.approx((3 + 0 + 0 + 0) / 4)
    assert out["matched"] == pytest.approx(4 / 5)
    assert out["unmatched_per_frame"] == pytest.approx(1 / 2)


def test_a_lane_that_jumps_beyond_the_match_distance_is_not_matched(bench):
    frames = [[_lane(100, 150)], [_lane(100 + 0.05 * 640 + 5, 150 + 0.05 * 640 + 5)]]
    out = bench.stability(frames, ROWS, width=640)
    assert out["matched"] == 0 and np.isnan(out["jitter_px"])


def test_crossings_counts_pairs_whose_order_changes(bench):
    assert bench.crossings([_lane(100, 200), _lane(300, 250)], ROWS) == 0
    assert bench.crossings([_lane(100, 300), _lane(300, 100)], ROWS) == 1  # an X
    assert bench.crossings([_lane(100, 300), _lane(300, 100), _lane(500, 450)], ROWS) == 1


def test_the_check_scores_a_shipped_model_on_real_frames_and_video(bench, shared_dir: Path, tmp_path: Path):
    out = tmp_path / "real"
    argv = ["--ckpt", "single-synthetic", "--shared", str(shared_dir), "--frames", "2", "--video-frames", "5"]
    assert bench.main([*argv, "--strip", "2", "--out", str(out)]) == 0
    result = json.loads((out / "single-synthetic.json").read_text())
    frames, video = result["labelled_frames"], result["video"]
    assert frames["images"] == 2 and len(frames["per_image"]) == 2
    assert 0.0 <= frames["f1"] <= 1.0 and 0.0 <= frames["fp"] <= 1.0
    assert video["frames"] == 5 and sum(video["lanes_per_frame"].values()) == 5
    assert video["size"] == "960x540" and video["count_changes"] <= 4
    strip = cv2.imread(str(out / "single-synthetic-strip.jpg"))
    assert strip.shape == (2 * bench.STRIP_CELL[1], 2 * bench.STRIP_CELL[0], 3)
    assert "| single-synthetic |" in (out / "summary.md").read_text()


def test_missing_data_is_one_line_and_writes_nothing(bench, tmp_path: Path, capsys: pytest.CaptureFixture):
    out = tmp_path / "real"
    assert bench.main(["--ckpt", "single-synthetic", "--shared", str(tmp_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("real_roads: error:") and "lanenet_frames.json" in err[0]
    assert not out.exists()
    assert bench.main(["--frames", "0", "--out", str(out)]) == 2 and not out.exists()
