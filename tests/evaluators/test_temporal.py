"""RVLD's temporal stability (Ns/Nj/Nm, Rs/Rj/Rm): parity with the script's own numbers, quirks, the CLI."""

from __future__ import annotations

import importlib.util
import itertools
import json
import math
from pathlib import Path
from types import ModuleType

import cv2
import numpy as np
import pytest
from stamlane_eval import temporal, video
from stamlane_eval.cli import main
from stamlane_eval.io import read_culane_lines
from stamlane_eval.temporal import _draw, _inter, _spline, _unique_points
from stamlane_eval.video import Frame

GOLDEN = Path(__file__).parent / "golden" / "temporal"
EXPECTED = json.loads((GOLDEN / "expected.json").read_text())
SIZE = (360, 640)  # (H, W)
A = np.array([[150.0, 359.0], [220.0, 250.0], [290.0, 150.0]])
B = np.array([[490.0, 359.0], [420.0, 250.0], [350.0, 150.0]])


def _cases() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_cases", GOLDEN / "make_cases.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def golden_sequences(protocol: str) -> dict[str, list[Frame]]:
    """The committed golden set, every frame at its own size (vil100) as RVLD's shape_list gives it."""
    sizes = json.loads((GOLDEN / "sizes.json").read_text())
    seqs: dict[str, list[Frame]] = {}
    for entry in (GOLDEN / "list.txt").read_text().split():
        pred = read_culane_lines(GOLDEN / "pred" / f"{entry}.lines.txt")
        anno = read_culane_lines(GOLDEN / "anno" / f"{entry}.lines.txt")
        size = tuple(sizes[entry]) if protocol == "vil100" else None
        seqs.setdefault(entry.rsplit("/", 1)[0], []).append(Frame(pred, anno, size=size))
    return seqs


# ------------------------------------------------------------------------------------------------ parity
@pytest.mark.parametrize("protocol", ["vil100", "openlane-v"])
def test_golden_parity_with_rvld(protocol: str) -> None:
    want = EXPECTED["rvld"][protocol]
    thresholds = [float(t) for t in want]  # vil100 also at 0.0 and 0.3: the > / < quirks
    res = temporal.evaluate(golden_sequences(protocol), thresholds, protocol=protocol)
    pairs = [p for s in res.per_sequence for p in s.per_pair]
    for t in thresholds:
        assert res.totals[t].as_dict() == want[str(t)]["totals"], t  # counts and ratios, every bit
        assert [list(p[t]) for p in pairs] == want[str(t)]["per_pair"], t
    assert res.pairs == len(pairs) == 85 and res.frames == 113


def _lanes(lanes: list) -> list[np.ndarray]:
    return [np.zeros((0, 2)) if lane is None else np.asarray(lane, float) for lane in lanes]


def outcome_sequences(name: str, protocol: str) -> dict[str, list[Frame]]:
    """One of make_cases.outcome_cases(): small datasets on which RVLD's script fails or nearly does."""
    _, cases = _cases().outcome_cases()[name]
    return {
        seq: [Frame(_lanes(p), _lanes(a), size=None if protocol == "openlane-v" else sz) for a, p, sz in frames]
        for seq, _, frames in cases
    }


@pytest.mark.parametrize("protocol", ["vil100", "openlane-v"])
@pytest.mark.parametrize("name", sorted(EXPECTED["outcomes"]))
def test_outcomes_where_rvld_fails_or_nearly(name: str, protocol: str) -> None:
    seqs = outcome_sequences(name, protocol)
    want = EXPECTED["outcomes"][name]["rvld_vil100" if protocol == "vil100" else "rvld_openlane-v"]
    error = want.get("error", "")
    if error.startswith("TypeError"):  # splprep's k = 0 on a one-point lane: a ValueError naming the lane
        with pytest.raises(ValueError, match="all its points at one place"):
            temporal.evaluate(seqs, (0.5, 0.8), protocol=protocol)
        return
    res = temporal.evaluate(seqs, (0.5, 0.8), protocol=protocol)
    if error.startswith("ZeroDivisionError"):  # no lane matched across frames: the ratios are NaN here
        assert res.totals[0.5].total == 0 and math.isnan(res.totals[0.5].rs)
        assert res.totals[0.5].as_dict()["Rs"] is None
        return
    for t in ("0.5", "0.8"):
        assert res.totals[float(t)].as_dict() == want[t]["totals"]


def test_large_vil100_sized_lanes_match_full_image_drawing() -> None:
    """The cropped, row-run drawing equals draw_lane's full (H, W, 3) images, IoU bit for bit."""
    rng = np.random.default_rng(5)
    size = (1080, 1920)
    for _ in range(6):
        lanes = []
        for _ in range(3):
            y = np.linspace(1079, rng.uniform(400, 700), int(rng.integers(5, 60)))
            x = rng.uniform(-100, 2000) + (1079 - y) * rng.uniform(-1.5, 1.5)
            lanes.append(_spline(_unique_points(np.stack([x, y], 1), "vil100", 0, "a")))
        masks = []
        for pts in lanes:
            img = np.zeros((*size, 3), np.uint8)
            for p1, p2 in itertools.pairwise(pts):
                cv2.line(img, tuple(int(v) for v in p1), tuple(int(v) for v in p2), (255, 255, 255), thickness=30)
            masks.append(img > 0)
        drawn = [_draw(p, size) for p in lanes]
        for i, j in itertools.product(range(3), repeat=2):
            x, y = masks[i], masks[j]
            want = (x & y).sum() / ((x | y).sum() + temporal.IOU_EPS)
            assert temporal._iou_matrix([drawn[i]], [drawn[j]])[0, 0] == want


def test_predictions_far_outside_the_image_are_drawn_clipped_as_the_script_draws_them() -> None:
    """x = +-150,000 (RVLD's script scores them): drawn on a canvas no larger than the image, pixel for pixel
    draw_lane's full image (nothing, or the part that crosses it)."""
    size = (360, 640)
    for pts in (
        np.array([[150000, 10], [150010, 300]], np.int32),
        np.array([[-150000, 10], [-150000, 300]], np.int32),
        np.array([[-150000, 0], [150000, 359]], np.int32),  # crosses the image
        np.array([[-150000, 300], [320, 200], [150000, 100]], np.int32),
    ):
        want = np.zeros((*size, 3), np.uint8)
        for p1, p2 in itertools.pairwise(pts):
            cv2.line(want, tuple(int(v) for v in p1), tuple(int(v) for v in p2), (255, 255, 255), thickness=30)
        d = _draw(pts, size)
        assert d.mask.size <= size[0] * size[1]
        got = np.zeros(size, bool)
        got[d.y0 : d.y0 + d.mask.shape[0], d.x0 : d.x0 + d.mask.shape[1]] = d.mask > 0
        assert (got == (want[..., 0] > 0)).all()
    far = [np.array([[150000.0, 350], [150003, 200], [150010, 10]])]
    frame = temporal.evaluate_frame([*far, A], [A], size)
    assert frame.anno_iou.tolist() == temporal.evaluate_frame([A], [A], size).anno_iou.tolist()


def test_intersections_of_crops_equal_full_images() -> None:
    lanes = [
        np.array([[100, 300], [160, 200], [240, 180], [300, 220], [320, 300]], np.int32),  # turns back
        np.array([[90, 359], [330, 150]], np.int32),
        np.array([[600, 350], [700, 300]], np.int32),  # leaves the image on the right
        np.array([[-50, 10], [20, -40]], np.int32),  # mostly outside, top left
    ]
    drawn = [_draw(p, SIZE) for p in lanes]

    def full(d: temporal._Drawn) -> np.ndarray:
        img = np.zeros(SIZE, bool)
        img[d.y0 : d.y0 + d.mask.shape[0], d.x0 : d.x0 + d.mask.shape[1]] = d.mask > 0
        return img

    for p, q in itertools.product(drawn, repeat=2):
        assert _inter(p, q) == np.count_nonzero(full(p) & full(q))
    assert _draw(np.array([[900, 10], [950, 0]], np.int32), SIZE).area == 0  # entirely outside


def test_crops_hold_draw_lanes_pixels_with_repeated_points_and_at_the_borders() -> None:
    """_draw keeps repeated points (a zero-length segment only repeats a cap) and crops 17 px around the
    points: pixel for pixel draw_lane's full image, wherever the lane is, and the crop's border stays empty."""
    rng = np.random.default_rng(11)
    cases = [
        np.array([[100, 100], [100, 100]], np.int32),  # one point twice: a round cap alone
        np.array([[100, 100], [100, 100], [140, 200], [140, 200], [140, 200], [90, 300]], np.int32),
        np.array([[5, 5], [5, 5], [7, 6]], np.int32),  # in the corner: the image clips it
        np.array([[630, 350], [700, 400], [600, 359]], np.int32),  # out of the bottom right and back
    ]
    for _ in range(40):  # random walks of short steps, as the splines' truncated samples are
        start = rng.integers(-20, [660, 380])
        cases.append((start + np.cumsum(rng.integers(-4, 5, (int(rng.integers(2, 80)), 2)), 0)).astype(np.int32))
    for pts in cases:
        want = np.zeros((*SIZE, 3), np.uint8)
        for p1, p2 in itertools.pairwise(pts):
            cv2.line(want, tuple(int(v) for v in p1), tuple(int(v) for v in p2), (255, 255, 255), thickness=30)
        d = _draw(pts, SIZE)
        got = np.zeros(SIZE, bool)
        h, w = d.mask.shape
        got[d.y0 : d.y0 + h, d.x0 : d.x0 + w] = d.mask > 0
        assert (got == (want[..., 0] > 0)).all() and d.area == np.count_nonzero(want[..., 0])
        if d.area:  # two empty rows / columns inside the crop wherever it is not cut by the image
            assert d.y0 == 0 or not d.mask[:2].any()
            assert d.x0 == 0 or not d.mask[:, :2].any()
            assert d.y0 + h == SIZE[0] or not d.mask[-2:].any()
            assert d.x0 + w == SIZE[1] or not d.mask[:, -2:].any()


# ------------------------------------------------------------------------------------------------ quirks
def test_stable_jump_missing_and_the_threshold_itself() -> None:
    assert temporal.stability_counts(0.9, 0.7, 0.5) == (1, 0, 0)
    assert temporal.stability_counts(0.9, 0.1, 0.5) == (0, 1, 0)
    assert temporal.stability_counts(0.0, 0.7, 0.5) == (0, 1, 0)
    assert temporal.stability_counts(0.2, 0.0, 0.5) == (0, 0, 1)
    # exactly at the threshold is neither above nor below: the script's else, Stable
    assert temporal.stability_counts(0.5, 0.1, 0.5) == (1, 0, 0)
    assert temporal.stability_counts(0.0, 0.0, 0.0) == (1, 0, 0)  # at T = 0 a lane missed twice is Stable


def test_duplicate_points_dropped_wherever_they_are() -> None:
    lane = np.array([[1.0, 9.0], [2.0, 5.0], [1.0, 9.0], [3.0, 1.0], [-0.0, 0.0], [0.0, 0.0]])
    assert _unique_points(lane, "vil100", 0, "x") == [(1.0, 9.0), (2.0, 5.0), (3.0, 1.0), (-0.0, 0.0)]
    assert _unique_points(lane[:1], "vil100", 0, "x") is None  # < 2 points: dropped before de-duplication
    one = _unique_points(np.array([[4.0, 4.0], [4.0, 4.0]]), "vil100", 0, "x")
    assert one == [(4.0, 4.0)] and _spline(one) is None


def test_spline_samples_and_truncation() -> None:
    pts = _spline([(0.0, 10.0), (-3.7, 5.0), (2.0, 0.0)])
    assert len(pts) == (3 - 1) * temporal.SPLINE_SAMPLES + 1 and pts.dtype == np.int32
    assert pts[0].tolist() == [0, 10] and pts[-1].tolist() == [2, 0]


def test_openlane_v_scales_to_its_canvas() -> None:
    lane = np.array([[1919.0, 1279.0], [0.0, 0.0]])
    assert _unique_points(lane, "openlane-v", 0, "x") == [(959.0, 639.0), (0.0, 0.0)]
    frame = temporal.evaluate_frame([lane], [lane], None, "openlane-v")
    assert frame.size == temporal.OPENLANE_V_EVAL_SIZE
    assert 1 - 1e-12 < frame.anno_iou[0] < 1.0  # the eps: a lane's IoU with itself is just below 1
    with pytest.raises(ValueError, match="openlane-v"):
        temporal.evaluate_frame([lane], [lane], (720, 1280), "openlane-v")


def test_previous_frame_is_drawn_at_the_current_size() -> None:
    near_edge = np.array([[600.0, 340.0], [630.0, 355.0], [700.0, 400.0]])
    big, small = Frame([near_edge], [near_edge], size=(720, 1280)), Frame([near_edge], [near_edge], size=SIZE)
    res = temporal.evaluate({"s": [big, small, big]})
    assert res.totals[0.5].as_dict() == {"Ns": 2, "Nj": 0, "Nm": 0, "Rs": 1.0, "Rj": 0.0, "Rm": 0.0}


def test_worked_example_of_the_docs() -> None:
    """The tiny sequence of docs/evaluators.md."""
    frames = [
        Frame([A, B], [A, B], size=SIZE),  # frame 0 opens the sequence: no pair
        Frame([B], [A, B], size=SIZE),  # A missed: A jumps (0 -> 1), B stays
        Frame([], [A, B], size=SIZE),  # nothing predicted: A missing twice, B jumps
    ]
    res = temporal.evaluate_sequence(frames, "clip")
    assert res.per_pair == [{0.5: (1, 1, 0), 0.8: (1, 1, 0)}, {0.5: (0, 1, 1), 0.8: (0, 1, 1)}]
    assert res.counts[0.5].as_dict() == {"Ns": 1, "Nj": 2, "Nm": 1, "Rs": 0.25, "Rj": 0.5, "Rm": 0.25}


def test_bad_input() -> None:
    with pytest.raises(ValueError, match="protocol"):
        temporal.evaluate({"s": [Frame([A], [A], size=SIZE)]}, protocol="tusimple")
    with pytest.raises(ValueError, match="size"):
        temporal.evaluate({"s": [Frame([A], [A])]})
    with pytest.raises(ValueError, match=r"clip frame 1: annotated lane 0: expected an \(N, 2\)"):
        temporal.evaluate({"clip": [Frame([A], [A], size=SIZE), Frame([A], [np.zeros(3)], size=SIZE)]})
    with pytest.raises(ValueError, match="non-finite"):
        temporal.evaluate_frame([A], [np.array([[1.0, np.nan], [2.0, 3.0]])], SIZE)
    far = temporal.evaluate_frame([A], [A * 1e6], SIZE)  # a label far outside: drawn clipped, as the script (#59)
    assert far.anno_iou.tolist() == [0.0]
    with pytest.raises(ValueError, match="int32"):
        temporal.evaluate_frame([A], [A * 1e8], SIZE)  # a label beyond the script's drawing, as a prediction
    with pytest.raises(ValueError, match="int32"):
        temporal.evaluate_frame([A * 1e8], [A], SIZE)  # a prediction beyond what the script's drawing can hold
    with pytest.raises(ValueError, match="no sequence"):
        temporal.evaluate({})


# --------------------------------------------------------------------------------------------------- CLI
def _write(root: Path, frames: dict[str, list[list[np.ndarray]]]) -> None:
    for seq, lanes_per_frame in frames.items():
        (root / seq).mkdir(parents=True, exist_ok=True)
        for i, lanes in enumerate(lanes_per_frame):
            text = "".join(" ".join(f"{v:g}" for v in lane.ravel()) + "\n" for lane in lanes)
            (root / seq / f"{i:05d}.lines.txt").write_text(text)


def test_cli_temporal(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    gt, pred = tmp_path / "anno", tmp_path / "pred"
    _write(gt, {"clip": [[A, B], [A, B], [A, B]], "other": [[A], [A]]})
    _write(pred, {"clip": [[A, B], [B], []], "other": [[A], [A]]})
    args = ["video", str(pred), str(gt), "--temporal", "--size", "640x360"]
    assert main([*args, "--json", "--per-sequence", str(tmp_path / "seq.jsonl")]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["0.5"] == {"Ns": 2, "Nj": 2, "Nm": 1, "Rs": 0.4, "Rj": 0.4, "Rm": 0.2}
    assert (res["sequences"], res["frames"], res["pairs"], res["protocol"]) == (2, 5, 3, "vil100")
    per = [json.loads(line) for line in (tmp_path / "seq.jsonl").read_text().splitlines()]
    assert [p["sequence"] for p in per] == ["clip", "other"] and per[0]["0.5"]["Nm"] == 1
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "3 pairs of frames" in out and "0.5   2   2   1  40.00  40.00  20.00" in out
    assert main([*args, "--jobs", "2"]) == 0 and capsys.readouterr().out == out
    for bad in ("-1", "two", "100000"):
        assert main([*args, "--jobs", bad]) == 2
        err = capsys.readouterr().err
        assert "expected a number of processes in 0..256" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("metric", [temporal, video])
def test_progress_bar_over_frames(metric: ModuleType, capsys: pytest.CaptureFixture[str]) -> None:
    """evaluate(progress=True): a bar over the frames on stderr (cleared when done), the same numbers."""
    pytest.importorskip("tqdm")
    seqs = golden_sequences("vil100")
    quiet = metric.evaluate(seqs, (0.5,))
    capsys.readouterr()
    shown = metric.evaluate(seqs, (0.5,), progress=True)
    err = capsys.readouterr().err
    assert shown.as_dict() == quiet.as_dict()
    name = metric.__name__.rsplit(".", 1)[-1]
    assert f"{name}:" in err and f" 0/{quiet.frames} " in err  # tqdm draws its first state at once


@pytest.mark.parametrize("metric", [temporal, video])
def test_sequences_spread_over_processes_give_the_same_numbers(metric: ModuleType) -> None:
    """evaluate(jobs=2): the same result, per sequence and per pair, as one process; the first failing
    sequence in order is the one reported."""
    seqs = golden_sequences("vil100")
    one = metric.evaluate(seqs, (0.5, 0.8))
    two = metric.evaluate(seqs, (0.5, 0.8), jobs=2)
    assert two.as_dict() == one.as_dict()
    assert [s.as_dict() for s in two.per_sequence] == [s.as_dict() for s in one.per_sequence]
    if metric is temporal:
        assert [s.per_pair for s in two.per_sequence] == [s.per_pair for s in one.per_sequence]
    names = list(seqs)
    broken = dict(seqs)
    for name in (names[1], names[-1]):  # a predicted lane with a NaN: refused, naming the sequence
        frames = list(broken[name])
        frames[0] = Frame([np.array([[np.nan, 1.0], [2.0, 3.0]])], frames[0].target, size=frames[0].size)
        broken[name] = frames
    for jobs in (1, 2):
        with pytest.raises(ValueError, match=f"^{names[1]} frame 0"):
            metric.evaluate(broken, (0.5,), jobs=jobs)
    with pytest.raises(ValueError, match="jobs must be >= 0"):
        metric.evaluate(seqs, (0.5,), jobs=-1)


def test_cli_temporal_list_order_and_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    gt, pred = tmp_path / "anno", tmp_path / "pred"
    _write(gt, {"clip": [[A], [A], [A]], "other": [[A], [A]]})
    _write(pred, {"clip": [[A], [], [A]], "other": [[A], [A]]})
    base = ["video", str(pred), str(gt), "--temporal", "--size", "640x360", "--json"]
    listing = tmp_path / "list.txt"
    listing.write_text("/JPEGImages/clip/00000.jpg\n/JPEGImages/clip/00002.jpg\nother/00000\n")  # frame 1 skipped
    assert main([*base, "--list", str(listing)]) == 0
    assert json.loads(capsys.readouterr().out)["0.5"] == {"Ns": 1, "Nj": 0, "Nm": 0, "Rs": 1.0, "Rj": 0.0, "Rm": 0.0}
    listing.write_text("clip/00000\nother/00000\nclip/00001\n")
    assert main([*base, "--list", str(listing)]) == 2
    err = capsys.readouterr().err
    assert "resumes after other sequences" in err and len(err.strip().splitlines()) == 1
    listing.write_text("clip/00000\nother/00000\n")  # one frame per sequence: no pair at all
    assert main([*base, "--list", str(listing)]) == 2
    assert "ZeroDivisionError" in capsys.readouterr().err
    for extra, message in (
        (["--width", "20"], "--width does not apply"),
        (["--protocol", "openlane-v"], "--size does not apply"),
    ):
        assert main([*base, *extra]) == 2
        assert message in capsys.readouterr().err
    (gt / "clip" / "00001.lines.txt").write_text("5 5 5 5\n")  # one point twice: the script's splprep fails
    assert main(base) == 2
    err = capsys.readouterr().err
    assert "clip frame 1" in err and "one place" in err and len(err.strip().splitlines()) == 1


def test_cli_on_the_golden_set_gives_rvld_numbers(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    sizes = json.loads((GOLDEN / "sizes.json").read_text())
    per_frame = tmp_path / "sizes.json"
    per_frame.write_text(json.dumps({e: f"{w}x{h}" for e, (h, w) in sizes.items()}))
    args = ["video", str(GOLDEN / "pred"), str(GOLDEN / "anno"), "--temporal", "--json"]
    assert main([*args, "--list", str(GOLDEN / "list.txt"), "--sizes", str(per_frame)]) == 0
    res = json.loads(capsys.readouterr().out)
    for t in ("0.5", "0.8"):
        assert res[t] == EXPECTED["rvld"]["vil100"][t]["totals"]
    assert main([*args, "--protocol", "openlane-v"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["0.5"] == EXPECTED["rvld"]["openlane-v"]["0.5"]["totals"]
    per_frame.write_text('{"r_00": "640"}')
    assert main([*args, "--sizes", str(per_frame)]) == 2
    assert "'r_00'" in capsys.readouterr().err
