"""warp_to_key, chain_alignments, align_clip."""

from __future__ import annotations

import numpy as np
import pytest

from stamlane.align import Alignment, align_clip, chain_alignments, estimate_clip, warp_to_key
from stamlane.align.egomotion import key_from_hist_motion
from stamlane.align.synthetic import render_road

from .conftest import SMALL_CAMERA, SMALL_HORIZON, corner_error

SHAPE = (SMALL_CAMERA.height, SMALL_CAMERA.width)


def test_warp_to_key_translation_and_padding():
    image = np.zeros((50, 80, 3), np.uint8)
    image[10, 20] = 255
    shift = np.array([[1.0, 0, 5], [0, 1, 3], [0, 0, 1]])
    out = warp_to_key(image, shift, size=(60, 100))
    assert out.shape == (60, 100, 3) and out.dtype == np.uint8
    assert out[13, 25].tolist() == [255, 255, 255]
    assert out[:, 85:].max() == 0  # padded beyond the source
    np.testing.assert_array_equal(warp_to_key(image, np.eye(3)), image)
    gray = warp_to_key(image[..., 0], shift, border_value=7)
    assert gray.shape == (50, 80) and gray[0, 0] == 7


@pytest.mark.parametrize(
    ("image", "matrix", "message"),
    [
        (np.zeros((4,), np.uint8), np.eye(3), r"\(4,\)"),
        (np.zeros((4, 4), np.uint8), np.eye(2), "1., 0."),
        (np.zeros((4, 4), np.uint8), np.full((3, 3), np.inf), "inf"),
    ],
)
def test_warp_to_key_rejects_bad_input(image, matrix, message):
    with pytest.raises(ValueError, match=message):
        warp_to_key(image, matrix)


def test_chain_alignments_multiplies_and_propagates_failures():
    a = Alignment(np.array([[1.0, 0, 2], [0, 1, 0], [0, 0, 1]]), 10, 8, True, "")
    b = Alignment(np.array([[1.0, 0, 0], [0, 1, 3], [0, 0, 1]]), 11, 9, True, "")
    chained = chain_alignments([a, b], SHAPE, SMALL_HORIZON)
    np.testing.assert_allclose(chained[0].key_from_hist, b.key_from_hist @ a.key_from_hist)
    np.testing.assert_allclose(chained[1].key_from_hist, b.key_from_hist)
    failed = chain_alignments([a, Alignment.failed("too few matches: 3 < 15")], SHAPE, SMALL_HORIZON)
    assert not failed[0].ok and not failed[1].ok and "too few matches" in failed[0].reason


def _clip(texture, color=True, step=1.0):
    frames = [render_road(texture, SMALL_CAMERA, forward=step * i, yaw=0.004 * i, color=color) for i in range(3)]
    truths = [key_from_hist_motion(SMALL_CAMERA, step * (2 - i), 0.004 * (2 - i), hist_yaw=0.004 * i) for i in range(3)]
    return frames, truths


@pytest.mark.parametrize("strategy", ["direct", "chain"])
def test_align_clip_order_shape_and_accuracy(texture, strategy):
    frames, truths = _clip(texture)
    aligned, alignments = align_clip(frames, horizon_row=SMALL_HORIZON, strategy=strategy)
    assert aligned.shape == (3, *SHAPE, 3) and aligned.dtype == np.uint8
    assert len(alignments) == 3
    key = alignments[-1]
    assert key.ok and key.reason == "" and np.array_equal(key.key_from_hist, np.eye(3))
    np.testing.assert_array_equal(aligned[-1], frames[-1])  # key frame last and untouched
    for alignment, truth in zip(alignments[:-1], truths[:-1], strict=True):
        assert alignment.ok, alignment.reason
        assert corner_error(alignment.key_from_hist, truth, SHAPE, SMALL_HORIZON) < 2.0
    # the warped oldest frame looks like the key frame on the road, the raw one does not
    road = slice(SMALL_HORIZON + 20, SHAPE[0] - 40)
    before = np.abs(frames[0][road].astype(int) - frames[-1][road]).mean()
    after = np.abs(aligned[0][road].astype(int) - frames[-1][road]).mean()
    assert after < 0.5 * before


def test_align_clip_accepts_a_grey_array_and_keeps_failed_frames(texture):
    frames, _ = _clip(texture, color=False)
    frames[0] = np.zeros_like(frames[0])  # black: cannot be matched, so it moves as the pair that matched
    aligned, alignments = align_clip(np.stack(frames), horizon_row=SMALL_HORIZON)
    assert aligned.shape == (3, *SHAPE)
    assert alignments[0].ok and alignments[0].extrapolated and alignments[1].ok and not alignments[1].extrapolated
    frames[1] = np.zeros_like(frames[1])  # no pair matches: nothing to move them with
    aligned, alignments = align_clip(np.stack(frames), horizon_row=SMALL_HORIZON)
    assert not alignments[0].ok and "too few features" in alignments[0].reason and not alignments[1].ok
    np.testing.assert_array_equal(aligned[0], frames[0])  # left as it was


def test_align_clip_single_frame_is_the_key(texture):
    frame = render_road(texture, SMALL_CAMERA)
    aligned, alignments = align_clip([frame])
    assert aligned.shape == (1, *frame.shape) and alignments[0].ok


@pytest.mark.parametrize(
    ("frames", "kwargs", "message"),
    [
        ([], {}, r"\[\]"),
        ([np.zeros((100, 100, 3), np.uint8), np.zeros((100, 90, 3), np.uint8)], {}, r"\(100, 90, 3\)"),
        (np.zeros((100, 100), np.uint8), {}, r"\(100, 100\)"),
        ([np.zeros((100, 100, 3), np.float64)], {}, "float64"),
        ([np.zeros((100, 100, 3), np.uint8)], {"strategy": "best"}, "best"),
    ],
)
def test_align_clip_rejects_bad_input(frames, kwargs, message):
    with pytest.raises(ValueError, match=message):
        align_clip(frames, **kwargs)


def test_estimate_clip_returns_the_alignments_of_align_clip(texture):
    frames, _ = _clip(texture)
    alignments = estimate_clip(frames, horizon_row=SMALL_HORIZON)
    _, reference = align_clip(frames, horizon_row=SMALL_HORIZON)
    assert len(alignments) == 3 and alignments[-1].ok
    for a, b in zip(alignments, reference, strict=True):
        np.testing.assert_allclose(a.key_from_hist, b.key_from_hist)
    with pytest.raises(ValueError, match="best"):
        estimate_clip(frames, strategy="best")


def test_chain_link_multiplies_checks_and_reports_the_counts_asked_for():
    from stamlane.align.warp import chain_link

    a = Alignment(np.array([[1.0, 0, 3.0], [0, 1, 0], [0, 0, 1]]), 40, 30, True, "")  # mid -> key: 3 px right
    b = Alignment(np.array([[1.0, 0, 2.0], [0, 1, 1.0], [0, 0, 1]]), 50, 45, True, "")  # hist -> mid
    linked = chain_link(a, b, (360, 640), 160)
    np.testing.assert_allclose(linked.key_from_hist, [[1, 0, 5], [0, 1, 1], [0, 0, 1]])
    assert linked.ok and (linked.num_matches, linked.num_inliers) == (50, 45)
    assert (chain_link(a, b, (360, 640), 160, counts=a).num_inliers) == 30
    wild = Alignment(np.array([[1.0, 0, 900.0], [0, 1, 0], [0, 0, 1]]), 40, 30, True, "")  # off the image
    failed = chain_link(wild, b, (360, 640), 160)
    assert not failed.ok and failed.reason


def test_a_failed_pair_moves_as_the_nearest_pair_that_matched():
    """Constant motion: in a 4-frame chain whose last pair failed (a washed-out key frame) every history frame
    takes the motion of the pair before it; without fill the chain stays broken; a clip with no matched pair
    stays failed."""
    from stamlane.align.warp import alignments_to_key

    motion = key_from_hist_motion(SMALL_CAMERA, forward=1.0)  # the same motion between every pair of frames

    def estimate(failed: set[tuple[int, int]]):
        def one(i: int, j: int) -> Alignment:
            if (i, j) in failed or j == 3:  # every pair with the key frame fails, direct ones too
                return Alignment.failed("washed out")
            return Alignment(np.linalg.matrix_power(motion, j - i), 50, 40, True, "")

        return one

    size = (SMALL_CAMERA.height, SMALL_CAMERA.width)
    found = alignments_to_key(4, estimate(set()), size, SMALL_HORIZON)
    assert all(a.ok and a.extrapolated for a in found)
    for back, a in zip((3, 2, 1), found):  # frames 0, 1, 2: 3, 2 and 1 pairs from the key frame
        want = np.linalg.matrix_power(motion, back)
        np.testing.assert_allclose(a.key_from_hist, want / want[2, 2], atol=1e-9)
    broken = alignments_to_key(4, estimate(set()), size, SMALL_HORIZON, fill=False)
    assert not any(a.ok for a in broken)
    nothing = alignments_to_key(4, estimate({(0, 1), (1, 2)}), size, SMALL_HORIZON)
    assert not any(a.ok for a in nothing) and not any(a.extrapolated for a in nothing)
