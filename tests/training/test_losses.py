"""Losses: bounded inverse class weights, the discriminative loss against a loop reference, LaneLoss."""

from __future__ import annotations

import math

import pytest
import torch
import torch.nn.functional as F

from stamlane.training.losses import LaneLoss, class_weights, discriminative_loss


def _reference(embedding, instance, delta_v=0.5, delta_d=1.5, alpha=1.0, beta=1.0, gamma=0.001):
    """Straight from De Brabandere et al. (2017): loops over images, lanes and lane pairs."""
    totals = {"var": 0.0, "dist": 0.0, "reg": 0.0}
    for b in range(embedding.shape[0]):
        ids = [i for i in instance[b].unique().tolist() if i > 0]
        means, var = [], 0.0
        for lane_id in ids:
            pixels = embedding[b][:, instance[b] == lane_id].T  # (N, E)
            mean = pixels.mean(dim=0)
            means.append(mean)
            var = var + (F.relu((mean - pixels).norm(dim=1) - delta_v) ** 2).mean()
        n = len(ids)
        if n == 0:
            continue
        dist = 0.0
        for a in range(n):
            for c in range(n):
                if a != c:
                    dist = dist + F.relu(2 * delta_d - (means[a] - means[c]).norm()) ** 2
        totals["var"] = totals["var"] + alpha * var / n
        totals["dist"] = totals["dist"] + (beta * dist / (n * (n - 1)) if n > 1 else 0.0)
        totals["reg"] = totals["reg"] + gamma * sum(m.norm() for m in means) / n
    return {k: torch.as_tensor(v) / embedding.shape[0] for k, v in totals.items()}


def _instances(batch: int = 3, height: int = 12, width: int = 16) -> torch.Tensor:
    instance = torch.zeros(batch, height, width, dtype=torch.long)
    instance[0, :, 2:4] = 1
    instance[0, :, 8:9] = 3  # ids need not be consecutive
    instance[0, 2:10, 12:15] = 4
    instance[1, :, 5] = 2  # one lane
    # image 2: no lane
    return instance


@pytest.mark.parametrize("params", [{}, {"delta_v": 0.1, "delta_d": 3.0, "alpha": 2.0, "beta": 0.5, "gamma": 0.1}])
def test_discriminative_loss_matches_loop_reference(params: dict) -> None:
    torch.manual_seed(0)
    instance = _instances()
    embedding = torch.randn(3, 4, 12, 16, dtype=torch.float64).float().requires_grad_()
    got = discriminative_loss(embedding, instance, **params)
    ref_embedding = embedding.detach().clone().requires_grad_()
    expected = _reference(ref_embedding, instance, **params)
    for key in ("var", "dist", "reg"):
        torch.testing.assert_close(got[key], expected[key].float(), atol=1e-5, rtol=1e-5)
        assert got[key] > 0
    sum(got.values()).backward()
    sum(expected.values()).backward()
    torch.testing.assert_close(embedding.grad, ref_embedding.grad, atol=1e-6, rtol=1e-4)


def test_push_term_vanishes_beyond_the_margin() -> None:
    instance = torch.zeros(1, 4, 4, dtype=torch.long)
    instance[0, :, 0] = 1
    instance[0, :, 3] = 2
    embedding = torch.zeros(1, 2, 4, 4)
    embedding[0, 0, :, 3] = 3.01  # centres 3.01 apart > 2 * delta_d = 3.0
    terms = discriminative_loss(embedding, instance)
    assert terms["dist"] == 0 and terms["var"] == 0
    embedding[0, 0, :, 3] = 2.0
    assert math.isclose(discriminative_loss(embedding, instance)["dist"].item(), 1.0, rel_tol=1e-6)


@pytest.mark.parametrize("num_lanes", [0, 1])
def test_finite_for_zero_and_one_lane(num_lanes: int) -> None:
    instance = torch.zeros(2, 8, 8, dtype=torch.long)
    if num_lanes:
        instance[:, :, 3] = 1
    embedding = torch.zeros(2, 4, 8, 8, requires_grad=True)  # all pixels on their mean: norms of 0
    terms = discriminative_loss(embedding, instance)
    assert all(torch.isfinite(v) for v in terms.values())
    assert terms["dist"] == 0 and terms["var"] == 0 and terms["reg"] == 0
    sum(terms.values()).backward()
    assert torch.isfinite(embedding.grad).all()


def test_discriminative_loss_rejects_mismatched_shapes() -> None:
    with pytest.raises(ValueError, match=r"expected instance of shape \(2, 8, 8\)"):
        discriminative_loss(torch.zeros(2, 4, 8, 8), torch.zeros(2, 8, 9, dtype=torch.long))
    with pytest.raises(ValueError, match="embedding"):
        discriminative_loss(torch.zeros(4, 8, 8), torch.zeros(4, 8, dtype=torch.long))


def test_class_weights_bounded_inverse_frequency() -> None:
    labels = torch.zeros(2, 10, 10, dtype=torch.long)
    labels[:, :, :1] = 1  # 10 % lane pixels
    weights = class_weights(labels)
    expected = torch.tensor([1 / math.log(1.02 + 0.9), 1 / math.log(1.02 + 0.1)])
    torch.testing.assert_close(weights, expected)
    assert weights[1] > weights[0]
    only_background = class_weights(torch.zeros(4, 4, dtype=torch.long))
    torch.testing.assert_close(only_background[1], torch.tensor(1 / math.log(1.02)))  # the bound
    with pytest.raises(ValueError, match=r"\[0, 2\)"):
        class_weights(torch.full((3,), 2))


def test_lane_loss_combines_terms() -> None:
    torch.manual_seed(1)
    instance = _instances()
    binary = (instance > 0).long()
    logits = torch.randn(3, 2, 12, 16, requires_grad=True)
    embedding = torch.randn(3, 4, 12, 16, requires_grad=True)
    loss = LaneLoss(seg_weight=0.7, embed_weight=2.0)
    out = loss(logits, embedding, binary, instance)
    assert set(out) == {"loss", "seg", "var", "dist", "reg"}
    seg = F.cross_entropy(logits, binary, weight=class_weights(binary))
    torch.testing.assert_close(out["seg"], seg)
    torch.testing.assert_close(out["loss"], 0.7 * seg + 2.0 * (out["var"] + out["dist"] + out["reg"]))
    out["loss"].backward()
    assert torch.isfinite(logits.grad).all() and torch.isfinite(embedding.grad).all()
    plain = LaneLoss(class_weighting=False)(logits, embedding, binary, instance)
    torch.testing.assert_close(plain["seg"], F.cross_entropy(logits, binary))


def test_lane_loss_accepts_bf16_outputs() -> None:
    instance = _instances()
    out = LaneLoss()(
        torch.randn(3, 2, 12, 16).bfloat16(), torch.randn(3, 4, 12, 16).bfloat16(), (instance > 0).long(), instance
    )
    assert all(v.dtype == torch.float32 and torch.isfinite(v) for v in out.values())


def test_lane_loss_rejects_bad_shapes() -> None:
    with pytest.raises(ValueError, match="logits"):
        LaneLoss()(
            torch.zeros(1, 3, 4, 4),
            torch.zeros(1, 4, 4, 4),
            torch.zeros(1, 4, 4, dtype=torch.long),
            torch.zeros(1, 4, 4, dtype=torch.long),
        )
