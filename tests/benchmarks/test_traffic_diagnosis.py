"""``benchmarks/traffic_diagnosis.py``: the vehicle-hidden points, what the aligned history shows of them, what the
networks recall there, and where ORB alignment fails with vehicles in view."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from stamlane.synth.clip import SynthClip, generate_clip
from stamlane.synth.config import FACTORS, REVEAL_TRAFFIC, SynthConfig
from stamlane.synth.layout import SPLITS
from tests.benchmarks.scripts import benchmark_module
from tests.tiny_checkpoint import save_tiny_checkpoint

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results" / "traffic"


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("traffic_diagnosis") as module:
        yield module


def _shift(dx: float) -> np.ndarray:
    """A ground homography that differs from the identity by ``dx`` pixels across."""
    return np.array([[1.0, 0, dx], [0, 1, 0], [0, 0, 1]])


def _clip() -> SynthClip:
    """Four 40x64 frames, one vertical line at x = 20 (the key frame's), the camera moving 3 px right a frame (the
    line 3 px further left in each later frame); a vehicle over rows 18-27 of the line in the key frame and, one
    frame back, over rows 18-22 of where the line lies there; paint visible wherever no vehicle stands."""
    h, w, rows = 40, 64, [10, 15, 20, 25, 30, 35]
    frames, contrasts, labels, occluded, homs, masks = [], [], [], [], [], []
    for back in (3, 2, 1, 0):
        x = 20 + 3 * back  # where the line lies in this frame
        contrast = np.zeros((h, w), np.uint8)
        contrast[:, x] = 60
        mask = np.zeros((h, w), np.uint8)
        if back == 0:
            mask[18:28, x - 4 : x + 5] = 255
        if back == 1:
            mask[18:23, x - 4 : x + 5] = 255
        contrast[mask > 0] = 0
        frames.append(np.zeros((h, w, 3), np.uint8))
        contrasts.append(contrast)
        labels.append([[x] * len(rows)])
        occluded.append([[bool(mask[y, x]) for y in rows]])
        homs.append(_shift(3.0 * back))  # image_from_ground: key_from_hist(key, key - j) = a shift by -3 j
        masks.append(mask)
    return SynthClip(frames, labels, occluded, rows, homs, masks, contrasts)


def test_the_hidden_points_are_the_vehicle_masks_labelled_points(bench):
    clip = _clip()
    assert bench.hidden_points(clip, 3) == [(0, 2), (0, 3)]  # rows 20 and 25: under the vehicle; 30 is past it
    assert bench.hidden_points(clip, 2) == [(0, 2)]  # one frame back: row 20 alone


def test_the_history_shows_what_the_exact_alignment_finds_uncovered_and_a_wrong_one_does_not(bench):
    clip = _clip()
    key, hidden = 3, bench.hidden_points(clip, 3)
    exact = [clip.key_from_hist(key, key - j) for j in range(4)]
    masks = bench.history_shows(clip, key, exact)
    # row 20: covered one frame back too, free 2 and 3 back; row 25: free in every history frame
    assert masks[0][2] == 0b1100 and masks[0][3] == 0b1110
    assert masks[0][0] == 0b1111  # a point no vehicle hides: visible in the key frame and every history frame
    assert bench.shown_counts(masks, hidden) == [2, 2, 1, 2, 2]
    wrong = [exact[0], *(m @ _shift(4.0) for m in exact[1:])]  # 4 px off: beyond the 2-px window, no paint there
    assert bench.shown_counts(bench.history_shows(clip, key, wrong), hidden) == [2, 0, 0, 0, 0]
    with pytest.raises(ValueError, match="paint_contrast"):
        bench.history_shows(SynthClip(*[getattr(clip, f) for f in ("frames", "labels", "occluded", "h_samples",
                                                                   "image_from_ground", "vehicle_masks")]), key, exact)  # fmt: skip


def test_point_counts_split_the_recall_by_what_hides_a_point(bench):
    clip = _clip()
    hidden = bench.hidden_points(clip, 3)
    right = [[20] * 6]  # on the line
    off_far = [[20, 20, 20, 20, 50, 50]]  # the last two rows 30 px off
    assert bench.point_counts(right, clip, 3, hidden, {(0, 3)}) == [2, 2, 1, 1, 1, 1, 4, 4]
    assert bench.point_counts(off_far, clip, 3, hidden, {(0, 2)}) == [2, 2, 1, 1, 1, 1, 2, 4]
    assert bench.point_counts([], clip, 3, hidden, set()) == [0, 2, 0, 0, 0, 2, 0, 4]


def test_on_mask_counts_the_margin(bench):
    mask = np.zeros((20, 20), np.uint8)
    mask[5:8, 5:8] = 255
    points = np.array([[6, 6], [9, 6], [10.6, 6], [15, 15]], np.float32)  # inside, 2 px off, 4 px off, far
    assert bench.on_mask(mask, points).tolist() == [True, True, False, False]


@pytest.mark.parametrize(
    ("kind", "split", "position"), [("same_speed", "reveal-traffic", 1), ("traffic_oncoming", "challenging", 2)]
)
def test_a_kind_renders_its_splits_own_clips_and_the_control_keeps_road_and_motion(bench, kind, split, position):
    factor = REVEAL_TRAFFIC[kind] if kind in REVEAL_TRAFFIC else FACTORS[kind]
    cycle = len(REVEAL_TRAFFIC) if kind in REVEAL_TRAFFIC else len(FACTORS)
    assert bench.kind_split(kind) == (split, position, cycle) and bench.split_index(kind, 2) == position + 2 * cycle
    config = SynthConfig().overridden(factor.overrides)
    small = {"width": 160, "height": 96, "num_frames": 6}
    clip = bench.render(kind, 5, 1, **small)
    split_clip = generate_clip(
        config.overridden(small), np.random.default_rng([5, SPLITS.index(split), position + cycle])
    )
    assert all(np.array_equal(a, b) for a, b in zip(clip.frames, split_clip.frames, strict=True))
    bare = bench.render(kind, 5, 1, occluder_prob=0.0, **small)
    assert all(np.allclose(a, b) for a, b in zip(clip.image_from_ground, bare.image_from_ground, strict=True))
    assert any(m.any() for m in clip.vehicle_masks) and not any(m.any() for m in bare.vehicle_masks)
    assert bench.clip_keys(kind, 20) == ([19] if kind in REVEAL_TRAFFIC else [7, 10, 13, 16, 19])


def test_a_tiny_run_writes_its_numbers_and_their_table(bench, tmp_path: Path, capsys) -> None:
    out = tmp_path / "traffic"
    argv = ["--clips", "2", "--kinds", "oncoming_close", "--ckpt", "stam4-synthetic", "single-synthetic"]
    assert bench.main([*argv, "--resamples", "100", "--out", str(out)]) == 0
    result = json.loads((out / "diagnosis.json").read_text())
    entry = result["kinds"]["oncoming_close"]
    assert entry["split"] == "reveal-traffic" and entry["fps"] == 5.0 and entry["split_indices"] == [0, 2]
    summary = entry["summary"]
    assert summary["key_frames"] == 2 and summary["hidden_points"] > 0
    assert set(summary["models"]["stam4-synthetic"]) == {"real", "exact", "copies", "real_minus_copies",
                                                         "exact_minus_copies"}  # fmt: skip
    assert set(summary["models"]["single-synthetic"]) == {"real"}
    use = summary["models"]["stam4-synthetic"]["real_minus_copies"]["f1"]["value"]
    f1 = {p: summary["models"]["stam4-synthetic"][p]["f1"]["value"] for p in ("real", "copies")}
    assert use == pytest.approx(f1["real"] - f1["copies"])
    assert {"5fps/with/1", "20fps/without/3", "5fps/support/2"} <= set(summary["alignment"])
    assert (out / "summary.md").read_text() == bench.table(result)
    assert "| oncoming_close | stam4-synthetic | real − copies |" in capsys.readouterr().out


def test_another_preset_is_paired_with_standard_on_the_same_key_frames(bench, tmp_path: Path) -> None:
    """``--align-preset motion``: the 4-frame model also reads the history the standard chain aligns, and the
    difference is paired over the same clips (the history the 1-frame model never reads: not run)."""
    out = tmp_path / "traffic"
    argv = ["--clips", "2", "--kinds", "oncoming_close", "--ckpt", "stam4-synthetic", "single-synthetic"]
    assert bench.main([*argv, "--resamples", "100", "--align-preset", "motion", "--out", str(out)]) == 0
    models = json.loads((out / "diagnosis.json").read_text())["kinds"]["oncoming_close"]["summary"]["models"]
    stam4 = models["stam4-synthetic"]
    assert {"standard", "real_minus_standard"} <= set(stam4) and set(models["single-synthetic"]) == {"real"}
    f1 = {p: stam4[p]["f1"]["value"] for p in ("real", "standard")}
    assert stam4["real_minus_standard"]["f1"]["value"] == pytest.approx(f1["real"] - f1["standard"])
    low, high = (stam4["real_minus_standard"]["f1"][k] for k in ("low", "high"))
    assert low <= f1["real"] - f1["standard"] <= high
    assert "| oncoming_close | stam4-synthetic | real − standard |" in (out / "summary.md").read_text()


def test_a_model_of_another_stride_is_read_only_with_any_stride(bench, tmp_path: Path, capsys) -> None:
    """A stride-4 fine-tune is refused by name (its spacing and the clips' differ) unless ``--any-stride`` asks for
    it; then it reads the same consecutive frames and the result records its stride."""
    ckpt = save_tiny_checkpoint(tmp_path / "s4-s0.ckpt", num_frames=4)
    content = torch.load(ckpt, map_location="cpu", weights_only=False)
    content["datamodule_hyper_parameters"]["stride"] = 4
    torch.save(content, ckpt)
    argv = ["--clips", "2", "--kinds", "oncoming_close", "--resamples", "100", "--ckpt", str(ckpt)]
    assert bench.main([*argv, "--out", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "of stride 1 (--any-stride reads other strides)" in err[0]
    assert not (tmp_path / "refused").exists()
    assert bench.main([*argv, "--any-stride", "--out", str(tmp_path / "read")]) == 0
    result = json.loads((tmp_path / "read" / "diagnosis.json").read_text())
    assert result["strides"] == {"s4-s0": 4}
    assert {"real", "copies", "real_minus_copies"} <= set(
        result["kinds"]["oncoming_close"]["summary"]["models"]["s4-s0"]
    )
    two = save_tiny_checkpoint(tmp_path / "two-s0.ckpt", num_frames=2)  # any stride, but still 1 or 4 frames
    assert bench.main([*argv[:-1], str(two), "--any-stride", "--out", str(tmp_path / "two")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith("not a 1-frame or 4-frame model") and not (tmp_path / "two").exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["--kinds", "snow"],
        ["--clips", "1"],
        ["--clips", "1000"],
        ["--resamples", "5"],
        ["--seed", "-1"],
        ["--ckpt", "nowhere.ckpt"],
        ["--any-stride", "--ckpt", "nowhere.ckpt"],
        ["--any-stride", "--ckpt", "/dev/zero"],
    ],
)
def test_bad_input_is_one_line_status_2_and_writes_nothing(bench, tmp_path: Path, capsys, argv: list[str]) -> None:
    out = tmp_path / "out"
    assert (
        bench.main([*argv, "--clips", "2", "--out", str(out)] if "--clips" not in argv else [*argv, "--out", str(out)])
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("traffic_diagnosis: error: ")
    assert not out.exists()


@pytest.mark.parametrize(
    "folder", sorted(p.parent.relative_to(RESULTS).as_posix() for p in RESULTS.rglob("diagnosis.json"))
)
def test_the_committed_table_is_the_committed_numbers(bench, folder: str) -> None:
    """Every committed diagnosis (the shipped models', each probe's) beside the table it was written with."""
    out = json.loads((RESULTS / folder / "diagnosis.json").read_text())
    assert bench.table(out) == (RESULTS / folder / "summary.md").read_text()
