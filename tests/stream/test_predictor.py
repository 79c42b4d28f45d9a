"""StreamingPredictor: equals the clip model without alignment, warps cached features, runs on BGR frames."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import torch

from stamlane.align import align_clip
from stamlane.align.egomotion import RoadCamera, image_from_ground
from stamlane.align.synthetic import render_road, road_texture
from stamlane.models import STAM, LaneDecoder, LaneNet, VGGEncoder
from stamlane.stream import StreamingPredictor, fuse_feature_aligned

torch.set_num_threads(1)

H, W = 64, 128  # a 4x8 grid at stride 16
T = 4


@pytest.fixture(scope="module")
def net() -> LaneNet:
    torch.manual_seed(0)
    model = LaneNet(VGGEncoder(0.125), functools.partial(STAM, reduction=4), LaneDecoder).eval()
    # non-trivial batch-norm statistics, so eval mode differs from train mode
    with torch.no_grad():
        for m in model.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.uniform_(-0.2, 0.2)
                m.running_var.uniform_(0.5, 2.0)
    return model


@pytest.fixture(scope="module")
def frames() -> torch.Tensor:
    torch.manual_seed(1)
    return torch.rand(6, 3, H, W)


def _clip_of(frames: torch.Tensor, k: int, num_frames: int) -> torch.Tensor:
    """The clip `stamlane predict` builds with key frame k: predecessors, the earliest repeated at the start."""
    idx = [max(k - back, 0) for back in range(num_frames - 1, -1, -1)]
    return frames[idx][None]


@pytest.mark.parametrize("num_frames", [1, 2, T])
def test_unaligned_stream_equals_clip_model(net: LaneNet, frames: torch.Tensor, num_frames: int) -> None:
    predictor = StreamingPredictor(net, num_frames, (H, W), align=False)
    for k in range(len(frames)):
        logits, embedding = predictor.step(frames[k])
        with torch.no_grad():
            ref_logits, ref_embedding = net(_clip_of(frames, k, num_frames))
        torch.testing.assert_close(logits, ref_logits, atol=1e-5, rtol=1e-5)
        torch.testing.assert_close(embedding, ref_embedding, atol=1e-5, rtol=1e-5)
        assert predictor.history_size == (min(k + 1, num_frames - 1) if num_frames > 1 else 0)


def test_identity_alignment_equals_clip_model(net: LaneNet, frames: torch.Tensor) -> None:
    predictor = StreamingPredictor(net, T, (H, W))
    for k in range(len(frames)):
        eye = np.repeat(np.eye(3)[None], predictor.history_size, axis=0)
        logits, _ = predictor.step(frames[k], eye)
        with torch.no_grad():
            ref_logits, _ = net(_clip_of(frames, k, T))
        torch.testing.assert_close(logits, ref_logits, atol=1e-5, rtol=1e-5)


def test_near_identity_goes_through_grid_sample_and_still_matches(net: LaneNet, frames: torch.Tensor) -> None:
    with torch.no_grad():
        feats = net.encode(frames[:T])
        ref_logits, ref_embedding = net(frames[:T][None])
    hist = feats[-1][: T - 1][None]
    key = [f[T - 1 :] for f in feats]
    near = np.repeat((np.eye(3) + np.diag([0, 0, 1e-12]))[None, None], T - 1, axis=1)  # not exactly I: warped
    with torch.no_grad():
        logits, embedding = fuse_feature_aligned(net, key, hist, near, 16)
    torch.testing.assert_close(logits, ref_logits, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(embedding, ref_embedding, atol=1e-5, rtol=1e-5)


def test_cached_features_are_warped_by_their_homographies(net: LaneNet, frames: torch.Tensor) -> None:
    """Translations by whole cells: the fusion must see the cached features shifted by those cells."""
    seen: list[torch.Tensor] = []
    hook = net.fusion.register_forward_hook(lambda module, args, out: seen.append(args[0].clone()))
    try:
        predictor = StreamingPredictor(net, T, (H, W))
        for k in range(T - 1):
            predictor.step(frames[k])
        shifts = [(1, 0), (0, 1), (-2, 0)]  # cells, per cached frame (oldest first)
        mats = np.stack([np.array([[1, 0, 16.0 * dx], [0, 1, 16.0 * dy], [0, 0, 1]]) for dx, dy in shifts])
        logits, embedding = predictor.step(frames[T - 1], mats)
    finally:
        hook.remove()
    with torch.no_grad():
        feats = net.encode(frames[:T])
    gh, gw = H // 16, W // 16
    expected = feats[-1].clone()
    for t, (dx, dy) in enumerate(shifts):
        out = torch.zeros_like(feats[-1][t])
        out[:, max(dy, 0) : gh + min(dy, 0), max(dx, 0) : gw + min(dx, 0)] = feats[-1][t][
            :, max(-dy, 0) : gh - max(dy, 0), max(-dx, 0) : gw - max(dx, 0)
        ]
        expected[t] = out
    fused_input = seen[-1]
    assert fused_input.shape == (1, T, *feats[-1].shape[1:])
    torch.testing.assert_close(fused_input[0], expected, atol=1e-5, rtol=1e-5)
    assert (fused_input[0] - feats[-1]).abs().max() > 0.1  # the warp changed what the fusion sees
    with torch.no_grad():
        ref_logits, ref_embedding = net.fuse_and_decode(expected[None], [f[T - 1 :] for f in feats[:-1]])
    torch.testing.assert_close(logits, ref_logits, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(embedding, ref_embedding, atol=1e-5, rtol=1e-5)


def _corner_error(estimate: np.ndarray, truth: np.ndarray, shape: tuple[int, int], row: int) -> float:
    """Mean distance (key pixels) of the key frame's ground corners sent to the history frame and back."""
    corners = np.array([[0, row, 1], [shape[1] - 1, row, 1], [shape[1] - 1, shape[0] - 1, 1], [0, shape[0] - 1, 1.0]])
    back = corners @ np.linalg.inv(truth).T @ np.asarray(estimate).T
    return float(np.linalg.norm(back[:, :2] / back[:, 2:] - corners[:, :2], axis=1).mean())


def test_bgr_frames_with_alignment_give_lanes_and_true_homographies(net: LaneNet) -> None:
    camera = RoadCamera(width=640, height=360, focal=500.0, horizon_row=140.0, camera_height=1.5)
    row = 160
    texture = road_texture(seed=3)
    poses = [(1.0 * i, 0.004 * i) for i in range(5)]  # (forward metres, yaw radians)
    images = [render_road(texture, camera, forward=z, yaw=yaw) for z, yaw in poses]
    predictor = StreamingPredictor(net, 3, (H, W), horizon_row=row)
    outputs = [predictor(image) for image in images]
    assert [o.index for o in outputs] == list(range(5))
    for out in outputs:
        assert out.logits.shape == (1, 2, H, W) and out.embedding.shape == (1, 4, H, W)
        assert isinstance(out.lanes, list)
        assert len(out.alignments) == 2
        assert set(out.timings) == {"preprocess", "align", "network", "decode"}
    np.testing.assert_allclose(outputs[0].net_from_orig[0, 0], W / 640)
    # frame 4's history slots are frames 2 and 3: the chain equals stamlane.align's clip alignment ...
    _, reference = align_clip(images[2:5], horizon_row=row, strategy="chain")
    last = outputs[-1]
    for got, ref in zip(last.alignments, reference[:2], strict=True):
        assert got.ok and ref.ok, (got.reason, ref.reason)
        np.testing.assert_allclose(got.key_from_hist, ref.key_from_hist, atol=1e-9)
    # ... and the true ground motion
    key = image_from_ground(camera, poses[4][1], 0.0, poses[4][0])
    for slot, hist_index in enumerate((2, 3)):
        z, yaw = poses[hist_index]
        truth = key @ np.linalg.inv(image_from_ground(camera, yaw, 0.0, z))
        error = _corner_error(last.alignments[slot].key_from_hist, truth / truth[2, 2], (360, 640), row)
        assert error < 2.0, (hist_index, error)
    # warm-up: frame 1 repeats frame 0 in its first history slot
    assert outputs[1].alignments[0] is outputs[1].alignments[1]
    predictor.reset()
    assert predictor.history_size == 0
    predictor(images[0])
    with pytest.raises(ValueError, match="size changed"):
        predictor(images[0][:-16])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"num_frames": 0}, "num_frames"),
        ({"image_size": (60, 128)}, "image_size"),
    ],
)
def test_bad_arguments_raise(net: LaneNet, kwargs: dict, match: str) -> None:
    options = {"num_frames": T, "image_size": (H, W)} | kwargs
    with pytest.raises(ValueError, match=match):
        StreamingPredictor(net, **options)


def test_bad_step_inputs_raise(net: LaneNet, frames: torch.Tensor) -> None:
    predictor = StreamingPredictor(net, T, (H, W))
    with pytest.raises(ValueError, match="expected a frame"):
        predictor.step(frames[0, :, :32])
    predictor.step(frames[0])
    with pytest.raises(ValueError, match=r"\(1, 3, 3\)"):
        predictor.step(frames[1], np.eye(3)[None].repeat(2, axis=0))
    with pytest.raises(ValueError, match="uint8"):
        predictor(np.zeros((100, 100, 3), np.float32))


def test_frames_given_to_step_are_used_unaligned_by_call(net: LaneNet, frames: torch.Tensor) -> None:
    predictor = StreamingPredictor(net, 2, (H, W))
    predictor.step(frames[0])
    image = (np.random.default_rng(0).random((128, 256, 3)) * 255).astype(np.uint8)
    out = predictor(image)
    assert len(out.alignments) == 1 and not out.alignments[0].ok
    assert "no image kept" in out.alignments[0].reason
    np.testing.assert_array_equal(out.alignments[0].key_from_hist, np.eye(3))


def test_run_gives_the_outputs_of_frame_after_frame_calls() -> None:
    """`StreamingPredictor.run` (reading, features and lane decoding beside the network) gives what calling the
    predictor frame after frame gives, bit for bit, with the shipped 4-frame model on a rendered drive."""
    from stamlane.training.module import StamLaneModule
    from stamlane.weights import shipped_path

    module = StamLaneModule.from_checkpoint(shipped_path("stam4-synthetic"))
    camera = RoadCamera(width=640, height=360, focal=500.0, horizon_row=140.0, camera_height=1.5)
    texture = road_texture(seed=3)
    images = [render_road(texture, camera, forward=1.0 * i, yaw=0.004 * i) for i in range(7)]
    serial = StreamingPredictor.from_module(module, horizon_row=160)
    expected = [serial(image) for image in images]
    piped = StreamingPredictor.from_module(module, horizon_row=160)
    got = list(piped.run(iter(images)))
    assert [o.index for o in got] == list(range(len(images)))
    for a, b in zip(got, expected, strict=True):
        assert torch.equal(a.logits, b.logits) and torch.equal(a.embedding, b.embedding)
        assert len(a.lanes) == len(b.lanes) and all(np.array_equal(x, y) for x, y in zip(a.lanes, b.lanes))
        assert [al.key_from_hist.tolist() for al in a.alignments] == [al.key_from_hist.tolist() for al in b.alignments]
        assert set(a.timings) == {"preprocess", "align", "network", "decode"}
    assert all(al.ok for al in got[4].alignments) and not got[5].alignments[0].ok  # the chain, and its breaking
    assert sum(len(o.lanes) for o in got) > 0
    assert list(piped.run([])) == []
    with pytest.raises(ValueError, match="size changed"):
        list(piped.run([images[0], images[0][:-16]]))
