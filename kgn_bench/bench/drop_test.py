"""The statistical regression test: is a run's rate lower than its baseline's by more than chance?

Used when a run cannot be compared with its baseline trial by trial (another environment, or another
detector checked against a reference detector's baseline). The run (``k₁`` of ``n₁``) and the baseline
(``k₀`` of ``n₀``) are two independent binomial samples with rates ``p₁`` and ``p₀``; the test is
Boschloo's exact test of ``H₀: p₁ ≥ p₀`` against ``H₁: p₁ < p₀`` (one-sided; ``scipy.stats.boschloo_exact``),
which conditions on nothing and is uniformly more powerful than Fisher's exact test. A **regression** is
declared when its p-value is below ``ALPHA`` = 0.05.

Power. The chance that the test declares a true drop from ``p₀`` to ``p₀ − δ`` is
``Σ_{k₀,k₁} Bin(k₀; n₀, p₀) · Bin(k₁; n₁, p₀ − δ) · 1[p(k₁, k₀) < α]`` (``power``: exact, summed over the
baseline counts that carry probability, with the critical run count of each found by bisection). With
``n₀ = n₁ = n`` attempts, a drop from 95 % to 85 % is caught with power ≥ 0.8 from ``n = 118`` on (0.808;
0.789 at 116; ``trials_for_power``); the false-alarm rate of an unchanged 95 % detector is then about 3 %.
The CI regression task is sized from this.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.stats import binom, boschloo_exact

from .stats import Rate

__all__ = ["ALPHA", "drop_pvalue", "false_alarm_rate", "power", "trials_for_power"]

ALPHA = 0.05
"""Significance level of the one-sided test."""

_SAMPLING_POINTS = 16
"""Nuisance-parameter grid of Boschloo's test (scipy's ``n``)."""

_NEGLIGIBLE = 1e-7
"""Outcomes less likely than this are left out of the power sums."""


@lru_cache(maxsize=1 << 16)
def _pvalue(k1: int, n1: int, k0: int, n0: int) -> float:
    if n1 == 0 or n0 == 0 or k1 * n0 >= k0 * n1:  # the run did not do worse: nothing to test
        return 1.0
    table = [[k1, k0], [n1 - k1, n0 - k0]]  # columns are the two samples: the run and the baseline
    return float(boschloo_exact(table, alternative="less", n=_SAMPLING_POINTS).pvalue)


def drop_pvalue(run: Rate, baseline: Rate) -> float:
    """One-sided p-value of Boschloo's test that ``run``'s rate is below ``baseline``'s (1 when it is not)."""
    return _pvalue(run.k, run.n, baseline.k, baseline.n)


def _critical_k1(k0: int, n0: int, n1: int, alpha: float) -> int:
    """The largest run count ``k₁`` that the test calls a regression against ``k₀`` of ``n₀`` (−1 if none).
    The p-value grows with ``k₁``, so a bisection finds it."""
    lo, hi = -1, n1  # p(lo) < alpha (vacuous for -1), p(hi) ≥ alpha unless proven otherwise
    if _pvalue(n1, n1, k0, n0) < alpha:
        return n1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _pvalue(mid, n1, k0, n0) < alpha:
            lo = mid
        else:
            hi = mid
    return lo


def _rejection_mass(n0: int, p0: float, n1: int, p1: float, alpha: float) -> float:
    """``Σ_{k₀} Bin(k₀; n₀, p₀) · P(K₁ ≤ c(k₀))`` with ``K₁ ~ Bin(n₁, p₁)`` and ``c`` the critical count."""
    b0 = binom.pmf(np.arange(n0 + 1), n0, p0)
    total = 0.0
    for k0 in np.flatnonzero(b0 > _NEGLIGIBLE):
        c = _critical_k1(int(k0), n0, n1, alpha)
        if c >= 0:
            total += b0[k0] * binom.cdf(c, n1, p1)
    return float(total)


def power(n0: int, n1: int, p0: float = 0.95, drop: float = 0.10, alpha: float = ALPHA) -> float:
    """Chance that the test declares a regression when the rate truly fell from ``p0`` to ``p0 − drop``,
    with ``n0`` baseline and ``n1`` run attempts (module docstring)."""
    return _rejection_mass(n0, p0, n1, p0 - drop, alpha)


def false_alarm_rate(n0: int, n1: int, p0: float = 0.95, alpha: float = ALPHA) -> float:
    """Chance that the test declares a regression of a detector whose rate did not change (``p0`` both)."""
    return _rejection_mass(n0, p0, n1, p0, alpha)


def trials_for_power(p0: float = 0.95, drop: float = 0.10, target: float = 0.8, alpha: float = ALPHA,
                     start: int = 20, step: int = 2) -> int:
    """The smallest ``n`` (in steps of ``step`` from ``start``) with ``power(n, n, p0, drop) ≥ target``."""
    n = start
    while power(n, n, p0, drop, alpha) < target:
        n += step
    return n
