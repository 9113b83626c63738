"""Comparators, marginal bands, Monte Carlo statistics and verdict combination."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import binom

from bench.acceptance.criteria import (
    Criterion,
    Limit,
    MonteCarlo,
    RunValue,
    aggregate_runs,
    judge_value,
    order_statistic_bound,
    runs_needed,
)
from bench.acceptance.verdict import Verdict, worst
from bench.scoring.windows import WindowSpec

P, M, F, E = Verdict.PASS, Verdict.MARGINAL, Verdict.FAIL, Verdict.ERROR


@pytest.mark.parametrize(
    ("limit", "band", "value", "verdict"),
    [
        (Limit("at_most", high=10.0), 1.0, 8.0, P),
        (Limit("at_most", high=10.0), 1.0, 9.5, M),
        (Limit("at_most", high=10.0), 1.0, 10.0, M),
        (Limit("at_most", high=10.0), 1.0, 10.0001, F),
        (Limit("at_most", high=10.0), 0.0, math.inf, F),
        (Limit("at_least", low=0.9), 0.05, 1.0, P),
        (Limit("at_least", low=0.9), 0.05, 0.92, M),
        (Limit("at_least", low=0.9), 0.05, 0.89, F),
        (Limit("within", high=2.0), 0.0, -1.9, P),
        (Limit("within", high=2.0), 0.0, -2.1, F),
        (Limit("in_range", low=1.0, high=3.0), 0.5, 2.0, P),
        (Limit("in_range", low=1.0, high=3.0), 0.5, 1.2, M),
        (Limit("in_range", low=1.0, high=3.0), 0.5, 3.2, F),
        (Limit("at_most", high=1.0), 0.0, math.nan, E),
    ],
)
def test_judge_value(limit, band, value, verdict):
    assert judge_value(limit, band, value)[0] is verdict


def test_margin_sign_and_size():
    assert judge_value(Limit("at_most", high=10.0), 0.0, 7.0)[1] == 3.0
    assert judge_value(Limit("at_least", low=10.0), 0.0, 7.0)[1] == -3.0
    assert judge_value(Limit("in_range", low=0.0, high=10.0), 0.0, 7.0)[1] == 3.0


EACH = MonteCarlo()
AT_MOST_10 = Limit("at_most", high=10.0)


def _crit(limit: Limit, mc: MonteCarlo = EACH, **kw) -> Criterion:
    return Criterion("c", ("R",), "accuracy.horizontal.rms", WindowSpec(), limit, "m", "length", monte_carlo=mc, **kw)


def _runs(values, limit=AT_MOST_10, band=0.0):
    return [RunValue(i, v, judge_value(limit, band, v)[0]) for i, v in enumerate(values)]


def test_each_run_must_pass_and_the_worst_value_is_shown():
    c = _crit(Limit("at_most", high=10.0))
    a = aggregate_runs(c, _runs([3.0, 9.0, 5.0]))
    assert (a.verdict, a.value) == (P, 9.0)
    a = aggregate_runs(c, _runs([3.0, 11.0, 5.0]))
    assert (a.verdict, a.value) == (F, 11.0)


def test_marginal_relative_band():
    c = _crit(Limit("at_most", high=10.0), marginal_relative=0.1)
    assert c.band() == pytest.approx(1.0)
    assert aggregate_runs(c, _runs([9.5], band=1.0)).verdict is M


def test_error_run_makes_each_mode_error_and_dut_failure_without_value_fails():
    c = _crit(Limit("at_most", high=10.0))
    runs = [*_runs([3.0, 4.0]), RunValue(9, math.nan, E, "no DUT epoch in window")]
    a = aggregate_runs(c, runs)
    assert a.verdict is E and "no DUT epoch" in a.reason
    runs = [*_runs([3.0]), RunValue(9, math.nan, F, "invalid throughout")]
    assert aggregate_runs(c, runs).verdict is F


def test_pass_runs_k_of_n():
    c = _crit(Limit("at_most", high=10.0), MonteCarlo("pass_runs", pass_runs=9))
    values = [1.0] * 9 + [20.0]
    a = aggregate_runs(c, _runs(values))
    assert a.verdict is P and a.value == 1.0 and "9 of 10" in a.reason
    a = aggregate_runs(c, _runs([1.0] * 8 + [20.0, 30.0]))
    assert a.verdict is F and a.value == 20.0  # the 9th best run
    runs = [*_runs([1.0] * 8 + [20.0]), RunValue(9, math.nan, E, "lost link")]
    assert aggregate_runs(c, runs).verdict is E  # the unjudged run could have decided it
    a = aggregate_runs(c, _runs([1.0] * 3))  # --seed 1 and the like: too few runs to judge
    assert a.verdict is E and "3 runs cannot show 9 passing runs" in a.reason


def test_order_statistic_bound_is_the_binomial_one():
    for n in (10, 45, 59, 100):
        for p, conf in ((0.95, 0.9), (0.5, 0.95), (0.9, 0.5)):
            r = order_statistic_bound(n, p, conf, upper=True)
            if r is None:
                assert 1 - p**n < conf
                continue
            assert binom.cdf(r - 1, n, p) >= conf
            assert r == 1 or binom.cdf(r - 2, n, p) < conf
    assert runs_needed(0.95, 0.9, True) == 45
    assert order_statistic_bound(44, 0.95, 0.9, True) is None
    assert order_statistic_bound(45, 0.95, 0.9, True) == 45


def test_percentile_with_confidence():
    c = _crit(Limit("at_most", high=10.0), MonteCarlo("percentile", percentile=50.0, confidence=0.95))
    values = list(np.arange(1.0, 101.0))  # 1 .. 100
    a = aggregate_runs(c, _runs(values, Limit("at_most", high=1000.0)))
    assert a.value == 59.0  # upper 95 % bound of the median of 100 runs: the 59th value
    assert a.verdict is F
    c2 = _crit(Limit("at_most", high=10.0), MonteCarlo("percentile", percentile=95.0, confidence=0.9))
    a = aggregate_runs(c2, _runs([1.0] * 10))
    assert a.verdict is E and "at least 45" in a.reason


def test_aggregate_mean():
    c = _crit(Limit("at_most", high=10.0), MonteCarlo("aggregate", aggregate="mean"))
    a = aggregate_runs(c, _runs([6.0, 8.0, 16.0]))
    assert (a.value, a.verdict) == (10.0, P)


def test_worst_verdict_order():
    assert worst([P, M, P]) is M
    assert worst([P, F, M]) is F
    assert worst([F, E, P]) is E
    assert worst([]) is P
    assert P.passed and M.passed and not F.passed and not E.passed
