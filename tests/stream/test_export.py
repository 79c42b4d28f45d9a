"""ONNX export: encoder, fusion + decoder (with the in-graph feature warp) and clip model match PyTorch."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
import torch

from stamlane.models import STAM, LaneDecoder, LaneNet, VGGEncoder
from stamlane.models.feature_warp import feature_homography, sampling_grid
from stamlane.stream.export import export_all, export_encoder, export_fuse_decode, identity_grid
from stamlane.stream.predictor import fuse_feature_aligned

torch.set_num_threads(1)
pytest.importorskip("onnx", reason="onnx is not installed")
pytest.importorskip("onnxruntime", reason="onnxruntime is not installed (pip install onnxruntime)")

from stamlane.stream.onnx_runner import OnnxLaneNet  # noqa: E402

H, W, T = 64, 128, 3
TOL = 1e-4


@pytest.fixture(scope="module")
def net() -> LaneNet:
    torch.manual_seed(0)
    return LaneNet(VGGEncoder(0.125), functools.partial(STAM, reduction=4), LaneDecoder).eval()


@pytest.fixture(scope="module")
def exported(net: LaneNet, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("onnx")
    paths = export_all(net, folder, T, (H, W))
    assert set(paths) == {"encoder", "fuse_decode", "clip"} and all(p.is_file() for p in paths.values())
    return folder


@pytest.fixture(scope="module")
def runner(exported: Path) -> OnnxLaneNet:
    return OnnxLaneNet(exported, threads=1)


def _max_diff(a: np.ndarray, b: torch.Tensor) -> float:
    assert a.shape == tuple(b.shape)
    return float(np.abs(a - b.numpy()).max())


def test_opset_is_at_least_17(exported: Path) -> None:
    import onnx

    paths = sorted(exported.glob("*.onnx"))
    assert [p.name for p in paths] == ["clip.onnx", "encoder.onnx", "fuse_decode.onnx"]
    for path in paths:
        model = onnx.load(str(path))
        assert max(o.version for o in model.opset_import if o.domain in ("", "ai.onnx")) >= 17


def test_encoder_matches_pytorch_for_any_batch(net: LaneNet, runner: OnnxLaneNet) -> None:
    frames = torch.rand(3, 3, H, W)
    with torch.no_grad():
        expected = net.encode(frames)
    got = runner.encode(frames.numpy())
    assert len(got) == len(expected) == runner.num_stages
    for a, b in zip(got, expected, strict=True):
        assert _max_diff(a, b) < TOL


def test_fuse_decode_with_warp_matches_pytorch(net: LaneNet, runner: OnnxLaneNet) -> None:
    frames = torch.rand(2 * T, 3, H, W)
    with torch.no_grad():
        feats = net.encode(frames)
    per_clip = [f.unflatten(0, (2, T)) for f in feats]
    history = per_clip[-1][:, :-1]  # (2, T-1, C, h, w)
    key_stages = [f[:, -1] for f in per_clip]
    # a different homography per history frame and clip: translations and a mild perspective
    mats = np.stack(
        [
            [[[1, 0, 16.0], [0, 1, 0], [0, 0, 1]], [[1.02, 0.01, -5.0], [0, 1.03, 4.0], [0, 1e-4, 1]]],
            [np.eye(3), [[0.98, 0, 3.0], [0, 0.97, -8.0], [0, -2e-4, 1]]],
        ]
    )
    grid = sampling_grid(feature_homography(mats.reshape(-1, 3, 3), 16), tuple(history.shape[-2:]))
    grid = grid.float().reshape(2, T - 1, *history.shape[-2:], 2)
    with torch.no_grad():
        expected = fuse_feature_aligned(net, key_stages, history, mats, 16)
    got = runner.fuse_decode([k.numpy() for k in key_stages], history.numpy(), grid.numpy())
    for a, b in zip(got, expected, strict=True):
        assert _max_diff(a, b) < TOL
    # the identity grid gives the unaligned clip model
    with torch.no_grad():
        unaligned = net(frames.unflatten(0, (2, T)))
    same = runner.fuse_decode([k.numpy() for k in key_stages], history.numpy(), identity_grid(2, T - 1, (4, 8)).numpy())
    for a, b in zip(same, unaligned, strict=True):
        assert _max_diff(a, b) < TOL
    with pytest.raises(ValueError, match="history and grid"):
        runner.fuse_decode([k.numpy() for k in key_stages])


def test_clip_model_matches_pytorch(net: LaneNet, runner: OnnxLaneNet) -> None:
    clip = torch.rand(1, T, 3, H, W)
    with torch.no_grad():
        expected = net(clip)
    for a, b in zip(runner.clip(clip.numpy()), expected, strict=True):
        assert _max_diff(a, b) < TOL


def test_single_frame_fuse_decode_has_no_history_inputs(net: LaneNet, tmp_path: Path) -> None:
    export_encoder(net, tmp_path / "encoder.onnx", (32, 64))
    export_fuse_decode(net, tmp_path / "fuse_decode.onnx", 1, (32, 64))
    runner = OnnxLaneNet(tmp_path, threads=1)
    assert not runner.takes_history and runner.clip_session is None
    frame = torch.rand(1, 3, 32, 64)
    with torch.no_grad():
        expected = net(frame[:, None])
    got = runner.fuse_decode(runner.encode(frame.numpy()))
    for a, b in zip(got, expected, strict=True):
        assert _max_diff(a, b) < TOL
    with pytest.raises(FileNotFoundError, match=r"clip\.onnx"):
        runner.clip(frame[:, None].numpy())


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda net, p: export_encoder(net, p / "e.onnx", (40, 64)), "multiples of 16"),
        (lambda net, p: export_fuse_decode(net, p / "f.onnx", 3, (32, 64), opset=15), "opset"),
        (lambda net, p: export_fuse_decode(net, p / "f.onnx", 0, (32, 64)), "num_frames"),
    ],
)
def test_bad_arguments_raise(net: LaneNet, tmp_path: Path, call, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        call(net, tmp_path)


def test_missing_graph_is_reported(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"encoder\.onnx"):
        OnnxLaneNet(tmp_path)


def test_export_leaves_the_network_untouched(tmp_path: Path) -> None:
    torch.manual_seed(0)
    model = LaneNet(VGGEncoder(0.125), functools.partial(STAM, reduction=4), LaneDecoder).eval()
    before = {k: v.clone() for k, v in model.state_dict().items()}
    export_encoder(model, tmp_path / "encoder.onnx", (32, 64))
    export_fuse_decode(model, tmp_path / "fuse_decode.onnx", 2, (32, 64))
    assert not any(m.training for m in model.modules())
    assert all(torch.equal(v, before[k]) for k, v in model.state_dict().items())
    model.train()
    export_encoder(model, tmp_path / "encoder.onnx", (32, 64))
    assert all(m.training for m in model.modules())
