"""The synthetic generator: true homographies, labels, determinism, layout."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from stamlane.synth.clip import generate_clip
from stamlane.synth.config import FACTORS, SynthConfig
from stamlane.synth.dataset import generate_dataset
from stamlane.synth.effects import Windscreen
from stamlane.synth.layout import SplitCounts
from stamlane.synth.statistics import clip_statistics

GEOM = SynthConfig(width=320, height=180, num_frames=6, occluder_prob=0.0)


@pytest.fixture(scope="module")
def clip():
    return generate_clip(GEOM, np.random.default_rng([5, 1]))


def road_rows(cfg: SynthConfig) -> slice:
    cam = cfg.camera()
    return slice(int(cam.cy + 0.12 * cfg.height), cfg.height)


def test_true_homography_aligns_the_road(clip):
    key = clip.frames[-1].astype(np.float32)
    rows = road_rows(GEOM)
    for j in (0, 3):
        h = clip.key_from_hist(len(clip.frames) - 1, j)
        warped = cv2.warpPerspective(clip.frames[j], h, (GEOM.width, GEOM.height)).astype(np.float32)
        cover = cv2.warpPerspective(np.full(clip.frames[j].shape[:2], 255, np.uint8), h, (GEOM.width, GEOM.height))
        valid = cv2.erode(cover, np.ones((5, 5), np.uint8))[rows] > 0
        aligned = np.abs(warped[rows] - key[rows]).mean(axis=2)[valid]
        unaligned = np.abs(clip.frames[j].astype(np.float32)[rows] - key[rows]).mean(axis=2)[valid]
        assert valid.mean() > 0.5
        assert np.median(aligned) < 8.0, np.median(aligned)
        assert np.median(aligned) < 0.5 * np.median(unaligned)


def test_labels_of_every_frame_agree_through_the_homography(clip):
    key_i = len(clip.frames) - 1
    ys = np.asarray(clip.h_samples, dtype=np.float64)
    errors = []
    for j in range(key_i):
        h = clip.key_from_hist(key_i, j)
        for lane in clip.labels[j]:
            for x, y in zip(lane, ys):
                if x < 0:
                    continue
                p = h @ np.array([x, y, 1.0])
                u, v = p[:2] / p[2]
                best = np.inf
                for kl in clip.labels[key_i]:
                    kx = np.asarray(kl, dtype=np.float64)
                    ok = kx >= 0
                    if ok.sum() >= 2 and ys[ok].min() <= v <= ys[ok].max():
                        best = min(best, abs(np.interp(v, ys[ok], kx[ok]) - u))
                if np.isfinite(best):
                    errors.append(best)
    assert len(errors) >= 10
    assert np.median(errors) < 1.5 and np.percentile(errors, 90) < 4.0


def test_same_seed_same_clip_other_seed_other_clip():
    cfg = SynthConfig(width=128, height=72, num_frames=3)
    a = generate_clip(cfg, np.random.default_rng([1, 2]))
    b = generate_clip(cfg, np.random.default_rng([1, 2]))
    c = generate_clip(cfg, np.random.default_rng([1, 3]))
    for fa, fb in zip(a.frames, b.frames):
        np.testing.assert_array_equal(fa, fb)
    assert a.labels == b.labels
    assert not np.array_equal(a.frames[-1], c.frames[-1])


def test_dataset_layout_and_determinism(tmp_path: Path, synthetic_root: Path):
    from tests.conftest import TINY_SYNTH as TINY

    again = tmp_path / "again"
    generate_dataset(again, SplitCounts(train=3, val=1, test=1, challenging=1), seed=3, config=TINY, progress=False)
    # every file of the session's set is one the generator wrote: no reader writes inside it (the alignment cache
    # lives in the user's cache folder, `stamlane.align.user_cache`), whichever tests ran before
    files = sorted(p.relative_to(synthetic_root) for p in synthetic_root.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(again) for p in again.rglob("*") if p.is_file())
    for rel in files:
        assert (synthetic_root / rel).read_bytes() == (again / rel).read_bytes(), rel
    names = {str(p) for p in files}
    for split in ("train", "val", "test", "challenging"):
        assert f"{split}.json" in names
    assert "clips/train-0002/8.jpg" in names and "clips/challenging-0000/1.jpg" in names
    rec = json.loads((synthetic_root / "train.json").read_text().splitlines()[0])
    assert rec["raw_file"] == "clips/train-0000/8.jpg"
    assert all(len(lane) == len(rec["h_samples"]) for lane in rec["lanes"]) and rec["lanes"]
    frames = json.loads((synthetic_root / "frame_labels" / "train-0000.json").read_text())
    assert len(frames) == 8 and frames[-1]["lanes"] == rec["lanes"]
    geo = json.loads((synthetic_root / "homographies" / "train-0000.json").read_text())
    assert len(geo["image_from_ground"]) == 8 and len(geo["next_from_frame"]) == 7
    np.testing.assert_allclose(geo["last_from_frame"][-1], np.eye(3), atol=1e-9)
    info = json.loads((synthetic_root / "dataset.json").read_text())
    assert info["splits"]["train"] == 3 and "statistics" in info
    # a different seed gives different frames
    other = tmp_path / "other"
    generate_dataset(other, SplitCounts(train=1), seed=4, config=TINY, progress=False)
    assert (other / "clips/train-0000/8.jpg").read_bytes() != (again / "clips/train-0000/8.jpg").read_bytes()


def test_traffic_factors_hide_more_lane_points_and_only_moving_traffic_is_revealed():
    cfg = SynthConfig(width=160, height=96, num_frames=6)

    def stats(config):
        return [clip_statistics(generate_clip(config, np.random.default_rng([7, i]))) for i in range(6)]

    def fraction(found, num, den):
        return sum(s[num] for s in found) / max(sum(s[den] for s in found), 1)

    normal = stats(cfg)
    standing = stats(SynthConfig.with_factor("traffic_standing", width=160, height=96, num_frames=6))
    oncoming = stats(SynthConfig.with_factor("traffic_oncoming", width=160, height=96, num_frames=6))
    assert fraction(standing, "hidden", "key_points") > fraction(normal, "hidden", "key_points")
    # a standing vehicle hides the same road in every frame; one driving towards the camera uncovers it
    assert fraction(oncoming, "revealed", "hidden") > fraction(standing, "revealed", "hidden")


def test_every_factor_is_a_labelled_split_of_the_challenging_clips(tmp_path: Path):
    from tests.conftest import TINY_SYNTH as TINY

    root = tmp_path / "set"
    info = generate_dataset(root, SplitCounts(challenging=len(FACTORS) + 1), seed=1, config=TINY, progress=False)
    names = list(FACTORS)
    assert info["clip_factors"] == {f"challenging-{i:04d}": names[i % len(names)] for i in range(len(names) + 1)}
    every = [json.loads(line)["raw_file"] for line in (root / "challenging.json").read_text().splitlines()]
    parts = []
    for name in names:
        files = [json.loads(line)["raw_file"] for line in (root / f"challenging-{name}.json").read_text().splitlines()]
        assert files and all(info["clip_factors"][f.split("/")[1]] == name for f in files)
        parts += files
    assert sorted(parts) == sorted(every)
    assert info["factors"]["night"]["overrides"] == {"night": True}


def test_windscreen_dirt_stays_on_the_same_pixels_and_the_wiper_moves():
    rng = np.random.default_rng(3)
    screen = Windscreen.sample(rng, 160, 96)
    masks = [screen.apply(np.full((96, 160, 3), 128, np.uint8), i) for i in range(8)]
    common = np.logical_and.reduce([m > 0 for m in masks])
    assert common.sum() > 20  # the dirt hides the same pixels in every frame
    assert any((masks[0] != m).any() for m in masks[1:])  # the wiper does not
    with pytest.raises(ValueError, match="windscreen made for"):
        screen.apply(np.zeros((10, 10, 3), np.uint8), 0)


def test_glare_and_night_change_the_frame_and_clean_clips_do_not_draw_for_them():
    base = SynthConfig(width=160, height=96, num_frames=4)
    clean = generate_clip(base, np.random.default_rng(5))
    for factor in ("glare", "night"):
        cfg = SynthConfig.with_factor(factor, width=160, height=96, num_frames=4)
        clip = generate_clip(cfg, np.random.default_rng(5))
        assert clip.labels == clean.labels  # the same road and drive: the effect is on the image only
        diff = [float(np.abs(a.astype(int) - b.astype(int)).mean()) for a, b in zip(clip.frames, clean.frames)]
        assert max(diff) > 10, (factor, diff)
    dark = generate_clip(SynthConfig.with_factor("night", width=160, height=96, num_frames=4), np.random.default_rng(5))
    assert np.mean(dark.frames[-1]) < 0.6 * np.mean(clean.frames[-1])
    with pytest.raises(ValueError, match="factor must be one of"):
        SynthConfig.with_factor("fog")


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="frame size"):
        SynthConfig(width=10, height=10)
    with pytest.raises(ValueError, match="num_frames"):
        SynthConfig(num_frames=0)
    with pytest.raises(ValueError, match="clip count"):
        generate_dataset("/tmp/never", SplitCounts(train=-1), progress=False)
