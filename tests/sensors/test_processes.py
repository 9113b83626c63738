"""Shared noise processes: configured statistics, exact discretisation, window independence."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.rng import stream
from bench.sensors.processes import (
    GaussMarkov,
    RandomWalk,
    WhiteNoise,
    autocovariance,
    fit_markov,
    period_ns,
    sample_times,
)


def test_gauss_markov_sigma_and_tau_within_10_percent():
    # 10^6 samples at 0.1 s over 10^4 correlation times
    gm = GaussMarkov(2.5, 10.0, 0.1, stream(7, "t", "gm"))
    x = gm.draw(1_000_000)
    s_w, s_m, tau = fit_markov(x, 0.1)
    assert np.std(x) == pytest.approx(2.5, rel=0.10)
    assert s_m == pytest.approx(2.5, rel=0.10)
    assert tau == pytest.approx(10.0, rel=0.10)
    assert s_w < 0.1 * 2.5  # no white part


def test_gauss_markov_exact_discretisation_at_a_coarse_interval():
    # dt = tau: phi = exp(-1); lag-1 autocorrelation must be exp(-1) whatever dt is
    x = GaussMarkov(1.0, 5.0, 5.0, stream(1, "gm")).draw(400_000)
    c = autocovariance(x, 2)
    assert c[1] / c[0] == pytest.approx(math.exp(-1.0), abs=0.01)
    assert c[2] / c[0] == pytest.approx(math.exp(-2.0), abs=0.01)


def test_gauss_markov_starts_stationary_and_vectorised_axes_are_independent():
    starts = np.array([GaussMarkov(3.0, 100.0, 1.0, stream(s, "gm")).state[0] for s in range(4000)])
    assert np.std(starts) == pytest.approx(3.0, rel=0.05)
    x = GaussMarkov(np.array([1.0, 2.0, 4.0]), np.array([5.0, 50.0, 0.5]), 0.1, stream(3, "gm")).draw(500_000)
    assert x.shape == (500_000, 3)
    assert np.std(x, axis=0) == pytest.approx([1.0, 2.0, 4.0], rel=0.10)
    for i, tau in enumerate((5.0, 50.0, 0.5)):
        assert fit_markov(x[:, i], 0.1)[2] == pytest.approx(tau, rel=0.10)
    assert abs(np.corrcoef(x[:, 0], x[:, 2])[0, 1]) < 0.02


def test_white_plus_markov_split():
    n, dt = 1_000_000, 0.2
    x = WhiteNoise(0.3, stream(2, "w")).draw(n) + GaussMarkov(0.4, 20.0, dt, stream(2, "m")).draw(n)
    s_w, s_m, tau = fit_markov(x, dt)
    assert s_w == pytest.approx(0.3, rel=0.10)
    assert s_m == pytest.approx(0.4, rel=0.10)
    assert tau == pytest.approx(20.0, rel=0.10)


def test_random_walk_variance_grows_linearly():
    runs = np.stack([RandomWalk(0.5, 0.01, stream(s, "rw")).draw(1000) for s in range(2000)])
    # after 10 s the variance is q^2 t = 0.25 * 10
    assert np.var(runs[:, -1]) == pytest.approx(2.5, rel=0.10)
    assert np.var(runs[:, 99]) == pytest.approx(0.25, rel=0.10)


@pytest.mark.parametrize("cls", ["white", "gm", "rw"])
def test_draws_do_not_depend_on_how_the_run_is_cut(cls):
    def make():
        g = stream(11, "cut", cls)
        if cls == "white":
            return WhiteNoise(np.array([1.0, 2.0]), g)
        if cls == "gm":
            return GaussMarkov(np.array([1.0, 2.0]), 3.0, 0.05, g)
        return RandomWalk(np.array([1.0, 2.0]), 0.05, g)

    whole = make().draw(1000)
    p = make()
    cut = np.vstack([p.draw(k) for k in (1, 0, 17, 300, 682)])
    assert np.array_equal(whole, cut)


def test_sample_grid():
    P = period_ns(50.0)
    assert P == 20_000_000
    assert np.array_equal(
        sample_times(P, 0, 100_000_000), [20_000_000, 40_000_000, 60_000_000, 80_000_000, 100_000_000]
    )
    assert np.array_equal(sample_times(P, 20_000_000, 50_000_000), [40_000_000])
    assert len(sample_times(P, 0, 10_000_000)) == 0
    with pytest.raises(ValueError):
        period_ns(3.0)
    with pytest.raises(ValueError):
        GaussMarkov(1.0, 0.0, 0.1, stream(0, "x"))
