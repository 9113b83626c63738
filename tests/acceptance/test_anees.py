"""The Monte Carlo consistency test over the runs (``monte_carlo = { anees = c }``), judged on
synthetic per-run NEES series whose answer is known: a consistent filter whose error is one
slowly varying draw per run PASSes over the runs where a per-run band FAILs some of them; an
overconfident one (errors twice its sigma) FAILs; N is the number of runs; the band is the
chi-square interval of N x dof, computed here independently of the bench."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter
from scipy.stats import chi2

from bench.acceptance.anees import MIN_GRID_TIMES, anees_band
from bench.acceptance.case import parse_case
from bench.acceptance.criteria import Criterion, Limit, MonteCarlo, RunValue, aggregate_runs
from bench.acceptance.judge import CriterionResult
from bench.acceptance.verdict import Verdict
from bench.errors import ConfigError
from bench.report.results import criterion_json
from bench.scoring.consistency import chi2_bounds, nees_grid
from bench.scoring.windows import WindowSpec

GRID = 600  # grid times (1 s) per run


def _criterion(stat: str = "within", comparator: str = "at_least", limit: float = 0.9, conf: float = 0.95,
               quantity: str = "position") -> Criterion:
    lim = Limit(comparator, low=limit) if comparator == "at_least" else Limit(comparator, high=limit)
    return Criterion("NEES", ("R",), f"consistency.{quantity}.{stat}", WindowSpec("converged", converged=True), lim,
                     "%", "dimensionless", monte_carlo=MonteCarlo("anees", anees=conf))


def _slow_errors(rng: np.random.Generator, scale: float, dof: int) -> np.ndarray:
    """One run's normalised errors (GRID x dof): the error over its sigma times ``scale``
    (1: consistent), each axis a Gauss-Markov process of unit variance with a 2000 s time
    constant, so that a run is dominated by its first draw (as a heading error is)."""
    a = math.exp(-1.0 / 2000.0)
    b = math.sqrt(1 - a * a)
    w = rng.standard_normal((GRID, dof))
    w[0] /= b  # z[0] = w[0]: stationary from the start
    return scale * b * lfilter([1.0], [1.0, -a], w, axis=0)


def _run(seed: int, z: np.ndarray, start: float = 100.0, stat: str = "within", conf: float = 0.95) -> RunValue:
    """A run's value as :func:`bench.acceptance.judge.score_run` gives it: the per-run
    metric over all its epochs and the sampled series in the details."""
    dof = z.shape[1]
    nees = np.sum(z * z, axis=1)
    lo, hi = chi2_bounds(dof, conf)
    value = {"within": np.mean((nees >= lo) & (nees <= hi)), "above": np.mean(nees > hi)}[stat]
    t_ns = ((start + np.arange(len(nees))) * 1e9).astype(np.int64)  # epochs on the grid times
    grid = nees_grid(t_ns, nees / dof)
    return RunValue(seed, float(value), Verdict.PASS if value >= 0.9 else Verdict.FAIL, "",
                    {"dof": dof, "nees_grid": grid})


def _runs(n: int, scale: float, dof: int = 3, seed0: int = 0) -> list[RunValue]:
    return [_run(s, _slow_errors(np.random.default_rng(seed0 + s), scale, dof)) for s in range(1, n + 1)]


def test_the_band_is_the_chi_square_interval_of_n_runs():
    for n, conf in ((1, 0.95), (20, 0.95), (10, 0.99), (7, 0.9)):
        a = (1 - conf) / 2
        assert anees_band(n, conf) == pytest.approx((chi2.ppf(a, n) / n, chi2.ppf(1 - a, n) / n), rel=1e-12)
    assert anees_band(20, 0.95) == pytest.approx((9.591 / 20, 34.170 / 20), abs=1e-4)  # the printed table
    assert anees_band(1, 0.95) == pytest.approx(chi2_bounds(1, 0.95), rel=1e-12)  # N = 1: the per-run band


def test_the_band_of_n_runs_holds_whatever_the_correlation_between_the_axes():
    """A consistent DUT whose east and north errors correlate (a heading error moves both):
    the mean over 20 runs of its position NEES per dof leaves the band of chi-square(20)/20
    at most 5 % of the time, where the band of chi-square(60)/60 (3 independent axes per
    run) would be left 11 % of the time."""
    rng = np.random.default_rng(7)
    r = np.array([[1.0, 0.9, 0.1], [0.9, 1.0, 0.1], [0.1, 0.1, 1.0]])
    z = rng.standard_normal((100_000, 20, 3)) @ np.linalg.cholesky(r).T
    anees = np.mean(np.sum(z * z, axis=2) / 3, axis=1)
    lo, hi = anees_band(20, 0.95)
    assert np.mean((anees < lo) | (anees > hi)) < 0.05
    lo3, hi3 = chi2.ppf(0.025, 60) / 60, chi2.ppf(0.975, 60) / 60
    assert np.mean((anees < lo3) | (anees > hi3)) > 0.10
    one = np.mean(z[:, :, :1] ** 2, axis=(1, 2))  # one error on every axis: exactly the band's law
    assert np.mean((one < lo) | (one > hi)) == pytest.approx(0.05, abs=0.003)


def test_a_consistent_filter_passes_over_the_runs_where_the_per_run_band_fails_some():
    runs = _runs(20, 1.0)
    per_run = [r.value for r in runs]
    assert sum(v < 0.9 for v in per_run) >= 3  # judged run by run (mode each) a consistent filter FAILs
    agg = aggregate_runs(_criterion(), runs)
    assert agg.verdict is Verdict.PASS, agg.reason
    d = agg.details
    assert d["runs"] == 20 and d["dof"] == 3 and d["grid_times"] == GRID and d["left_out"] == 0
    band = (chi2.ppf(0.025, 20) / 20, chi2.ppf(0.975, 20) / 20)
    assert d["band"] == pytest.approx(band)
    # the value is the share of grid times whose mean over the runs lies in that band
    samples = np.array([r.details["nees_grid"]["values"] for r in runs], dtype=float)
    anees = samples.mean(axis=0)
    assert agg.value == pytest.approx(np.mean((anees >= band[0]) & (anees <= band[1])), abs=1e-12)
    assert agg.value >= 0.9
    assert "ANEES of 20 runs at 600 grid times" in agg.reason and "95 % band" in agg.reason


def test_the_share_in_band_of_one_campaign_spreads_with_the_errors_correlation_in_time():
    """The budget the reference cases cite for their band's confidence: the grid times of one
    campaign are correlated (one slowly varying draw per run), so the share of them in the
    band is not near the confidence. For a consistent heading error (1 dof, 2000 s time
    constant, 600 s window), 100 campaigns of 20 runs: ">= 90 % of the grid times in band"
    fails 11 of them with a 95 % band, 4 with a 99 % band."""
    fails = {}
    for conf in (0.95, 0.99):
        shares = [aggregate_runs(_criterion(conf=conf, quantity="heading"),
                                 _runs(20, 1.0, dof=1, seed0=1000 * k)).value for k in range(100)]
        fails[conf] = sum(v < 0.9 for v in shares)
    assert fails == {0.95: 11, 0.99: 4}


def test_an_overconfident_filter_fails_over_the_runs():
    """Errors twice the filter's sigma: the ANEES near 4 lies above the band of 20 runs."""
    agg = aggregate_runs(_criterion(), _runs(20, 2.0))
    assert agg.verdict is Verdict.FAIL
    assert agg.value < 0.5 and agg.details["above"] > 0.5
    above = aggregate_runs(_criterion("above", "at_most", 0.1), _runs(20, 2.0))
    assert above.verdict is Verdict.FAIL and above.value > 0.5
    # a pessimistic filter (errors half its sigma) falls below the band
    below = aggregate_runs(_criterion(), _runs(20, 0.5))
    assert below.verdict is Verdict.FAIL and below.details["below"] > 0.5


def test_n_is_the_number_of_runs_and_one_run_is_the_per_run_test():
    for n in (1, 5, 12):
        agg = aggregate_runs(_criterion(quantity="heading"), _runs(n, 1.0, dof=1))
        assert agg.details["runs"] == n and agg.details["dof"] == 1
        assert agg.details["band"] == pytest.approx([chi2.ppf(0.025, n) / n, chi2.ppf(0.975, n) / n])
    one = aggregate_runs(_criterion(quantity="heading"), _runs(1, 1.0, dof=1))
    assert "one run: the per-run test" in one.reason
    assert MonteCarlo("anees", anees=0.95).text(20) == "ANEES over 20 runs in its 95 % band"
    assert MonteCarlo("anees", anees=0.99).text(1) == "ANEES over 1 run in its 99 % band"


def test_only_grid_times_every_run_covers_are_judged_and_too_few_is_error():
    rng = np.random.default_rng(5)
    late = _run(2, _slow_errors(rng, 1.0, 3), start=100.0 + GRID - 30)  # overlaps the others' last 30 s
    runs = [_run(1, _slow_errors(rng, 1.0, 3)), late]
    agg = aggregate_runs(_criterion(), runs)
    assert agg.details["grid_times"] == 30 and agg.details["left_out"] == 2 * GRID - 60
    assert "left out" in agg.reason
    later = _run(2, _slow_errors(rng, 1.0, 3), start=100.0 + GRID - MIN_GRID_TIMES + 1)
    agg = aggregate_runs(_criterion(), [runs[0], later])
    assert agg.verdict is Verdict.ERROR and f"at least {MIN_GRID_TIMES}" in agg.reason


def test_a_run_without_its_series_is_error_never_a_verdict_on_fewer_runs():
    runs = _runs(3, 1.0)
    runs[1] = RunValue(runs[1].seed, runs[1].value, runs[1].verdict, "", {"dof": 3})
    agg = aggregate_runs(_criterion(), runs)
    assert agg.verdict is Verdict.ERROR and "seed 2 carries no sampled NEES series" in agg.reason
    # a run the DUT failed (no value) decides as in the other modes: FAIL with its reason
    runs = _runs(3, 1.0)
    runs[0] = RunValue(1, math.nan, Verdict.FAIL, "the DUT output no quality")
    assert aggregate_runs(_criterion(), runs).verdict is Verdict.FAIL


def test_an_infinite_sample_is_above_the_band():
    runs = _runs(5, 1.0)
    runs[0].details["nees_grid"]["values"][:300] = [math.inf] * 300  # a zero sigma with an error
    agg = aggregate_runs(_criterion(), runs)
    assert agg.verdict is Verdict.FAIL and agg.details["above"] >= 0.5
    assert agg.details["mean"] == "inf"


def test_the_grid_samples_the_epoch_at_or_just_after_each_grid_time():
    t = np.array([0.5, 1.0, 1.7, 2.2, 5.1, 5.2, 6.0]) * 1e9
    g = nees_grid(t.astype(np.int64), np.array([9.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]))
    assert g["start_s"] == 1.0 and g["step_s"] == 1.0
    assert g["values"] == [1.0, 3.0, None, None, 4.0, 6.0]  # 1 s, 2 s, 3 s, 4 s (none), 5 s, 6 s


def test_the_results_record_shows_the_mode_and_its_series():
    c = _criterion()
    runs = _runs(4, 1.0)
    doc = criterion_json(CriterionResult(c, None, aggregate_runs(c, runs), runs))
    assert doc["monte_carlo"] == "ANEES over 4 runs in its 95 % band"
    assert doc["anees"]["runs"] == 4 and len(doc["anees"]["t_s"]) == len(doc["anees"]["anees"]) == GRID


CASE = """
[case]
id = "C"
title = "t"
requirements = ["R"]
[scenario]
script = "s.toml"
[dut]
kind = "synthetic"
[dut.variants.a]
description = "a"
[dut.variants.b]
description = "b"
[run]
seeds = [1, 2]
[[criterion]]
id = "X"
requirement = "R"
variant = "a"
metric = "{metric}"
{limit}
{extra}
"""


def _parse(metric: str = "consistency.position.within", limit: str = 'at_least = "90 %"',
           extra: str = 'monte_carlo = { anees = "95 %" }'):
    return parse_case(CASE.format(metric=metric, limit=limit, extra=extra), file="c.toml", check_files=False)


def test_the_case_file_takes_the_mode_on_consistency_shares_only():
    c = _parse().criteria[0]
    assert c.monte_carlo.mode == "anees" and c.monte_carlo.anees == pytest.approx(0.95)
    assert _parse(extra="monte_carlo = { anees = 0.99 }").criteria[0].monte_carlo.anees == 0.99
    refused = {
        "on another metric": dict(metric="accuracy.horizontal.rms", limit='at_most = "1 m"'),
        "on a run's mean NEES": dict(metric="consistency.heading.nees", limit="at_most = 3"),
        "a confidence of 1": dict(extra='monte_carlo = { anees = "100 %" }'),
        "with another mode": dict(extra='monte_carlo = { anees = "95 %", aggregate = "mean" }'),
        "on a comparison": dict(extra='relative_to = "b"\nmonte_carlo = { anees = "95 %" }', limit="at_most = 1"),
    }
    for why, kw in refused.items():
        with pytest.raises(ConfigError) as exc:
            _parse(**kw)
        assert "c.toml" in str(exc.value) and "criterion[0]" in str(exc.value), why
        assert "anees" in str(exc.value) or "relative_to" in str(exc.value), (why, str(exc.value))


def test_the_sanity_bound_holds_whatever_the_correlation_of_a_runs_errors():
    """A run's mean NEES per dof is a weighted sum of squared normal draws with weights adding
    to 1 (the eigenvalues of the errors' correlation over the run and the axes); its chance
    of exceeding 10.83, the 99.9 % point of chi-square(1), is largest for one draw: 0.1 %."""
    rng = np.random.default_rng(11)
    assert chi2.ppf(0.999, 1) == pytest.approx(10.83, abs=0.005)
    for weights in ([1.0], [0.5, 0.5], [0.8, 0.2], [0.6, 0.3, 0.1], [1 / 3] * 3, [0.9] + [0.01] * 10):
        w = np.asarray(weights)
        q = (rng.chisquare(1, (400_000, len(w))) * w).sum(axis=1)
        assert np.mean(q > 10.83) <= 0.001 + 0.0002, weights
