"""Confidence intervals for lane metrics: the percentile bootstrap over images, or over groups of images.

A benchmark number is a function of per-image quantities (TuSimple: the paper's F1 is a function of the
mean FP and FN rates). Resampling the test images with replacement and recomputing the number gives its
sampling distribution; resampling the SAME images for two models (a paired bootstrap) gives the
distribution of their difference, which is far narrower than two separate intervals suggest, since both
models find the same images hard.

Images of one video clip are not independent (the synthetic test splits label 5 key frames per clip), so
``groups`` resamples whole clips: every image of a drawn clip enters the resample, as often as the clip
was drawn (the cluster bootstrap). Without ``groups`` every image is its own group::

    a = tusimple_rates(evaluate(preds_a, gts).per_image)
    b = tusimple_rates(evaluate(preds_b, gts).per_image)
    paired_bootstrap(a, b, f1_of_rates, groups=clip_ids).interval   # (low, high) of F1(a) - F1(b)

Both intervals hold the trained weights fixed: they say how much a number would move on other test images, not
on another training run. Where two models were trained with several seeds, `seed_interval` of the per-seed
differences (the Student-t interval of their mean) says how much training randomness moves the difference; on
the synthetic benchmark it was the larger of the two (docs/results.md), so a difference is claimed there only
when both intervals exclude 0. Three seeds whose differences are +2, +3 and +4 points:

    >>> low, high = seed_interval([0.02, 0.03, 0.04]).interval
    >>> round(low, 4), round(high, 4)
    (0.0052, 0.0548)

The CULane / ApolloScape F1 is a function of the summed lane counts: ``culane_counts(result.per_image, 0.5)`` with
``f1_of_counts`` goes through the same functions; so are RVLD's Rs, Rj, Rm of the summed Ns, Nj, Nm:
``temporal_counts(result.per_sequence, 0.5)`` (one row per clip) with ``rs_of_counts`` / ``rj_of_counts`` /
``rm_of_counts``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from stamlane_eval.aggregate import paper_f1, prf, stability_rates
from stamlane_eval.culane import CULaneImageResult
from stamlane_eval.temporal import TemporalSequenceResult
from stamlane_eval.tusimple import TuSimpleImageResult

__all__ = [
    "Estimate",
    "bootstrap",
    "culane_counts",
    "f1_of_counts",
    "f1_of_rates",
    "paired_bootstrap",
    "rj_of_counts",
    "rm_of_counts",
    "rs_of_counts",
    "seed_interval",
    "temporal_counts",
    "tusimple_rates",
]

RESAMPLES = 2000
"""Bootstrap resamples: the 2.5 % / 97.5 % percentiles then move by well under 0.1 F1 point between seeds."""

Statistic = Callable[[np.ndarray], float]
"""Maps the column means of the per-image quantities, (k,), to the number reported."""


@dataclass(frozen=True)
class Estimate:
    """A number with its percentile-bootstrap interval.

    Attributes:
        value: the statistic on all images (for `paired_bootstrap`: of A minus of B).
        low, high: the interval's ends.
        level: its coverage (0.95).
        resamples: bootstrap resamples drawn (0 for `seed_interval`'s t interval).
        groups: independent units (clips or images resampled; for `seed_interval`, training seeds).
    """

    value: float
    low: float
    high: float
    level: float
    resamples: int
    groups: int

    @property
    def interval(self) -> tuple[float, float]:
        return self.low, self.high

    def excludes_zero(self) -> bool:
        """True when the interval lies entirely on one side of 0 (a difference the data supports)."""
        return self.low > 0.0 or self.high < 0.0

    def as_dict(self) -> dict[str, float | int]:
        return {
            "value": self.value,
            "low": self.low,
            "high": self.high,
            "level": self.level,
            "resamples": self.resamples,
            "groups": self.groups,
        }


def tusimple_rates(per_image: Sequence[TuSimpleImageResult]) -> np.ndarray:
    """Per-image ``(fp, fn)`` rates of a TuSimple evaluation, (N, 2): the quantities its F1 is made of."""
    return np.array([[r.fp, r.fn] for r in per_image], dtype=np.float64).reshape(-1, 2)


def f1_of_rates(means: np.ndarray) -> float:
    """The paper's TuSimple F1 from the mean ``(fp, fn)`` rates (what `tusimple_rates` gives per image)."""
    return paper_f1(float(means[0]), float(means[1]))


def culane_counts(per_image: Sequence[CULaneImageResult], iou_threshold: float) -> np.ndarray:
    """Per-image ``(tp, fp, fn)`` lane counts of a CULane / ApolloScape evaluation at one IoU threshold, (N, 3)."""
    return np.array([r.counts[float(iou_threshold)] for r in per_image], dtype=np.float64).reshape(-1, 3)


def f1_of_counts(means: np.ndarray) -> float:
    """The CULane F1 from the mean ``(tp, fp, fn)`` counts (what `culane_counts` gives per image): the evaluator's
    own F1 (`stamlane_eval.aggregate.prf`), which the means give as the sums do; 0 where no lane is matched."""
    tp, fp, fn = (float(v) for v in means[:3])
    return float(prf(tp, fp, fn)[2])


def temporal_counts(per_sequence: Sequence[TemporalSequenceResult], iou_threshold: float) -> np.ndarray:
    """Per-sequence ``(Ns, Nj, Nm)`` of a temporal stability evaluation at one threshold, (N, 3)."""
    return np.array(
        [[c.ns, c.nj, c.nm] for c in (s.counts[float(iou_threshold)] for s in per_sequence)], dtype=np.float64
    ).reshape(-1, 3)


def rs_of_counts(means: np.ndarray) -> float:
    """RVLD's Rs from the mean ``(Ns, Nj, Nm)`` per sequence (what `temporal_counts` gives): the evaluator's own
    shares (`stamlane_eval.aggregate.stability_rates`), NaN where nothing was counted."""
    return stability_rates(means[0], means[1], means[2])[0]


def rj_of_counts(means: np.ndarray) -> float:
    """RVLD's Rj from the mean ``(Ns, Nj, Nm)`` per sequence."""
    return stability_rates(means[0], means[1], means[2])[1]


def rm_of_counts(means: np.ndarray) -> float:
    """RVLD's Rm from the mean ``(Ns, Nj, Nm)`` per sequence."""
    return stability_rates(means[0], means[1], means[2])[2]


def _weights(n: int, groups: Sequence[object] | None, resamples: int, seed: int) -> tuple[np.ndarray, int]:
    """(resamples, n) counts: how often each image enters each resample (whole groups drawn with replacement)."""
    if groups is None:
        index = np.arange(n)
    else:
        if len(groups) != n:
            raise ValueError(f"groups must give one group per image ({n}), got {len(groups)}")
        _, index = np.unique(np.array([str(g) for g in groups]), return_inverse=True)
    units = int(index.max()) + 1 if n else 0
    if units < 2:
        raise ValueError(f"the bootstrap needs at least 2 independent groups, got {units}")
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, units, size=(resamples, units))
    counts = np.zeros((resamples, units), dtype=np.float64)
    np.add.at(counts, (np.arange(resamples)[:, None], draws), 1.0)
    return counts[:, index], units


def _check(values: np.ndarray, name: str) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    if values.ndim != 2 or len(values) == 0:
        raise ValueError(f"{name} must be (N, k) per-image values with N >= 1, got shape {values.shape}")
    if not np.isfinite(values).all():
        raise ValueError(f"{name} holds non-finite values")
    return values


def _estimate(
    stat_of: Callable[[np.ndarray], np.ndarray],
    n: int,
    groups: Sequence[object] | None,
    level: float,
    resamples: int,
    seed: int,
) -> Estimate:
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level}")
    if resamples < 100:
        raise ValueError(f"resamples must be >= 100, got {resamples}")
    weights, units = _weights(n, groups, resamples, seed)
    value = float(stat_of(np.ones((1, n)))[0])
    draws = stat_of(weights)
    tail = (1.0 - level) / 2.0
    low, high = np.quantile(draws, [tail, 1.0 - tail])
    return Estimate(value, float(low), float(high), level, resamples, units)


def _weighted(values: np.ndarray, statistic: Statistic) -> Callable[[np.ndarray], np.ndarray]:
    def stat_of(weights: np.ndarray) -> np.ndarray:
        means = weights @ values / weights.sum(axis=1, keepdims=True)
        return np.array([statistic(m) for m in means])

    return stat_of


def bootstrap(
    values: np.ndarray,
    statistic: Statistic,
    *,
    groups: Sequence[object] | None = None,
    level: float = 0.95,
    resamples: int = RESAMPLES,
    seed: int = 0,
) -> Estimate:
    """A statistic of per-image values with its percentile-bootstrap interval.

    Args:
        values: per-image quantities, (N, k) (or (N,)); e.g. `tusimple_rates`.
        statistic: maps their column means (k,) to the number, e.g. `f1_of_rates`.
        groups: per image, the id of its independent unit (its clip); None: images are independent.
        level: coverage of the interval.
        resamples: bootstrap resamples.
        seed: seed of the resampling (the result is a deterministic function of it).
    """
    values = _check(values, "values")
    return _estimate(_weighted(values, statistic), len(values), groups, level, resamples, seed)


def paired_bootstrap(
    a: np.ndarray,
    b: np.ndarray,
    statistic: Statistic,
    *,
    groups: Sequence[object] | None = None,
    level: float = 0.95,
    resamples: int = RESAMPLES,
    seed: int = 0,
) -> Estimate:
    """``statistic(A) - statistic(B)`` on the same images, with a paired percentile-bootstrap interval.

    Args:
        a, b: per-image quantities of two models on the SAME images in the same order, (N, k) each.
        statistic, groups, level, resamples, seed: as in `bootstrap`.
    """
    a, b = _check(a, "a"), _check(b, "b")
    if a.shape != b.shape:
        raise ValueError(f"a and b must hold the same images, got shapes {a.shape} and {b.shape}")
    stat_a, stat_b = _weighted(a, statistic), _weighted(b, statistic)
    return _estimate(lambda w: stat_a(w) - stat_b(w), len(a), groups, level, resamples, seed)


def seed_interval(values: Sequence[float], *, level: float = 0.95) -> Estimate:
    """The mean of per-seed values (e.g. F1(A) - F1(B) of two models trained from the same seed, each on all
    test images) with its Student-t interval: how far training randomness alone moves it.

    With few seeds the interval is wide by construction (t = 4.30 for 3 seeds, 2.78 for 5): it reports how little
    a handful of training runs can resolve, which a bootstrap over the seeds would understate.

    Raises:
        ValueError: fewer than 2 values, non-finite values, or a level outside (0, 1).
    """
    from scipy.stats import t as student_t  # imported here: the evaluators' commands never pay for it

    x = np.asarray(values, dtype=np.float64).ravel()
    if len(x) < 2:
        raise ValueError(f"an interval over seeds needs at least 2 seeds, got {len(x)}")
    if not np.isfinite(x).all():
        raise ValueError("values holds non-finite values")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level}")
    mean = float(x.mean())
    half = float(student_t.ppf(0.5 + level / 2.0, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x)))
    return Estimate(mean, mean - half, mean + half, level, 0, len(x))
