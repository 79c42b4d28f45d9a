"""STAM against the formulas of docs/method.md §3, written out frame by frame."""

from __future__ import annotations

import pytest
import torch

from stamlane.models import STAM

C = 16


def _stam(**kwargs) -> STAM:
    torch.manual_seed(0)
    module = STAM(C, **kwargs).eval()
    with torch.no_grad():  # move the SA conv off its init so the maps are not near-constant
        module.spatial_attention.conv.weight.mul_(5.0)
    return module


@pytest.fixture
def clip() -> torch.Tensor:
    torch.manual_seed(1)
    return torch.randn(2, 3, C, 5, 7)


def _ca_sa(module: STAM):
    return module.channel_attention, module.spatial_attention


def test_literal_parallel(clip: torch.Tensor) -> None:
    module = _stam(mode="parallel", reading="gates")
    ca, sa = _ca_sa(module)
    h1, h2, k = clip.unbind(1)
    expected = sum(ca(s) * k + sa(s) * k for s in (k, h2, h1))
    torch.testing.assert_close(module(clip), expected)


@pytest.mark.parametrize("order", ["cs", "sc"])
def test_literal_serial(clip: torch.Tensor, order: str) -> None:
    module = _stam(mode="serial", order=order, reading="gates")
    ca, sa = _ca_sa(module)
    first, second = (ca, sa) if order == "cs" else (sa, ca)
    h1, h2, k = clip.unbind(1)
    acc = h1
    for g in (h2, k):
        y = first(acc) * g
        acc = second(y) * y
    torch.testing.assert_close(module(clip), acc)


@pytest.mark.parametrize("order", ["cs", "sc"])
def test_literal_mixed(clip: torch.Tensor, order: str) -> None:
    module = _stam(mode="mixed", order=order, reading="gates")
    ca, sa = _ca_sa(module)
    first, second = (ca, sa) if order == "cs" else (sa, ca)
    h1, h2, k = clip.unbind(1)
    expected = 0
    for s in (k, h2, h1):
        y = first(s) * k
        expected = expected + second(y) * y
    torch.testing.assert_close(module(clip), expected)


@pytest.mark.parametrize("mode", ["serial", "mixed"])
def test_literal_single_frame_is_cbam(clip: torch.Tensor, mode: str) -> None:
    module = _stam(mode=mode, order="cs", reading="gates")
    ca, sa = _ca_sa(module)
    k = clip[:, -1]
    y = ca(k) * k
    torch.testing.assert_close(module(clip[:, -1:]), sa(y) * y)


def test_features_mixed_cs_is_the_prototype_formula(clip: torch.Tensor) -> None:
    module = _stam()  # the default: mixed C-S, history features
    assert (module.mode, module.order, module.reading) == ("mixed", "cs", "features")
    ca, sa = _ca_sa(module)
    h1, h2, k = clip.unbind(1)
    expected = k
    for s in (h2, h1):
        y = ca(s) * s
        expected = expected + sa(y) * y
    torch.testing.assert_close(module(clip), expected)


def test_features_parallel_and_serial(clip: torch.Tensor) -> None:
    h1, h2, k = clip.unbind(1)
    parallel = _stam(mode="parallel", reading="features")
    ca, sa = _ca_sa(parallel)
    torch.testing.assert_close(parallel(clip), k + sum(ca(s) * s + sa(s) * s for s in (h2, h1)))

    serial = _stam(mode="serial", order="sc", reading="features")
    ca, sa = _ca_sa(serial)

    def att(a: torch.Tensor) -> torch.Tensor:
        y = sa(a) * a
        return ca(y) * y

    torch.testing.assert_close(serial(clip), k + att(h2 + att(h1)))


@pytest.mark.parametrize("mode", ["parallel", "serial", "mixed"])
def test_features_single_frame_is_identity(clip: torch.Tensor, mode: str) -> None:
    torch.testing.assert_close(_stam(mode=mode, reading="features")(clip[:, -1:]), clip[:, -1])


@pytest.mark.parametrize("reading", ["gates", "features"])
def test_normalize_divides_by_clip_length(clip: torch.Tensor, reading: str) -> None:
    plain, mean = _stam(reading=reading), _stam(reading=reading, normalize=True)
    torch.testing.assert_close(mean(clip), plain(clip) / 3)


def test_history_content_reaches_output_only_in_features_variant() -> None:
    """The caution of docs/method.md §3: a lane hidden in the key frame (zero features there) cannot come back
    from history in the literal mixed mode, and does in the variant."""
    torch.manual_seed(4)
    clip = torch.rand(1, 3, C, 8, 8) + 0.1
    clip[:, -1, :, 2:5, 2:5] = 0.0  # occluded in the key frame only
    hole = (slice(None), slice(None), slice(2, 5), slice(2, 5))
    literal = _stam(mode="mixed", reading="gates")(clip)
    variant = _stam(mode="mixed", reading="features")(clip)
    assert literal[hole].abs().max() == 0
    assert variant[hole].abs().min() > 0


def test_parallel_ignores_order(clip: torch.Tensor) -> None:
    torch.testing.assert_close(_stam(mode="parallel", order="cs")(clip), _stam(mode="parallel", order="sc")(clip))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"mode": "cascade"}, "mode"), ({"order": "xy"}, "order"), ({"reading": "none"}, "reading")],
)
def test_rejects_unknown_options(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        STAM(C, **kwargs)
