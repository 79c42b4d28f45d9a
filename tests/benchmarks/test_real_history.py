"""``benchmarks/real_history.py``: the real video's labelled frames with their key frame spoiled, history clean."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.benchmarks.scripts import benchmark_module


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("real_history") as module:
        yield module


def _frame() -> np.ndarray:
    rng = np.random.default_rng(3)
    return rng.integers(0, 256, (90, 160, 3), dtype=np.uint8)


def test_a_spoil_is_the_training_corruption_drawn_from_its_seed(bench):
    image = _frame()
    assert bench.spoil(image, "none", [11, 0, 0]) is image
    blank = bench.spoil(image, "blank", [11, 4, 0])
    assert np.array_equal(blank, bench.spoil(image, "blank", [11, 4, 0]))  # the same pixels for every checkpoint
    assert not np.array_equal(blank, bench.spoil(image, "blank", [11, 4, 1]))  # another draw, another row
    changed = np.flatnonzero((blank != image).any(axis=(1, 2)))
    assert changed.size and np.array_equal(changed, np.arange(changed[0], 90))  # every row below one, none above
    assert len(np.unique(blank[changed[0] :].reshape(-1, 3), axis=0)) == 1  # filled with one colour (the mean)
    assert bench.spoil(image, "glare", [11, 2, 0]).mean() > image.mean()
    assert image.dtype == blank.dtype == np.uint8 and blank.shape == image.shape


def _records() -> tuple[list[dict], list[dict], list[dict]]:
    """Two frames of two draws each, one lane: the labels, every lane found, and the second frame's lanes lost."""
    h_samples = [400, 500, 600, 700]
    lane = [300, 250, 200, 150]
    records = [{"raw_file": f"v#{f}~k~{d}", "lanes": [lane], "h_samples": h_samples} for f in (1, 2) for d in (0, 1)]
    found = [
        {"raw_file": r["raw_file"], "lanes": [lane], "run_time": 0, "frame": i // 2} for i, r in enumerate(records)
    ]
    lost = [p | {"lanes": []} if p["frame"] == 1 else p for p in found]  # frame 2 lost in both its draws
    return records, found, lost


def _f1(fn: float) -> float:
    return 2 * (1 - fn) / (2 - fn)  # the paper's F1 with no false positive


def test_scores_and_paired_differences_resample_frames(bench):
    records, found, lost = _records()
    good, bad = bench.scores(found, records, 200), bench.scores(lost, records, 200)
    assert good["f1"] == 1.0 and (good["f1_low"], good["f1_high"]) == (1.0, 1.0)
    assert bad["fn"] == 0.5 and bad["f1"] == pytest.approx(_f1(0.5))
    diff = bench.paired(good, bad, [p["frame"] for p in found], 200)
    assert diff["diff"] == pytest.approx(1 - _f1(0.5)) and diff["low"] == 0.0  # a resample of frame 1 alone


def test_recipes_pool_the_seeds_of_a_name_and_compare_seed_averages_paired(bench):
    records, found, lost = _records()
    runs = {"a-s0": (found, lost), "a-s1": (lost, lost), "b-s0": (lost, None), "b-s1": (lost, None), "c": (found, None)}
    results = {}
    for name, (history, copies) in runs.items():
        results[name, "history", "k"] = bench.scores(history, records, 200)
        if copies is not None:
            results[name, "copies", "k"] = bench.scores(copies, records, 200)
    out = bench.recipes(results, {"k": [p["frame"] for p in found]}, list(runs), 200)
    assert list(out) == ["a", "b"] and out["a"]["seeds"] == ["a-s0", "a-s1"]  # "c" is no seed of a recipe
    a, b = out["a"]["kinds"]["k"], out["b"]["kinds"]["k"]
    assert a["history"]["per_seed"] == pytest.approx([1.0, _f1(0.5)])
    assert a["history_use"]["per_seed"] == pytest.approx([1.0 - _f1(0.5), 0.0])
    assert "copies" not in b and "vs_a" not in a
    assert b["vs_a"]["diff"] == pytest.approx(_f1(0.25) - _f1(0.5))  # a's seeds averaged per image: FN 0.25


def test_a_short_run_reads_history_where_the_key_frame_is_blank(bench, shared_dir: Path, tmp_path: Path):
    out = tmp_path / "history"
    argv = ["--ckpt", "stam4-dashcam", "single-dashcam", "--kinds", "none", "blank", "--draws", "1", "--frames", "2"]
    assert bench.main([*argv, "--shared", str(shared_dir), "--out", str(out), "--resamples", "200"]) == 0
    result = json.loads((out / "real-history.json").read_text())
    assert result["frames"] == [11, 33] and result["kinds"] == ["none", "blank"]
    stam4, single = result["checkpoints"]["stam4-dashcam"], result["checkpoints"]["single-dashcam"]
    assert stam4["num_frames"] == 4 and single["num_frames"] == 1
    assert set(stam4["kinds"]["blank"]) == {"history", "copies"} and set(single["kinds"]["blank"]) == {"history"}
    assert stam4["kinds"]["none"]["history"]["f1"] == single["kinds"]["none"]["history"]["f1"] == 1.0
    blank = stam4["kinds"]["blank"]
    assert blank["copies"]["history_use"]["diff"] == pytest.approx(blank["history"]["f1"] - blank["copies"]["f1"])
    assert single["kinds"]["blank"]["history"]["f1"] < blank["history"]["f1"]  # the near road is gone: history only
    sheet = cv2.imread(str(out / "sheet.jpg"))  # frame 33: a row per kind, real history then copies
    assert sheet.shape == (2 * bench.SHEET_CELL[1], 2 * bench.SHEET_CELL[0], 3)
    assert "| blank | stam4-dashcam |" in (out / "summary.md").read_text()


@pytest.mark.parametrize(
    "argv",
    [
        ["--kinds", "snow"],
        ["--draws", "0"],
        ["--draws", "1000000"],
        ["--frames", "0"],
        ["--resamples", "5"],
        ["--resamples", "1000000000"],
        ["--shared", "nowhere"],
    ],
)
def test_bad_input_is_one_line_status_2_and_writes_nothing(bench, tmp_path: Path, capsys, argv: list[str]) -> None:
    out = tmp_path / "out"
    argv = [a if a != "nowhere" else str(tmp_path / a) for a in argv]
    assert bench.main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("real_history: error: ")
    assert not out.exists()


@pytest.mark.parametrize("folder", ["real-history", "real-history/seeds", "real-history/vehicles"])
def test_the_committed_tables_are_the_committed_numbers(bench, folder: str) -> None:
    results = Path(__file__).resolve().parents[2] / "docs" / "results" / folder
    out = json.loads((results / "real-history.json").read_text())
    assert bench.table(out) == (results / "summary.md").read_text()


def _fake_shared(root: Path, frames: int) -> Path:
    """A ``shared`` folder whose video has ``frames`` frames of noise (the labels need frame 209)."""
    video = root / "data" / "real" / "solidWhiteRight.mp4"
    video.parent.mkdir(parents=True)
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 25, (160, 90))
    for _ in range(frames):
        writer.write(_frame())
    writer.release()
    return root


@pytest.mark.parametrize("where", ["a file", "inside the data"])
def test_an_output_over_a_file_or_inside_the_data_is_refused_before_any_model_runs(
    bench, tmp_path: Path, capsys, where: str
) -> None:
    shared = _fake_shared(tmp_path / "shared", 3)
    out = tmp_path / "taken.txt" if where == "a file" else shared / "data" / "history"
    if where == "a file":
        out.write_text("mine\n")
    before = sorted((str(p), p.stat().st_size) for p in tmp_path.rglob("*"))
    assert bench.main(["--shared", str(shared), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("real_history: error: ")
    assert sorted((str(p), p.stat().st_size) for p in tmp_path.rglob("*")) == before


def test_a_video_shorter_than_its_labels_is_one_line(bench, tmp_path: Path, capsys) -> None:
    shared = _fake_shared(tmp_path / "shared", 12)
    out = tmp_path / "out"
    assert bench.main(["--ckpt", "single-dashcam", "--shared", str(shared), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ends before frame" in err[0] and not out.exists()


# ------------------------------------------------------------------------------------------- real vehicles
def _road_record() -> dict:
    """Three straight lines in label pixels, rows 400-700 labelled: x = -1.6 y + 1200, x = -y + 990 and x = y + 290
    (the ego lane: 2 px a row wider, vanishing at row 350, 640 across)."""
    rows = list(range(400, 710, 10))
    lanes = [[-1.6 * y + 1200 for y in rows], [-y + 990 for y in rows], [y + 290 for y in rows]]
    return {"raw_file": "v#9", "lanes": lanes, "h_samples": rows}


def test_the_road_of_a_record_is_its_lines_vanishing_row_and_scale(bench):
    road = bench.Road.of(_road_record())
    assert [round(a, 6) for a, *_ in road.lines] == [-1.6, -1, 1]  # sorted left to right at the bottom
    assert road.horizon == pytest.approx(350)  # the ego pair
    assert road.height == pytest.approx(bench.LANE_WIDTH_M / 2)
    assert road.focal == pytest.approx(640 / np.tan(np.radians(bench.HFOV_DEG) / 2))
    with pytest.raises(bench.real_roads.RealRoadsError, match="fewer than two"):
        bench.Road.of({"raw_file": "v#9", "lanes": [[300, 200]], "h_samples": [600, 700]})


def test_a_vehicle_stands_on_its_line_scaled_with_its_row_and_moves_with_its_speed(bench):
    road = bench.Road.of(_road_record())
    near = bench.Vehicle(line=2, z=5.0, offset=0.0, speed=10.0, lateral=1.0, patch=0)
    x0, y0, x1, y1 = bench.placement(near, road, 0.5, 0.0)
    assert y1 == pytest.approx(road.horizon + road.focal * road.height / 5.0)  # the bottom on its ground row
    assert (x0 + x1) / 2 == pytest.approx(y1 + 290)  # centred on line 2 (x = y + 290) there
    assert x1 - x0 == pytest.approx(bench.VEHICLE_WIDTH_M * road.focal / 5.0) and y1 - y0 == pytest.approx(
        (x1 - x0) / 2
    )
    far = bench.placement(bench.Vehicle(2, 10.0, 0.0, 10.0, 1.0, 0), road, 0.5, 0.0)
    assert far[3] < y1 and far[2] - far[0] == pytest.approx((x1 - x0) / 2)  # twice as far: higher, half as wide
    before = bench.placement(near, road, 0.5, -0.1)  # 0.1 s earlier it was 1 m nearer (it drives away) and left
    assert before == bench.placement(bench.Vehicle(2, 4.0, -0.1, 10.0, 1.0, 0), road, 0.5, 0.0)
    assert bench.placement(near, road, 0.5, -0.3) is None  # 2 m ahead: under the bonnet


def test_the_draws_and_the_paste_are_deterministic_and_hide_the_lines_they_stand_on(bench):
    record, road = _road_record(), bench.Road.of(_road_record())
    patch = np.full((50, 100, 3), (0, 0, 255), np.uint8)  # a red vehicle
    draws = [bench.draw_vehicles(road, np.random.default_rng([9, 5, d]), 1) for d in (0, 0, 1)]
    assert draws[0] == draws[1] != draws[2]
    assert len({v.line for v in draws[0]}) == bench.VEHICLES_PER_FRAME
    image = np.full((540, 960, 3), 90, np.uint8)
    pasted = bench.paste(image, draws[0], road, [patch], 0.0)
    assert (image == 90).all() and np.array_equal(pasted, bench.paste(image, draws[0], road, [patch], 0.0))
    red = (pasted[..., 2] > 200) & (pasted[..., 0] < 50)
    mask = bench.cover((540, 960), draws[0], road, [patch], 0.0)
    assert red.any() and np.array_equal(red & mask, red)  # the vehicles are where `cover` says
    points, hidden, _ = bench.hidden_counts(record, [mask])
    assert points == 3 * 31 and 0 < hidden < points
    for v in draws[0]:  # each covers its line just above its bottom row
        _, y0, _, y1 = bench.placement(v, road, 0.5, 0.0)
        a, b = road.lines[v.line][:2]
        row = y1 - 0.25 * (y1 - y0)
        assert mask[round(row * 0.75), round((a * row + b) * 0.75)]


def test_the_vehicle_kinds_keep_or_move_the_history_and_share_the_key_frame(bench):
    record = _road_record()
    rng = np.random.default_rng(4)
    clean = [rng.integers(0, 256, (540, 960, 3), dtype=np.uint8) for _ in range(4)]
    patches = [np.full((50, 100, 3), 255, np.uint8)]
    vehicle = bench.spoiled_window(clean, "vehicle", [9, 5, 0], record, patches, 25.0)
    traffic = bench.spoiled_window(clean, "traffic", [9, 5, 0], record, patches, 25.0)
    assert all(a is b for a, b in zip(vehicle[:-1], clean[:-1]))  # the history intact
    assert np.array_equal(vehicle[-1], traffic[-1]) and not np.array_equal(vehicle[-1], clean[-1])
    assert all(not np.array_equal(a, b) for a, b in zip(traffic[:-1], clean[:-1]))  # the vehicles there too
    covers = bench.window_covers(record, "traffic", [9, 5, 0], patches, 25.0, 3, (540, 960))
    assert not any(np.array_equal(covers[-1], c) for c in covers[:-1])  # they moved
    still = bench.window_covers(record, "vehicle", [9, 5, 0], patches, 25.0, 3, (540, 960))
    assert not any(c.any() for c in still[:-1]) and np.array_equal(still[-1], covers[-1])
    blank = bench.spoiled_window(clean, "blank", [9, 4, 0], record, patches, 25.0)
    assert all(a is b for a, b in zip(blank[:-1], clean[:-1])) and not np.array_equal(blank[-1], clean[-1])


def test_a_short_run_pastes_real_vehicles(bench, shared_dir: Path, tmp_path: Path):
    out = tmp_path / "vehicles"
    argv = ["--ckpt", "stam4-dashcam", "--kinds", "vehicle", "traffic", "--draws", "1", "--frames", "2"]
    assert bench.main([*argv, "--shared", str(shared_dir), "--out", str(out), "--resamples", "200"]) == 0
    result = json.loads((out / "real-history.json").read_text())
    assert set(result["hidden_points"]) == {"vehicle", "traffic"}
    vehicle, traffic = result["hidden_points"]["vehicle"], result["hidden_points"]["traffic"]
    assert vehicle["hidden"] == traffic["hidden"] > 0 and vehicle["free_in_history"] == vehicle["hidden"]
    assert traffic["free_in_history"] <= traffic["hidden"]
    kinds = result["checkpoints"]["stam4-dashcam"]["kinds"]
    assert kinds["vehicle"]["copies"]["f1"] == kinds["traffic"]["copies"]["f1"]  # the same key frame copied
    assert (out / "summary.md").read_text() == bench.table(result)
    assert len(bench.read_patches(shared_dir)) == len(json.loads(bench.PATCHES.read_text())["patches"])


def test_missing_vehicle_pictures_are_one_line(bench, tmp_path: Path, capsys) -> None:
    shared = _fake_shared(tmp_path / "shared", 3)
    out = tmp_path / "out"
    assert bench.main(["--kinds", "traffic", "--shared", str(shared), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "lanenet_0002.jpg cannot be read" in err[0] and not out.exists()
