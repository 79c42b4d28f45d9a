"""Every fusion module (STAM in all modes, the Table 4 aggregators, the single-frame baseline) behind one
interface: (B, T, C, h, w) -> (B, C, h, w), key frame last."""

from __future__ import annotations

import itertools
from collections.abc import Callable

import pytest
import torch
from torch import nn

from stamlane.models import STDANet
from tests.benchmarks.scripts import load_script

C = 16

FUSIONS: dict[str, Callable[[int], nn.Module]] = load_script("model").FUSIONS
"""Every fusion by the name the model benchmark times it under (``benchmarks/model.py``, the one table of them): STAM
in each mode, order and reading, the Table 4 aggregators and the single-frame baseline."""


def _build(name: str, seed: int = 0) -> nn.Module:
    torch.manual_seed(seed)
    module = FUSIONS[name](C)
    if isinstance(module, STDANet):  # its scales start at 0 (output = K); make the attention visible
        with torch.no_grad():
            module.gamma_position.fill_(0.5)
            module.gamma_channel.fill_(0.5)
    return module.eval()


@pytest.mark.parametrize("name", list(FUSIONS))
def test_shapes_for_every_clip_length(name: str) -> None:
    module = _build(name)
    for num_frames in range(1, 6):
        feats = torch.randn(2, num_frames, C, 4, 6)
        with torch.no_grad():
            out = module(feats)
        assert out.shape == (2, C, 4, 6), (name, num_frames)
        assert torch.isfinite(out).all()


@pytest.mark.parametrize("name", list(FUSIONS))
def test_gradients_reach_every_parameter(name: str) -> None:
    module = _build(name).train()
    with torch.no_grad():  # no parameter at exactly zero, so no gradient is zero by construction
        for p in module.parameters():
            p.add_(0.05 * torch.randn_like(p))
    feats = torch.randn(2, 3, C, 4, 6, requires_grad=True)
    out = module(feats)
    (out**2).sum().backward()
    for param_name, p in module.named_parameters():
        assert p.grad is not None, f"{name}: {param_name} got no gradient"
        assert p.grad.abs().sum() > 0, f"{name}: {param_name} got a zero gradient"
    # every frame influences the output, except in the single-frame baseline
    frame_grad = feats.grad.abs().sum(dim=(0, 2, 3, 4))
    if name == "key_frame_only":
        assert (frame_grad[:-1] == 0).all() and frame_grad[-1] > 0
    else:
        assert (frame_grad > 0).all(), f"{name}: some frame does not reach the output"


def test_no_two_fusions_agree() -> None:
    torch.manual_seed(1)
    feats = torch.randn(2, 3, C, 4, 6)
    outputs = {}
    for name in FUSIONS:
        with torch.no_grad():
            outputs[name] = _build(name)(feats)
    for a, b in itertools.combinations(outputs, 2):
        assert not torch.allclose(outputs[a], outputs[b], atol=1e-4), f"{a} and {b} give the same output"


@pytest.mark.parametrize("name", list(FUSIONS))
def test_samples_do_not_influence_each_other(name: str) -> None:
    module = _build(name)
    torch.manual_seed(2)
    feats = torch.randn(3, 4, C, 4, 6)
    changed = feats.clone()
    changed[1:] = torch.randn_like(changed[1:])
    with torch.no_grad():
        full = module(feats)
        single = module(feats[:1])
        other = module(changed)
    torch.testing.assert_close(full[:1], single, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(other[0], full[0], atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("name", ["stam-mixed-cs-features", "convlstm", "stdanet", "stpsa"])
def test_deterministic_under_a_seed(name: str) -> None:
    torch.manual_seed(3)
    feats = torch.randn(2, 3, C, 4, 6)
    a, b = _build(name, seed=7), _build(name, seed=7)
    with torch.no_grad():
        torch.testing.assert_close(a(feats), b(feats), atol=0, rtol=0)


@pytest.mark.parametrize("name", list(FUSIONS))
def test_rejects_wrong_shapes(name: str) -> None:
    module = _build(name)
    with pytest.raises(ValueError, match=r"\(B, T, 16, h, w\)"):
        module(torch.randn(2, C, 4, 6))
    with pytest.raises(ValueError, match="got"):
        module(torch.randn(2, 3, C + 1, 4, 6))


@pytest.mark.filterwarnings(
    "ignore::DeprecationWarning"
)  # the TorchScript exporter; dynamo=True also works, 10x slower
@pytest.mark.parametrize("name", list(FUSIONS))
def test_exports_to_onnx(name: str, tmp_path) -> None:
    ort = pytest.importorskip("onnxruntime", reason="onnxruntime is not installed")
    pytest.importorskip("onnx", reason="onnx is not installed")
    module = _build(name)
    feats = torch.randn(1, 3, C, 4, 6)
    path = tmp_path / f"{name}.onnx"
    torch.onnx.export(module, (feats,), str(path), opset_version=17, dynamo=False, input_names=["feats"])
    with torch.no_grad():
        expected = module(feats).numpy()
    (got,) = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]).run(None, {"feats": feats.numpy()})
    assert abs(got - expected).max() < 1e-4
