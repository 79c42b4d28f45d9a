"""Where the lines beyond the ego pair go missing (``benchmarks/outer_lanes.py``, ``benchmarks/real_frames.py``): the
support of a labelled line in a lane probability map, the causes, the decoding taken apart as `decode_lanes` does it,
and a run of the script on the dev photos (``../shared``)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from stamlane.predict.postprocess import PostprocessConfig, decode_lanes
from tests.benchmarks.scripts import benchmark_module


@pytest.fixture(scope="module")
def frames_module():
    with benchmark_module("real_frames") as module:
        yield module


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("outer_lanes") as module:
        yield module


def _map_with_line(columns: list[int], value: float, height: int = 20, width: int = 64) -> np.ndarray:
    prob = np.zeros((height, width), np.float32)
    for row, col in enumerate(columns):
        prob[row, col] = value
    return prob


def test_label_in_net_maps_the_labelled_points_and_skips_the_absent_ones(frames_module):
    net_from_orig = np.array([[0.5, 0, 0], [0, 0.25, -10], [0, 0, 1.0]])
    points = frames_module.label_in_net([100.0, -2, 300.0], [40, 50, 80], net_from_orig)
    np.testing.assert_allclose(points, [[50.0, 0.0], [150.0, 10.0]])


def test_line_support_counts_rows_with_a_lane_pixel_near_the_label(frames_module):
    prob = _map_with_line([10] * 20, 0.7)  # a line at column 10, probability 0.7: a lane pixel, never a sure one
    label = np.stack([np.full(20, 13.0), np.arange(20.0)], axis=1)  # 3 columns beside it
    near = frames_module.line_support(prob, label, 0.5, 0.9, columns=4)
    assert near == {"rows": 20, "lane_rows": 1.0, "sure_rows": 0.0, "mean_max": pytest.approx(0.7), "present": True}
    far = frames_module.line_support(prob, label, 0.5, 0.9, columns=2)  # the line outside the search
    assert far["lane_rows"] == 0.0 and not far["present"]
    half = _map_with_line([10] * 20, 0.7)
    half[:11] = 0.0  # 9 of 20 rows hold it: below PRESENT_ROWS
    assert not frames_module.line_support(half, label, 0.5, 0.9)["present"]
    outside = frames_module.line_support(prob, label + np.array([0.0, 100.0]), 0.5, 0.9)
    assert outside == {"rows": 0, "lane_rows": None, "sure_rows": None, "mean_max": None, "present": False}
    with pytest.raises(ValueError, match=r"expected prob of shape \(H, W\)"):
        frames_module.line_support(prob[None], label, 0.5, 0.9)


def test_miss_cause_names_where_a_line_was_lost(frames_module):
    cause = frames_module.miss_cause
    assert cause(True, False, "noise") == "matched"
    assert cause(False, False, "own") == "absent"
    assert cause(False, True, "noise") == "not clustered"
    assert cause(False, True, "shared") == "merged"
    assert cause(False, True, "own") == "drawn off the label"
    with pytest.raises(ValueError, match="owner must be"):
        cause(False, True, "lost")


def _heads(lanes: int, height: int = 80, width: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """``lanes`` straight vertical lanes of 3 columns from row 20 down, each with its own embedding."""
    rng = np.random.default_rng(0)
    prob = np.full((height, width), 0.05, np.float32)
    emb = rng.normal(0, 1, (4, height, width)).astype(np.float32)
    for i in range(lanes):
        col = 40 + 60 * i
        prob[20:, col : col + 3] = 0.97
        emb[:, 20:, col : col + 3] = (3.0 * np.eye(4)[i])[:, None, None] + rng.normal(0, 0.05, (4, height - 20, 3))
    return prob, emb


def test_decode_parts_draws_what_decode_lanes_draws(bench):
    config = PostprocessConfig()
    prob, emb = _heads(3)
    prob[30:33, 200:203] = 0.97  # 9 pixels: a cluster too small to draw
    emb[:, 30:33, 200:203] = -3.0
    parts = bench.decode_parts(prob, emb, np.eye(3), config)
    assert len(parts["drawn"]) == len(decode_lanes(prob, emb, np.eye(3), config)) == 3
    column = np.stack([np.full(60, 41.0), np.arange(20.0, 80.0)], axis=1)
    members = bench.line_clusters(parts, column, 1)
    assert len(members) == 180 and len(set(members)) == 1 and members[0] in parts["drawn"]


def test_owners_tell_noise_a_shared_cluster_and_an_own_one(bench):
    assert bench.owners([[0, 0, 1], [0, 0], [2, 2, -1], [-1, -1, 2]], drawn=[0, 2]) == [
        "shared",
        "shared",
        "own",
        "noise",
    ]
    assert bench.owners([[]], drawn=[0]) == ["noise"]


def test_a_panel_of_another_input_size_draws_its_lines_on_its_map(bench):
    """A checkpoint at 128x384 beside one at 80x256: its map is resized to the picture, and its lines (in its own
    network pixels) must land on it, not be drawn at the first checkpoint's scale (they were, before)."""

    def panel(height: int, width: int) -> dict:
        prob = np.zeros((height, width), np.float32)
        prob[:, width // 4] = 1.0  # a vertical line a quarter across
        line = np.array([[width / 4, 0.0], [width / 4, height - 1.0]])
        return {"prob": prob, "labels": [line], "drawn": []}

    view = np.zeros((80, 256, 3), np.uint8)
    out = bench.picture(view, [("small", panel(80, 256)), ("large", panel(128, 384))])
    assert out.shape == (3 * 160, 512, 3)
    for heat in (out[160:320], out[320:]):
        yellow = np.flatnonzero((heat[100:150, :, 2] > 200) & (heat[100:150, :, 0] < 100) & (heat[100:150, :, 1] > 200))
        columns = yellow % 512
        assert len(columns) and abs(np.median(columns) - 128) <= 2  # a quarter of 512, in both panels


def test_the_script_diagnoses_every_dev_photo_of_a_shipped_model(bench, shared_dir: Path, tmp_path: Path):
    code = bench.main(
        [
            "--ckpt",
            "single-dashcam",
            "--shared",
            str(shared_dir),
            "--out",
            str(tmp_path / "out"),
            "--pictures",
            str(tmp_path / "pictures"),
        ]
    )
    assert code == 0
    result = json.loads((tmp_path / "out" / "outer-lanes.json").read_text())
    assert result["split"] == "dev"
    numbers = result["results"]["single-dashcam"]
    labelled = sum(len(json.loads(line)["lanes"]) for line in (shared_dir / "data/lanenet_frames.json").open())
    assert sum(sum(c.values()) for c in numbers["by_position"].values()) == labelled
    assert all(line["cause"] in bench.real_frames.CAUSES for photo in numbers["photos"] for line in photo["lines"])
    pictures = sorted((tmp_path / "pictures").glob("*.png"))
    assert len(pictures) == len(numbers["photos"])
    image = cv2.imread(str(pictures[0]))
    assert image.shape == (2 * 80 * 2, 2 * 256, 3)  # the view and one probability panel, at twice 80x256


def test_the_script_refuses_a_missing_shared_folder_with_one_line(bench, tmp_path: Path, capsys):
    assert bench.main(["--shared", str(tmp_path / "nowhere"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("outer_lanes: error: ") and err.count("\n") == 1
    assert bench.main(["--columns", "-1", "--out", str(tmp_path / "out")]) == 2
