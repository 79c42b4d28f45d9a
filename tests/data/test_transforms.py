"""Clip-consistent augmentation, flips that mirror lane order, and the lane round trip."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stamlane.data import ClipTransform, draw_lane_targets, left_to_right


def textured(h: int = 90, w: int = 160, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return cv2.GaussianBlur(rng.integers(0, 256, (h, w, 3), dtype=np.uint8), (5, 5), 0)


def test_one_draw_applies_to_every_frame_alike():
    t = ClipTransform(
        (48, 80), crop_scale=(0.6, 0.9), flip_prob=0.5, brightness=0.3, contrast=0.3, saturation=0.3, hue=0.05
    )
    assert t.augments
    frame = textured()
    eye = np.repeat(np.eye(3)[None], 4, axis=0)
    rng = np.random.default_rng(1)
    seen_flip = set()
    for _ in range(8):
        p = t.draw((90, 160), rng)
        seen_flip.add(p.flip)
        out = t.apply_frames([frame] * 4, eye, p)
        assert out.shape == (4, 3, 48, 80)
        for k in range(1, 4):  # identical input frames -> identical outputs: one crop/flip/jitter per clip
            np.testing.assert_array_equal(out[k], out[0])
    assert seen_flip == {True, False}
    plain = ClipTransform((48, 80)).apply_frames([frame], eye[:1], ClipTransform((48, 80)).draw((90, 160)))
    assert not np.allclose(out[0], plain[0])  # the augmentation did change something


def test_targets_follow_the_frames_through_crop_and_flip():
    """Lanes drawn into the image land on the target lanes after any augmentation draw."""
    h, w = 90, 160
    lanes = [np.array([[30.0, 89], [70, 30]]), np.array([[130.0, 89], [95, 30]])]
    img = np.zeros((h, w, 3), np.uint8)
    for lane in lanes:
        cv2.polylines(img, [lane.astype(np.int32)], False, (255, 255, 255), 3)
    t = ClipTransform((45, 80), crop_scale=(0.7, 1.0), flip_prob=0.5)
    rng = np.random.default_rng(0)
    for _ in range(6):
        p = t.draw((h, w), rng)
        frames = t.apply_frames([img, img], np.repeat(np.eye(3)[None], 2, 0), p)
        binary, _ = draw_lane_targets(ClipTransform.map_lanes(lanes, p.net_from_orig), (45, 80), thickness=1)
        bright = frames[-1].mean(axis=0) > 0.3
        on = binary.astype(bool)
        assert on.sum() > 10
        assert (bright & on).sum() / on.sum() > 0.8


def test_flip_mirrors_lane_order():
    lanes = [np.array([[20.0, 89], [60, 30]]), np.array([[140.0, 89], [100, 30]])]  # left, right
    t = ClipTransform((45, 80), flip_prob=1.0)
    p = t.draw((90, 160), np.random.default_rng(0))
    assert p.flip
    _, inst = draw_lane_targets(ClipTransform.map_lanes(lanes, p.net_from_orig), (45, 80), thickness=1)
    ys, xs = np.nonzero(inst == 1)
    # after the flip, lane id 1 (leftmost) is the originally RIGHT lane, which ended at x = 140 -> 80 - 1 - 70
    assert xs[ys.argmax()] < 40
    assert left_to_right(ClipTransform.map_lanes(lanes, p.net_from_orig)) == [1, 0]
    assert left_to_right(lanes) == [0, 1]


def test_lanes_round_trip_through_net_from_orig_without_drift():
    rng = np.random.default_rng(3)
    t = ClipTransform((128, 256), crop_scale=(0.5, 1.0), flip_prob=0.5)
    for _ in range(20):
        lanes = [rng.uniform([0, 0], [1280, 720], (12, 2))]
        p = t.draw((720, 1280), rng)
        net = ClipTransform.map_lanes(lanes, p.net_from_orig)
        back = ClipTransform.map_lanes(net, np.linalg.inv(p.net_from_orig))
        assert np.abs(back[0] - lanes[0]).max() < 0.5


@pytest.mark.parametrize("flip", [False, True])
def test_points_and_pixels_share_one_convention(flip: bool):
    """A 1-px vertical line at x in the original lands where net_from_orig maps x (within 0.5 net px)."""
    h, w = 72, 320
    t = ClipTransform((36, 80), flip_prob=1.0 if flip else 0.0)
    p = t.draw((h, w), np.random.default_rng(0))
    for x in (40, 161, 250):
        img = np.zeros((h, w, 3), np.uint8)
        img[:, x - 2 : x + 2] = 255  # 4 px wide, centred at x - 0.5
        out = t.apply_frames([img], np.eye(3)[None], p)[0, 0]
        profile = out.mean(axis=0)
        centre = float((profile * np.arange(80)).sum() / profile.sum())
        expected = (p.net_from_orig @ np.array([x - 0.5, 36, 1.0]))[0]
        assert abs(centre - expected) < 0.5


def test_history_frames_are_warped_by_key_from_hist():
    key = textured(90, 160, seed=2)
    shift = np.array([[1.0, 0, 6], [0, 1, 0], [0, 0, 1]])  # key_from_hist: history content moves 6 px right
    hist = cv2.warpAffine(key, np.linalg.inv(shift)[:2], (160, 90))
    t = ClipTransform((90, 160))
    p = t.draw((90, 160))
    out = t.apply_frames([hist, key], np.stack([shift, np.eye(3)]), p)
    diff = np.abs(out[0] - out[1])[:, :, 10:-10].mean()
    raw = np.abs(t.apply_frames([hist, key], np.repeat(np.eye(3)[None], 2, 0), p)[0] - out[1])[:, :, 10:-10].mean()
    assert diff < 0.2 * raw


def test_targets_ids_thickness_and_short_lanes():
    lanes = [np.array([[50.0, 40], [55, 0]]), np.array([[10.0, 40], [10, 0]]), np.array([[30.0, 20]])]
    with pytest.warns(UserWarning, match="lane 2 has 1 point"):
        binary, inst = draw_lane_targets(lanes, (41, 64), thickness=3, source="x.json")
    assert set(np.unique(inst)) == {0, 1, 2}
    assert inst[40, 10] == 1 and inst[40, 50] == 2  # ids left to right
    assert (inst[20] == 1).sum() == 3  # 3 px thick
    thin, _ = draw_lane_targets(lanes[:2], (41, 64), thickness=1)
    assert thin.sum() < binary.sum()
    with pytest.raises(ValueError, match="thickness"):
        draw_lane_targets(lanes, (41, 64), thickness=0)


def test_transform_rejects_bad_options():
    for kwargs, match in [
        ({"crop_scale": (0.0, 1.0)}, "crop_scale"),
        ({"flip_prob": 2.0}, "flip_prob"),
        ({"brightness": 1.5}, "brightness"),
        ({"hue": 0.7}, "hue"),
        ({"crop_top": 0.95}, "crop_top"),
        ({"crop_top": -0.1}, "crop_top"),
    ]:
        with pytest.raises(ValueError, match=match):
            ClipTransform((32, 32), **kwargs)
    with pytest.raises(ValueError, match="image_size"):
        ClipTransform((4, 32))


@pytest.mark.parametrize("crop_scale", [(1.0, 1.0), (0.7, 0.9)])
def test_crop_top_cuts_the_sky_before_any_other_crop(crop_scale: tuple[float, float]) -> None:
    """Rows above ``crop_top * H0`` never reach the network; the rest maps through ``net_from_orig``."""
    h, w = 90, 160
    frame = np.full((h, w, 3), 200, np.uint8)
    frame[:36] = 0  # "sky": the top 40 %
    t = ClipTransform((32, 64), crop_top=0.4, crop_scale=crop_scale)
    rng = np.random.default_rng(3)
    for _ in range(5):
        p = t.draw((h, w), rng)
        out = t.apply_frames([frame], np.eye(3)[None], p)[0]
        assert out.min() > 0.5, "a sky pixel reached the network input"
        top_net = p.net_from_orig @ np.array([0.0, 36.0 - 0.5, 1.0])  # the top edge of row 36
        assert top_net[1] <= -0.5 + 1e-9
    full = ClipTransform((32, 64), crop_top=0.4).draw((h, w))
    # no random crop: the kept band [36, 90) fills the network rows exactly (pixel edges -0.5 .. 31.5)
    edges = full.net_from_orig @ np.array([[0, 35.5, 1], [0, 89.5, 1]]).T
    np.testing.assert_allclose(edges[1], [-0.5, 31.5])


def test_a_training_frame_takes_as_many_lanes_as_its_8_bit_ids() -> None:
    """255 lanes get 255 ids; a 256th would share one (uint8 instance mask): refused, naming the label file."""
    import pytest

    from stamlane.data.labels import DataError
    from stamlane.data.targets import MAX_TRAINING_LANES

    def lanes(n: int) -> list[np.ndarray]:
        return [np.array([[x + 0.5, 0.0], [x + 0.5, 9.0]]) for x in range(n)]

    _, inst = draw_lane_targets(lanes(MAX_TRAINING_LANES), (10, 300), thickness=1)
    assert inst.max() == MAX_TRAINING_LANES == len(np.unique(inst)) - 1
    with pytest.raises(DataError, match=r"train\.json: 256 lanes in one frame; at most 255"):
        draw_lane_targets(lanes(MAX_TRAINING_LANES + 1), (10, 300), thickness=1, source="train.json")
