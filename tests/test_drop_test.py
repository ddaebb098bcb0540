"""The statistical regression test: Boschloo's one-sided test, its power and its false-alarm rate."""

import numpy as np
import pytest

from kgn_bench.bench.check import POWERED_ATTEMPTS
from kgn_bench.bench.drop_test import ALPHA, drop_pvalue, false_alarm_rate, power
from kgn_bench.bench.stats import Rate


def test_a_run_that_did_no_worse_is_never_a_regression():
    assert drop_pvalue(Rate(20, 20), Rate(19, 20)) == 1.0
    assert drop_pvalue(Rate(19, 20), Rate(19, 20)) == 1.0
    assert drop_pvalue(Rate(0, 0), Rate(19, 20)) == 1.0


def test_a_collapse_is_a_regression_and_one_failure_is_not():
    assert drop_pvalue(Rate(10, 20), Rate(20, 20)) < 1e-3
    assert drop_pvalue(Rate(19, 20), Rate(20, 20)) > 0.3
    # the old interval rule let 14/20 pass against 20/20; the test does not
    assert drop_pvalue(Rate(14, 20), Rate(20, 20)) < ALPHA


def test_power_matches_a_simulation_of_the_test():
    rng = np.random.default_rng(0)
    n, p0, p1 = 30, 0.9, 0.6
    k0, k1 = rng.binomial(n, p0, 400), rng.binomial(n, p1, 400)
    simulated = np.mean([drop_pvalue(Rate(int(b), n), Rate(int(a), n)) < ALPHA for a, b in zip(k0, k1, strict=True)])
    assert power(n, n, p0, p0 - p1) == pytest.approx(simulated, abs=0.06)


def test_false_alarms_stay_below_alpha_and_power_grows_with_trials():
    assert false_alarm_rate(40, 40) < ALPHA
    assert power(20, 20) < power(60, 60) < power(100, 100)


def test_the_powered_size_is_the_smallest_that_catches_a_10_point_drop_with_80_percent():
    assert power(POWERED_ATTEMPTS, POWERED_ATTEMPTS) >= 0.8 > power(POWERED_ATTEMPTS - 2, POWERED_ATTEMPTS - 2)
