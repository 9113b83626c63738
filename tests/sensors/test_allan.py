import allantools
import numpy as np
import pytest

from bench.sensors.allan import allan_deviation


def test_overlapping_allan_deviation_matches_allantools():
    rng = np.random.default_rng(0)
    rate = rng.normal(size=20_000) * 1e-3 + np.cumsum(rng.normal(size=20_000)) * 1e-6
    dt = 0.01
    ours = allan_deviation(rate * dt, dt)
    taus, adev, _, _ = allantools.oadev(rate, rate=1 / dt, data_type="freq", taus=ours.tau)
    common, i_ours, i_theirs = np.intersect1d(ours.tau, taus, return_indices=True)
    assert len(common) > 20
    assert ours.adev[i_ours] == pytest.approx(adev[i_theirs], rel=1e-9)


def test_white_noise_slope():
    rng = np.random.default_rng(1)
    N = 2e-4
    dt = 0.01
    x = rng.normal(size=200_000) * N * np.sqrt(dt)
    r = allan_deviation(x, dt)
    sel = r.tau < 10
    assert np.median(r.adev[sel] * np.sqrt(r.tau[sel])) == pytest.approx(N, rel=0.02)
