"""The bootstrap intervals: degenerate cases, coverage of a known mean, clips as units, paired differences."""

from __future__ import annotations

import numpy as np
import pytest
from stamlane_eval import culane
from stamlane_eval.stats import (
    bootstrap,
    culane_counts,
    f1_of_counts,
    f1_of_rates,
    paired_bootstrap,
    seed_interval,
    tusimple_rates,
)
from stamlane_eval.tusimple import TuSimpleImageResult, paper_f1


def _mean(means: np.ndarray) -> float:
    return float(means[0])


def test_constant_values_give_a_point_interval() -> None:
    est = bootstrap(np.full(50, 0.3), _mean)
    assert est.value == pytest.approx(0.3) and est.interval == pytest.approx((0.3, 0.3))


def test_interval_of_a_mean_matches_the_normal_approximation() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(1.0, 2.0, 400)
    est = bootstrap(x, _mean, resamples=4000)
    half = 1.96 * x.std(ddof=1) / np.sqrt(len(x))
    assert est.value == pytest.approx(x.mean())
    assert (est.high - est.low) / 2 == pytest.approx(half, rel=0.1)
    assert est.low < x.mean() < est.high


def test_groups_are_resampled_whole() -> None:
    """Five identical key frames per clip carry the information of one: the clip-level interval is as wide as
    the interval of the clips alone, the image-level one sqrt(5) times too narrow."""
    rng = np.random.default_rng(1)
    per_clip = rng.normal(0.0, 1.0, 100)
    images = np.repeat(per_clip, 5)
    clips = np.repeat([f"clip-{i}" for i in range(100)], 5)
    width_clips = np.subtract(*bootstrap(per_clip, _mean).interval[::-1])
    width_grouped = np.subtract(*bootstrap(images, _mean, groups=clips).interval[::-1])
    width_naive = np.subtract(*bootstrap(images, _mean).interval[::-1])
    assert width_grouped == pytest.approx(width_clips, rel=0.15)
    assert width_naive == pytest.approx(width_clips / np.sqrt(5), rel=0.15)
    assert bootstrap(images, _mean, groups=clips).groups == 100


def test_paired_difference_sees_a_small_shift_that_separate_intervals_hide() -> None:
    rng = np.random.default_rng(2)
    hardness = rng.uniform(0.0, 0.6, (300, 2))  # both models find the same images hard
    a = hardness
    b = np.clip(hardness + 0.02, 0, 1)  # B: 2 points more FP and FN on every image
    diff = paired_bootstrap(a, b, f1_of_rates)
    assert diff.value == pytest.approx(f1_of_rates(a.mean(0)) - f1_of_rates(b.mean(0)))
    assert diff.low > 0 and diff.excludes_zero()  # A (fewer errors) is better
    sep_a, sep_b = bootstrap(a, f1_of_rates), bootstrap(b, f1_of_rates)
    assert sep_a.low < sep_b.high  # the separate intervals overlap
    same = paired_bootstrap(a, a, f1_of_rates)
    assert same.interval == (0.0, 0.0) and not same.excludes_zero()


def test_tusimple_rates_and_f1() -> None:
    per_image = [TuSimpleImageResult(1.0, 0.0, 0.0, 4, 4, 4), TuSimpleImageResult(0.5, 0.5, 0.25, 2, 4, 4)]
    rates = tusimple_rates(per_image)
    np.testing.assert_array_equal(rates, [[0.0, 0.0], [0.5, 0.25]])
    assert f1_of_rates(rates.mean(0)) == pytest.approx(paper_f1(0.25, 0.125))


def test_culane_counts_and_f1_give_the_evaluators_totals() -> None:
    lane = np.array([[100.0, 500.0], [300.0, 200.0]])
    moved = lane + np.array([40.0, 0.0])  # 40 px to the right: beyond a 30-px line
    images = [([lane], [lane]), ([moved, lane], [lane]), ([], [lane, moved])]  # a TP; a TP + FP; two FN
    result = culane.evaluate([p for p, _ in images], [g for _, g in images])
    counts = culane_counts(result.per_image, 0.5)
    np.testing.assert_array_equal(counts, [[1, 0, 0], [1, 1, 0], [0, 0, 2]])
    assert f1_of_counts(counts.mean(0)) == pytest.approx(result.totals[0.5].f1, abs=1e-12)  # 2TP / (2TP + FP + FN)
    assert f1_of_counts(np.array([0.0, 3.0, 2.0])) == 0.0  # no match at all, as the tool says
    est = bootstrap(counts, f1_of_counts, resamples=200)
    assert est.low <= est.value <= est.high and est.value == pytest.approx(4 / 7)


def test_bad_input_is_refused() -> None:
    with pytest.raises(ValueError, match="same images"):
        paired_bootstrap(np.zeros((3, 2)), np.zeros((4, 2)), f1_of_rates)
    with pytest.raises(ValueError, match="non-finite"):
        bootstrap(np.array([0.1, np.nan]), _mean)
    with pytest.raises(ValueError, match="at least 2"):
        bootstrap(np.array([0.1, 0.2]), _mean, groups=["a", "a"])
    with pytest.raises(ValueError, match="one group per image"):
        bootstrap(np.array([0.1, 0.2]), _mean, groups=["a"])
    with pytest.raises(ValueError, match="level"):
        bootstrap(np.array([0.1, 0.2]), _mean, level=1.5)


def test_seed_interval_is_the_student_t_interval_of_the_mean() -> None:
    est = seed_interval([0.004, 0.009, 0.012])  # three seeds' differences
    # mean 0.00833, std 0.004041, t(0.975, 2) = 4.3027: half-width 0.010039
    assert est.value == pytest.approx(0.0083333, abs=1e-6)
    assert est.interval == pytest.approx((0.0083333 - 0.0100393, 0.0083333 + 0.0100393), abs=1e-6)
    assert est.groups == 3 and est.resamples == 0 and not est.excludes_zero()
    five = seed_interval([0.004, 0.009, 0.012, 0.006, 0.010], level=0.9)  # t(0.95, 4) = 2.1318
    assert five.high - five.value == pytest.approx(
        2.131847 * np.std([4, 9, 12, 6, 10], ddof=1) / 1000 / np.sqrt(5), abs=1e-7
    )
    assert five.excludes_zero()
    for bad in ([0.01], [0.01, float("nan")]):
        with pytest.raises(ValueError):
            seed_interval(bad)


def test_temporal_shares_through_the_bootstrap() -> None:
    import numpy as np
    from stamlane_eval import temporal
    from stamlane_eval.stats import bootstrap, rj_of_counts, rm_of_counts, rs_of_counts, temporal_counts
    from stamlane_eval.video import Frame

    a = np.array([[150.0, 359.0], [220.0, 250.0], [290.0, 150.0]])
    b = np.array([[490.0, 359.0], [420.0, 250.0], [350.0, 150.0]])
    clips = {
        "steady": [Frame([a, b], [a, b], size=(360, 640))] * 3,
        "flaky": [Frame([a, b], [a, b], size=(360, 640)), Frame([b], [a, b], size=(360, 640))],
    }
    res = temporal.evaluate(clips)
    counts = temporal_counts(res.per_sequence, 0.5)
    assert counts.tolist() == [[4, 0, 0], [1, 1, 0]]
    means = counts.mean(axis=0)
    c = res.totals[0.5]
    assert (rs_of_counts(means), rj_of_counts(means), rm_of_counts(means)) == (c.rs, c.rj, c.rm)
    est = bootstrap(counts, rs_of_counts, resamples=200)
    assert est.value == c.rs and est.interval[0] <= c.rs <= est.interval[1]
    assert np.isnan(rs_of_counts(np.zeros(3)))
