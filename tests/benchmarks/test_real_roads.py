"""The real-road check (``benchmarks/real_roads.py``): its stability numbers on lanes made by hand, and a short run
of a shipped model on two real labelled frames and the first frames of the real video (``../shared``)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.benchmarks.scripts import benchmark_module

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("real_roads") as module:
        yield module


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


def test_the_crop_ceiling_is_the_score_of_the_labels_cut_at_the_first_row_the_network_sees(bench):
    rows = list(range(100, 710, 10))  # 61 rows
    low = [600 - (y - 300) if y >= 300 else -2 for y in rows]  # drawn from row 300: all of it below the crop
    high = [100 + y for y in rows]  # drawn from row 100: 19 of its 61 rows above row 288, 69 % left: out of reach
    edge = [100 + y if y >= 200 else -2 for y in rows]  # from row 200: 9 rows lost, 85.2 % left: still matched
    records = [{"raw_file": "a.jpg", "h_samples": rows, "lanes": [low, high, edge]}]
    out = bench.crop_ceiling(records, [720], 0.4)
    assert out["lanes_out_of_reach"] == 1
    assert out["f1"] == pytest.approx(2 * 1.0 * (2 / 3) / (1.0 + 2 / 3))  # two of three lanes, no false positive
    assert bench.crop_ceiling(records, [720], 0.1) == {"crop_top": 0.1, "f1": 1.0, "lanes_out_of_reach": 0}


def test_the_real_frames_put_three_lanes_out_of_reach_of_the_shipped_crop(bench, shared_dir: Path):
    records, root = bench.read_labels(shared_dir)
    heights = [cv2.imread(str(root / r["raw_file"])).shape[0] for r in records]
    # frame 2 climbs a hill: three of its lanes have 9 of their 56 rows above row 288 of 720 (lane.py: 85 % or nothing)
    out = bench.crop_ceiling(records, heights, 0.4)
    assert out["lanes_out_of_reach"] == 3 and round(100 * out["f1"], 1) == 93.3


def test_the_check_scores_a_shipped_model_on_real_frames_and_video(bench, shared_dir: Path, tmp_path: Path):
    out = tmp_path / "real"
    argv = ["--ckpt", "single-synthetic", "--shared", str(shared_dir), "--frames", "2", "--video-frames", "12"]
    assert bench.main([*argv, "--strip", "2", "--out", str(out)]) == 0
    result = json.loads((out / "single-synthetic.json").read_text())
    frames, video = result["labelled_frames"], result["video"]
    assert frames["images"] == 2 and len(frames["per_image"]) == 2
    assert 0.0 <= frames["f1"] <= 1.0 and 0.0 <= frames["fp"] <= 1.0
    assert frames["crop_ceiling"] == {"crop_top": 0.4, "f1": 1.0, "lanes_out_of_reach": 0}  # frames 0 and 1
    assert video["frames"] == 12 and sum(video["lanes_per_frame"].values()) == 12
    assert video["size"] == "960x540" and video["count_changes"] <= 11
    assert video["labelled_frames"]["images"] == 1  # frame 11, the first labelled one
    strip = cv2.imread(str(out / "single-synthetic-strip.jpg"))
    assert strip.shape == (2 * bench.STRIP_CELL[1], 2 * bench.STRIP_CELL[0], 3)
    assert "| single-synthetic |" in (out / "summary.md").read_text()


def test_decodings_share_one_network_pass_and_score_a_synthetic_validation_split(
    bench, shared_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
):
    from stamlane.synth.cli import main as synth_main

    val = tmp_path / "synthetic"
    small = ["--clips", "3", "--challenging-clips", "0", "--reveal-clips", "0", "--reveal-traffic-clips", "0"]
    assert synth_main(["--out", str(val), *small, "--size", "256x144", "--frames", "9", "--quiet"]) == 0
    argv = ["--ckpt", "single-synthetic", "--shared", str(shared_dir), "--frames", "2", "--video-frames", "4"]
    plain, out = tmp_path / "plain", tmp_path / "decodings"
    assert bench.main([*argv, "--strip", "1", "--out", str(plain)]) == 0
    decode = ["--decode", "model", "short:extend=false,degree=2", "--val", str(val)]
    assert bench.main([*argv, "--strip", "1", "--out", str(out), *decode]) == 0
    own = json.loads((plain / "single-synthetic.json").read_text())
    same = json.loads((out / "single-synthetic@model.json").read_text())
    short = json.loads((out / "single-synthetic@short.json").read_text())
    # the model's own decoding of the shared pass is what the predictor decodes itself
    assert same["labelled_frames"] == own["labelled_frames"]
    assert same["video"]["lanes_per_frame_sequence"] == own["video"]["lanes_per_frame_sequence"]
    assert short["postprocess"]["extend"] is False and short["postprocess"]["degree"] == 2
    assert same["postprocess"]["extend"] is True
    assert same["synthetic_val"]["images"] == short["synthetic_val"]["images"] > 0
    assert "| single-synthetic | short |" in (out / "summary.md").read_text()
    capsys.readouterr()
    bad = tmp_path / "bad"
    assert bench.main([*argv, "--out", str(bad), "--decode", "x:degree=zero"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "degree" in err[0] and not bad.exists()


def test_the_video_labels_score_lanes_in_the_videos_own_pixels(bench):
    records = bench.read_video_labels()[:2]
    scale = bench.TUSIMPLE_WIDTH / 960

    def lanes(record: dict, shift: float) -> list[np.ndarray]:
        rows = np.asarray(record["h_samples"], dtype=np.float64)
        return [
            np.stack([xs[xs >= 0] / scale + shift, rows[xs >= 0] / scale], 1) for xs in map(np.array, record["lanes"])
        ]

    frames = int(records[1]["raw_file"].rpartition("#")[2]) + 1
    found = [[] for _ in range(frames)]
    for record in records:
        found[int(record["raw_file"].rpartition("#")[2])] = lanes(record, 0.0)
    assert bench.score_video_frames(found, records, 960)["f1"] == 1.0  # the labels, back in the video's pixels
    for record in records:  # lane.py's 20 px / cos(angle) at 1280 (~90 px for the steep far-left line): missed
        found[int(record["raw_file"].rpartition("#")[2])] = lanes(record, 120.0)
    assert bench.score_video_frames(found, records, 960)["f1"] == 0.0
    assert bench.score_video_frames(found[:5], records, 960) is None  # streamed frames end before the first label


def test_missing_data_is_one_line_and_writes_nothing(bench, tmp_path: Path, capsys: pytest.CaptureFixture):
    out = tmp_path / "real"
    assert bench.main(["--ckpt", "single-synthetic", "--shared", str(tmp_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("real_roads: error:") and "lanenet_frames.json" in err[0]
    assert not out.exists()
    assert bench.main(["--frames", "0", "--out", str(out)]) == 2 and not out.exists()


def test_an_output_over_a_file_or_inside_the_data_is_refused(
    bench, shared_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
):
    taken = tmp_path / "taken.txt"
    taken.write_text("mine\n")
    for out in (taken, shared_dir / "data" / "real-roads"):
        assert bench.main(["--ckpt", "single-synthetic", "--shared", str(shared_dir), "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("real_roads: error:")
    assert taken.read_text() == "mine\n" and not (shared_dir / "data" / "real-roads").exists()


def _tusimple_layout(root: Path, clips: int = 2, size: tuple[int, int] = (180, 320)) -> Path:
    """A tiny set in TuSimple's own layout (``clips/<date>/<id>/1..20.jpg``, ``label_data_<date>.json`` labelling
    frame 20): what a user with real data has, written here."""
    rng = np.random.default_rng(0)
    h, w = size
    h_samples = list(range(80, h, 10))
    records = []
    for c in range(clips):
        folder = root / "clips" / "0531" / f"14924{c:05d}"
        folder.mkdir(parents=True)
        lanes = [[round(w * (0.3 + 0.4 * k) + (y - 80) * (1.2 if k else -1.2)) for y in h_samples] for k in (0, 1)]
        for frame in range(1, 21):
            image = rng.integers(60, 110, (h, w, 3), dtype=np.uint8)
            for lane in lanes:
                points = np.array([(x, y) for x, y in zip(lane, h_samples) if 0 <= x < w], np.int32)
                cv2.polylines(image, [points], False, (235, 235, 235), 3)
            cv2.imwrite(str(folder / f"{frame}.jpg"), image)
        lanes = [[x if 0 <= x < w else -2 for x in lane] for lane in lanes]
        records.append({"raw_file": f"clips/0531/14924{c:05d}/20.jpg", "lanes": lanes, "h_samples": h_samples})
    (root / "label_data_0531.json").write_text("".join(json.dumps(r) + "\n" for r in records))
    return root


def test_fine_tuning_a_shipped_model_on_a_tusimple_layout_set_is_one_command(tmp_path: Path, plain_argv: None):
    import torch

    from stamlane.cli import main as cli_main
    from stamlane.weights import shipped_path

    root = _tusimple_layout(tmp_path / "tusimple")
    out = tmp_path / "run"
    command = [  # docs/models.md, "Fine-tune on your own data", with a 1-step budget and a small input
        "fit",
        "--config",
        str(REPO / "configs" / "demo.yaml"),
        f"--data.root={root}",
        "--data.train_labels=[label_data_0531.json]",
        "--data.val_labels=[label_data_0531.json]",
        "--model.init_weights=stam4-synthetic",
        "--trainer.max_steps=1",
        "--trainer.val_check_interval=1",
        "--data.loader.batch_size=2",
        "--data.loader.num_workers=0",
        f"--trainer.default_root_dir={out}",
        f"--trainer.logger.save_dir={out}",
        "--trainer.enable_progress_bar=false",
    ]
    assert cli_main(command) == 0
    tuned = torch.load(next(out.rglob("last.ckpt")), weights_only=True)
    shipped = torch.load(shipped_path("stam4-synthetic"), weights_only=True)["state_dict"]
    assert tuned["global_step"] == 1
    weights = [k for k, v in shipped.items() if v.is_floating_point() and "running_" not in k]  # not BN statistics
    moved = [float((tuned["state_dict"][k] - shipped[k]).abs().max()) for k in weights]
    assert 0 < max(moved) <= 0.0021  # one AdamW step of lr 0.002 from the shipped weights, not a fresh initialisation


# ------------------------------------------------------------------- lane positions, counts, the protocol's split
@pytest.fixture(scope="module")
def frames_module():
    with benchmark_module("real_frames") as module:
        yield module


ROWS_720 = list(range(160, 720, 10))  # TuSimple's h_samples


def _straight(x_bottom: float, x_top: float, top: int = 300) -> list[float]:
    """A TuSimple x list of a straight line from (x_top, top) to (x_bottom, 720), -2 above ``top``."""
    return [x_top + (x_bottom - x_top) * (y - top) / (720 - top) if y >= top else -2 for y in ROWS_720]


def test_positions_rank_the_lines_by_their_bottom_crossing_on_each_side_of_the_centre(frames_module):
    # bottoms at 100, 400, 600 (left of 640) and 700, 1000 (right): 600 and 700 the ego pair, 400 and 1000 adjacent
    lanes = [_straight(b, 600) for b in (1000, 100, 700, 400, 600)] + [[-2.0] * len(ROWS_720)]
    record = {"raw_file": "a.jpg", "lanes": lanes, "h_samples": ROWS_720}
    assert frames_module.positions(record, 1280, 720) == ["adjacent", "outer", "ego", "adjacent", "ego", None]


def test_a_line_leaving_the_frame_is_placed_where_its_lowest_points_meet_the_bottom_row(frames_module):
    # labelled on rows 300-500 only, x = y - 100: its five lowest points (460-500) extended meet row 720 at 620
    xs = [y - 100.0 if 300 <= y <= 500 else -2 for y in ROWS_720]
    assert frames_module.bottom_x(xs, ROWS_720, 720) == pytest.approx(620.0)
    assert frames_module.bottom_x([-2.0] * len(ROWS_720), ROWS_720, 720) is None
    one = [-2.0] * len(ROWS_720)
    one[10] = 333.0
    assert frames_module.bottom_x(one, ROWS_720, 720) == 333.0


def test_a_line_is_recalled_as_lane_py_matches_it_and_too_many_predictions_recall_none(frames_module):
    from stamlane_eval.tusimple import evaluate_image

    gt = [_straight(b, 600) for b in (300, 600, 1000)]
    record = {"raw_file": "a.jpg", "lanes": gt, "h_samples": ROWS_720}
    near, off = [x + 10 if x >= 0 else x for x in gt[0]], [x + 40 if x >= 0 else x for x in gt[2]]
    assert frames_module.matched_lanes([near, gt[1], off], record) == [True, True, False]  # 10 px in, 40 px out
    assert evaluate_image([near, gt[1], off], gt, ROWS_720).matched == 2  # what lane.py counts
    six = [near, gt[1], off, _straight(50, 500), _straight(1200, 700), _straight(20, 600)]  # > 3 + 2: the frame missed
    assert frames_module.matched_lanes(six, record) == [False, False, False]
    numbers = frames_module.frame_numbers([near, gt[1], off], 3, record, (1280, 720))
    # bottoms 300 and 600 on the left (600 ego, 300 adjacent), 1000 the right ego line: the right one missed
    assert numbers["positions"] == {"ego": [2, 1], "adjacent": [1, 1], "outer": [0, 0]} and numbers["gt_lanes"] == 3


def _frame(ego: tuple[int, int], adjacent: tuple[int, int], pred: int, gt: int) -> dict:
    return {
        "positions": {"ego": list(ego), "adjacent": list(adjacent), "outer": [0, 0]},
        "pred_lanes": pred,
        "gt_lanes": gt,
    }


def test_recall_by_position_and_the_count_error_by_hand(frames_module):
    frames = [_frame((2, 2), (1, 1), 4, 3), _frame((2, 1), (1, 0), 3, 3), _frame((2, 2), (0, 0), 5, 2)]
    recall = frames_module.position_recall(frames)
    assert recall["ego"]["recall"] == pytest.approx(5 / 6) and recall["ego"]["labelled"] == 6
    assert recall["adjacent"]["recall"] == pytest.approx(1 / 2) and recall["adjacent"]["frames"] == 2
    assert recall["outer"]["recall"] is None and recall["outer"]["labelled"] == 0
    assert recall["ego"]["interval"] is None  # 3 frames: fewer than MIN_INTERVAL_FRAMES, no interval
    counts = frames_module.count_numbers(frames)  # errors +1, 0, +3
    assert counts["mean_abs_error"] == pytest.approx(4 / 3) and counts["mean_error"] == pytest.approx(4 / 3)
    assert (counts["over_counted"], counts["under_counted"], counts["exact"], counts["over_max"]) == (2, 0, 1, 1)


def test_the_intervals_resample_frames_and_drop_resamples_without_the_position(frames_module):
    every = [_frame((2, 2), (1, 1), 3, 3)] * 6
    assert frames_module.position_recall(every)["ego"]["interval"] == [1.0, 1.0]
    mixed = [_frame((2, k % 3), (1 if k < 5 else 0, 1 if k < 2 else 0), 3, 3) for k in range(12)]
    recall = frames_module.position_recall(mixed)
    low, high = recall["ego"]["interval"]
    assert low < recall["ego"]["recall"] < high and 0.0 <= low and high <= 1.0
    assert recall["ego"]["resamples"] == frames_module.RESAMPLES
    # adjacent lines in 5 of 12 frames: a resample may draw none of them; it is left out, not scored 0/0
    assert 0 < recall["adjacent"]["resamples"] <= frames_module.RESAMPLES
    assert frames_module.position_recall(mixed) == recall  # seeded: the same frames give the same interval


def test_the_committed_split_is_the_protocols_rule(frames_module, bench):
    split = frames_module.read_split()
    dev_video = [r["raw_file"] for r in bench.read_video_labels()]
    assert set(dev_video) <= set(split["dev"]) and not set(split["dev"]) & set(split["sealed"])
    dev = [int(name.rpartition("#")[2]) for name in dev_video]
    rule = [i for i in range(4, 221, 4) if min(abs(i - d) for d in dev) >= 3]  # docs/real-protocol.md
    rejected = [int(r["raw_file"].rpartition("#")[2]) for r in split["rejected"]]
    assert len(rule) == 45 and [int(n.rpartition("#")[2]) for n in split["sealed"]] == sorted(set(rule) - set(rejected))
    records = bench.sealed_labels()  # the sealed file is the one the split was made from (its SHA-256)
    assert [r["raw_file"] for r in records] == split["sealed"]
    assert all(len(r["lanes"]) == 3 for r in records)  # the label rule's three lines on every kept frame


def test_a_changed_sealed_file_or_a_sealed_frame_among_the_dev_labels_is_refused(frames_module, bench, tmp_path: Path):
    split = frames_module.read_split()
    records = bench.read_video_labels(bench.SEALED_LABELS)
    changed = tmp_path / "sealed.json"
    changed.write_text("".join(json.dumps(r) + "\n" for r in records[:-1]))
    key = "benchmarks/labels/solidWhiteRight-sealed.json"
    with pytest.raises(frames_module.RealFramesError, match="SHA-256"):
        frames_module.check_split_labels(split, key, changed, records[:-1], "sealed")
    with pytest.raises(frames_module.RealFramesError, match="is not a dev frame"):
        frames_module.check_split_labels(
            split | {"labels": {key: {"sha256": _sha(changed)}}}, key, changed, records[:1], "dev"
        )


def _sha(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


def _fake_shared(root: Path, lines: list[str]) -> Path:
    (root / "data" / "real").mkdir(parents=True)
    (root / "data" / "lanenet_frames.json").write_text("".join(line + "\n" for line in lines))
    return root


@pytest.mark.parametrize(
    ("lines", "said"),
    [
        (["{not json"], "line 1"),
        (['{"raw_file": "../../outside.jpg", "lanes": [[1, 2]], "h_samples": [700, 710]}'], "leads outside"),
        (['{"raw_file": "/etc/hostname", "lanes": [[1, 2]], "h_samples": [700, 710]}'], "leads outside"),
        (['{"raw_file": "frames/a\\u0000.jpg", "lanes": [[1, 2]], "h_samples": [700, 710]}'], "NUL"),
        (['{"raw_file": "frames/a.jpg", "lanes": [[1, 2]], "h_samples": [700, 710]}'] * 2, "frames/a.jpg"),
        (['{"raw_file": "frames/a.jpg", "lanes": "x", "h_samples": [700, 710]}'], "lanes"),
    ],
)
def test_bad_labels_are_one_line_naming_the_file_and_write_nothing(
    bench, tmp_path: Path, capsys: pytest.CaptureFixture, lines: list[str], said: str
):
    shared, out = _fake_shared(tmp_path / "shared", lines), tmp_path / "out"
    (tmp_path / "outside.jpg").write_bytes(b"not read")
    assert bench.main(["--ckpt", "single-synthetic", "--shared", str(shared), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("real_roads: error:") and "lanenet_frames.json" in err[0], err
    assert said in err[0] and not out.exists()


def test_a_video_label_of_another_file_and_sealed_options_are_refused(
    bench, shared_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
):
    other = tmp_path / "labels.json"
    other.write_text(json.dumps({"raw_file": "../x.mp4#3", "lanes": [[1, 2]], "h_samples": [700, 710]}) + "\n")
    with pytest.raises(bench.real_frames.RealFramesError, match=r"no frame of solidWhiteRight\.mp4"):
        bench.read_video_labels(other)
    out = tmp_path / "out"
    for extra in (["--frames", "2"], ["--decode", "model"]):
        assert bench.main(["--split", "sealed", "--shared", str(shared_dir), "--out", str(out), *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--split sealed" in err[0] and not out.exists()


def test_the_dev_check_reports_lines_by_position_and_count(bench, shared_dir: Path, tmp_path: Path):
    out = tmp_path / "real"
    argv = ["--ckpt", "single-dashcam", "--shared", str(shared_dir), "--frames", "1", "--video-frames", "12"]
    assert bench.main([*argv, "--strip", "1", "--out", str(out)]) == 0
    result = json.loads((out / "single-dashcam.json").read_text())
    photo, video = result["labelled_frames"], result["video"]["labelled_frames"]
    assert result["split"] == "dev" and photo["per_frame"][0]["gt_lanes"] == 4  # photo 0: four labelled lines
    assert photo["by_position"]["ego"]["labelled"] == 2 and photo["by_position"]["adjacent"]["labelled"] == 2
    # the video's rule: the ego pair and the next line on the left (frame 11, the one streamed)
    assert video["by_position"]["ego"]["labelled"] == 2 and video["by_position"]["adjacent"]["labelled"] == 1
    assert video["by_position"]["ego"]["matched"] + video["by_position"]["adjacent"]["matched"] == video["lane_tp"]
    assert video["counts"]["frames"] == 1 and photo["f1_interval"] is None  # one frame: no interval
    assert "By lane position and count (dev)" in (out / "summary.md").read_text()


def test_the_sealed_check_scores_the_sealed_frames_streamed_with_history(bench, shared_dir: Path, tmp_path: Path):
    out = tmp_path / "sealed"
    argv = ["--split", "sealed", "--ckpt", "single-synthetic", "--shared", str(shared_dir), "--video-frames", "9"]
    assert bench.main([*argv, "--strip", "2", "--out", str(out)]) == 0
    result = json.loads((out / "single-synthetic-sealed.json").read_text())
    numbers = result["video"]["labelled_frames"]
    assert result["split"] == "sealed" and "labelled_frames" not in result  # no photo: they are dev
    assert [f["raw_file"] for f in numbers["per_image"]] == ["solidWhiteRight.mp4#4", "solidWhiteRight.mp4#8"]
    assert result["video"]["by_stretch"] == {"early": {"f1": numbers["f1"], "images": 2}}
    assert "labels/solidWhiteRight-sealed.json" in numbers["labels"]
    assert (out / "summary-sealed.md").is_file() and not (out / "summary.md").exists()


def test_a_synthetic_label_leading_out_of_val_is_refused_before_any_model(
    bench, shared_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
):
    val, out = tmp_path / "val", tmp_path / "out"
    val.mkdir()
    record = {"raw_file": "../elsewhere/clip/3.jpg", "lanes": [[1, 2]], "h_samples": [100, 110]}
    (val / "val.json").write_text(json.dumps(record) + "\n")
    argv = ["--ckpt", "no-such-model", "--shared", str(shared_dir), "--out", str(out), "--val", str(val)]
    assert bench.main(argv) == 2  # said before the checkpoint (which does not exist) is opened
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "leads outside" in err[0] and "val.json" in err[0] and not out.exists()
