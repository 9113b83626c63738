"""The IMU error model: deterministic terms appear exactly, random terms with the
configured statistics (Allan deviation), and the output does not depend on blocking."""

import math

import numpy as np
import pytest

from bench.sensors.allan import AllanResult, allan_deviation, read_noise_terms
from bench.sensors.imu.errors import ImuErrorModel
from bench.sensors.imu.grade import ImuGrade, TriadErrors
from bench.sensors.imu.ideal import ImuBlock
from bench.units import quantity

T = 0.005  # 200 Hz


def _block(n, rate=200.0, dtheta=None, dvel=None, start=0):
    period = round(1e9 / rate)
    t = (np.arange(start + 1, start + n + 1) * period).astype(np.int64)
    return ImuBlock(
        t,
        np.zeros((n, 3)) if dtheta is None else dtheta,
        np.zeros((n, 3)) if dvel is None else dvel,
        np.full(n, 0x3F, np.uint8),
    )


def _model(gyro=None, accel=None, seed=7, rate=200.0):
    return ImuErrorModel(ImuGrade("test", gyro or TriadErrors(), accel or TriadErrors()), seed, rate)


def _motion(n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(scale=1e-3, size=(n, 3)), rng.normal(scale=5e-2, size=(n, 3))


def test_constant_bias_appears_exactly():
    b_g = np.array([quantity("0.01 deg/h", "angular_rate", "deg/h")] * 2 + [-4.8e-8])
    b_a = np.array([9.80665e-4, -9.80665e-4, 2e-4])
    # at rest the output is the bias itself, to the last bit
    out = _model(TriadErrors(bias=b_g), TriadErrors(bias=b_a)).apply(_block(1000))
    assert np.array_equal(out.dtheta, np.broadcast_to(b_g * T, (1000, 3)))
    assert np.array_equal(out.dvel, np.broadcast_to(b_a * T, (1000, 3)))
    # in motion, to the rounding of the sum (one ulp of the increment)
    th, v = _motion(1000)
    out = _model(TriadErrors(bias=b_g), TriadErrors(bias=b_a)).apply(_block(1000, dtheta=th, dvel=v))
    assert np.abs(out.dtheta - th - b_g * T).max() <= np.spacing(np.abs(th).max())
    assert np.abs(out.dvel - v - b_a * T).max() <= np.spacing(np.abs(v).max())


def test_scale_factor_and_asymmetry_appear_exactly():
    sf = np.array([100e-6, -50e-6, 20e-6])
    asym = np.array([10e-6, 0.0, 5e-6])
    th, v = _motion(1000)
    out = _model(TriadErrors(scale_factor=sf, scale_factor_asymmetry=asym)).apply(_block(1000, dtheta=th, dvel=v))
    k = sf + np.where(th >= 0, 1.0, -1.0) * asym
    assert np.allclose(out.dtheta, th * (1 + k), rtol=1e-15, atol=0)
    assert np.array_equal(out.dvel, v)


def test_misalignment_matrix():
    M = np.zeros((3, 3))
    M[0, 1], M[2, 0] = 1e-4, -2e-4
    th, _ = _motion(100)
    out = _model(TriadErrors(misalignment=M)).apply(_block(100, dtheta=th))
    assert np.allclose(out.dtheta, th + th @ M.T, rtol=1e-15, atol=0)


def test_random_draws_are_per_seed_and_reported():
    g = TriadErrors(
        bias=np.full(3, 1e-6),
        bias_draw="random",
        misalignment=np.full((3, 3), 1e-4) - np.diag(np.full(3, 1e-4)),
        misalignment_draw="random",
    )
    a = _model(g, seed=1).realised["gyro"]
    b = _model(g, seed=1).realised["gyro"]
    c = _model(g, seed=2).realised["gyro"]
    assert np.array_equal(a["bias"], b["bias"]) and not np.array_equal(a["bias"], c["bias"])
    assert np.all(np.diag(a["misalignment"]) == 0) and np.all(a["misalignment"][~np.eye(3, dtype=bool)] != 0)


def test_g_sensitivity_uses_true_specific_force():
    G = np.diag([1e-5, 2e-5, 3e-5])  # rad/s per m/s^2
    g = TriadErrors(g_sensitivity=G)
    dv = np.tile([0.0, 0.0, 9.8 * T], (10, 1))
    out = _model(g).apply(_block(10, dvel=dv))
    assert out.dtheta[:, 2] == pytest.approx(3e-5 * 9.8 * T, rel=1e-12)


def test_quantization_carries_the_residual():
    q = math.radians(0.1 / 3600)  # 0.1 arcsec pulses
    rng = np.random.default_rng(3)
    th = rng.uniform(-3 * q, 7 * q, size=(5000, 3))
    m = _model(TriadErrors(quantization=q))
    out = np.concatenate([m.apply(_block(1000, dtheta=th[i : i + 1000], start=i)).dtheta for i in range(0, 5000, 1000)])
    counts = out / q
    assert np.allclose(counts, np.round(counts), atol=1e-6)  # whole pulses
    # the running sum never drifts more than one pulse from the true angle
    assert np.abs(np.cumsum(out, 0) - np.cumsum(th, 0)).max() < q * (1 + 1e-9)


def test_saturation_clips_and_flags():
    rng_ = quantity("400 deg/s", "angular_rate", "deg/s")
    th = np.zeros((4, 3))
    th[1, 0] = 1.5 * rng_ * T
    th[2, 2] = -2.0 * rng_ * T
    out = _model(TriadErrors(range=rng_)).apply(_block(4, dtheta=th))
    assert out.dtheta[1, 0] == pytest.approx(rng_ * T) and out.dtheta[2, 2] == pytest.approx(-rng_ * T)
    assert list(out.status & 0x80) == [0, 0x80, 0x80, 0]


def test_blocking_does_not_change_the_output():
    g = TriadErrors(
        noise=np.full(3, 1e-5), bias_instability=np.full(3, 1e-6), bias_random_walk=np.full(3, 1e-8), quantization=1e-7
    )
    a = TriadErrors(noise=np.full(3, 1e-4), bias_instability=np.full(3, 1e-4), quantization=1e-5)
    th, v = _motion(3000)
    whole = _model(g, a).apply(_block(3000, dtheta=th, dvel=v))
    m = _model(g, a)
    parts = [
        m.apply(_block(n1 - n0, dtheta=th[n0:n1], dvel=v[n0:n1], start=n0))
        for n0, n1 in [(0, 1), (1, 1000), (1000, 1777), (1777, 3000)]
    ]
    assert np.array_equal(whole.dtheta, np.concatenate([p.dtheta for p in parts]))
    assert np.array_equal(whole.dvel, np.concatenate([p.dvel for p in parts]))


def test_same_seed_same_noise_other_seed_other_noise():
    g = TriadErrors(noise=np.full(3, 1e-5))
    a = _model(g, seed=5).apply(_block(100)).dtheta
    b = _model(g, seed=5).apply(_block(100)).dtheta
    c = _model(g, seed=6).apply(_block(100)).dtheta
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def _pooled_allan(x, dt):
    rs = [allan_deviation(x[:, i], dt) for i in range(3)]
    return AllanResult(rs[0].tau, np.sqrt(np.mean([r.adev**2 for r in rs], axis=0)), rs[0].n_terms * 3)


@pytest.mark.slow
def test_allan_recovers_arw_and_bias_instability_of_the_navigation_grade():
    # static data through the navigation grade's random terms (0.001 deg/sqrt(h),
    # 0.003 deg/h over 500 s; 10 ug/sqrt(Hz), 10 ug): Allan deviation read back within 10 %
    from bench.sensors.imu.grade import load_grade

    nav = load_grade("navigation")
    g = TriadErrors(
        noise=nav.gyro.noise,
        bias_instability=nav.gyro.bias_instability,
        bias_instability_tau=nav.gyro.bias_instability_tau,
    )
    a = TriadErrors(
        noise=nav.accel.noise,
        bias_instability=nav.accel.bias_instability,
        bias_instability_tau=nav.accel.bias_instability_tau,
    )
    rate = 5.0
    n = int(300_000 * rate)
    out = _model(g, a, seed=11, rate=rate).apply(_block(n, rate=rate))
    for x, e in ((out.dtheta, g), (out.dvel, a)):
        terms = read_noise_terms(_pooled_allan(x, 1 / rate), tau_c=float(e.bias_instability_tau[0]))
        assert terms["random_walk"] == pytest.approx(e.noise[0], rel=0.10)
        assert terms["bias_instability"] == pytest.approx(e.bias_instability[0], rel=0.10)


def test_allan_recovers_rate_random_walk():
    K = 1e-7  # rad/s/sqrt(s)
    N = 1e-6
    rate = 10.0
    n = 200_000
    out = _model(TriadErrors(noise=np.full(3, N), bias_random_walk=np.full(3, K)), seed=3, rate=rate).apply(
        _block(n, rate=rate)
    )
    terms = read_noise_terms(_pooled_allan(out.dtheta, 1 / rate))
    assert terms["random_walk"] == pytest.approx(N, rel=0.1)
    assert terms["rate_random_walk"] == pytest.approx(K, rel=0.15)
