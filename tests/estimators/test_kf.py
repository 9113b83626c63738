"""The Kalman filter core: Joseph form with solves equals the textbook update, and the
innovations of a filter matched to its system are chi-square distributed."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from bench.estimators.kf import KalmanFilter, joseph_update, nis, time_update


def _spd(rng, n):
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


def test_joseph_update_equals_the_textbook_update():
    rng = np.random.default_rng(1)
    n, m = 7, 3
    P = _spd(rng, n)
    H = rng.normal(size=(m, n))
    R = _spd(rng, m) * 0.1
    z = rng.normal(size=m)
    x = np.zeros(n)
    P1 = P.copy()
    S = joseph_update(x, P1, z, H, R)
    # textbook: K = P H' S^-1, P+ = (I - K H) P   (explicit inverse only here, as a reference)
    S_ref = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S_ref)
    assert np.allclose(S, S_ref)
    assert np.allclose(x, K @ z)
    assert np.allclose(P1, (np.eye(n) - K @ H) @ P, atol=1e-10)
    assert np.allclose(P1, P1.T)
    assert np.isclose(nis(z, S), z @ np.linalg.solve(S_ref, z))


def test_joseph_form_keeps_a_widely_scaled_covariance_positive():
    # a covariance spanning 1e-14 (rad^2) to 1e4 (m^2): the Joseph form keeps it symmetric
    # and positive
    n = 4
    P = np.diag([1e-14, 1e-10, 1.0, 1e4])
    P[0, 3] = P[3, 0] = 0.99 * np.sqrt(1e-14 * 1e4)
    H = np.array([[0.0, 0.0, 0.0, 1.0]])
    R = np.array([[1e-8]])
    x = np.zeros(n)
    joseph_update(x, P, np.array([1.0]), H, R)
    assert np.all(np.linalg.eigvalsh(P) > -1e-20)


def test_sequential_equals_batch_for_uncorrelated_noise():
    rng = np.random.default_rng(2)
    n, m = 6, 4
    P0 = _spd(rng, n)
    H = rng.normal(size=(m, n))
    r = rng.uniform(0.1, 1.0, m)
    z = rng.normal(size=m)
    a, b = KalmanFilter(P0), KalmanFilter(P0)
    a.update(z, H, np.diag(r))
    b.update_sequential(z, H, r)
    assert np.allclose(a.x, b.x)
    assert np.allclose(a.P, b.P)


def test_innovations_of_a_matched_filter_are_chi_square():
    # constant-velocity target, position measured: normalised innovations squared follow
    # chi-square(1); the time-averaged NIS lies in its 99 % interval
    rng = np.random.default_rng(5)
    dt, q, r = 0.1, 0.5, 0.3
    Phi = np.array([[1.0, dt], [0.0, 1.0]])
    Qd = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    H = np.array([[1.0, 0.0]])
    R = np.array([[r**2]])
    kf = KalmanFilter(np.diag([1.0, 1.0]))
    truth = np.zeros(2)
    est = np.zeros(2)
    L = np.linalg.cholesky(Qd)
    out = []
    for _ in range(3000):
        truth = Phi @ truth + L @ rng.normal(size=2)
        est = Phi @ est
        kf.predict(Phi, Qd)
        z = H @ truth + r * rng.normal(size=1)
        out.append(kf.update(z - H @ est, H, R))
        est = est + kf.feedback()
    v = np.mean(out[100:])
    k = len(out) - 100
    lo, hi = chi2.ppf([0.005, 0.995], k) / k
    assert lo <= v <= hi, v


def test_time_update_is_phi_p_phi_plus_q():
    rng = np.random.default_rng(4)
    P = _spd(rng, 5)
    Phi = np.eye(5) + 0.1 * rng.normal(size=(5, 5))
    Q = _spd(rng, 5) * 0.01
    want = Phi @ P @ Phi.T + Q
    time_update(P, Phi, Q)
    assert np.allclose(P, want)
