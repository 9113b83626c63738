"""The core INS error model against the bench's own mechanization: every column of the
error-transition matrix is checked by perturbing one error state, running the strapdown
mechanization twice (true and perturbed) on the same increments and comparing the error
that results with Phi times the perturbation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from bench.estimators.ins_model import N_CORE, discretize, euler_jacobian, ins_error_matrix, position_difference
from bench.nav.rotation import euler_to_dcm, quat_mul, quat_to_dcm, rotvec_to_quat
from bench.nav.strapdown import NavState, Strapdown

RATE = 200.0
T = 1.0 / RATE


def _motion(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Increments of a turning, accelerating, climbing vehicle (body rates and forces)."""
    k = np.arange(n)[:, None]
    w = np.array([0.002, 0.001, 0.05]) + 0.01 * np.sin(0.7 * k * T) * np.array([1.0, 0.0, 0.5])
    f = np.array([0.3, 1.2, 9.81]) + 0.2 * np.cos(0.5 * k * T) * np.array([1.0, 1.0, 0.0])
    return w * T, f * T


def _errors(true: NavState, comp: NavState) -> np.ndarray:
    """(9,) phi, dv, dr of a computed solution against the true one."""
    Ct, Cc = quat_to_dcm(true.q_bn), quat_to_dcm(comp.q_bn)
    M = Ct @ Cc.T  # = I + [phi x]
    phi = 0.5 * np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])
    d = np.zeros(3)
    position_difference(comp.lat, comp.lon, comp.h, true.lat, true.lon, true.h, d)
    return np.concatenate([phi, comp.vel_n - true.vel_n, d])


def _perturbed(s: NavState, dx: np.ndarray) -> NavState:
    from bench.nav.earth import radii

    rm, rn = radii(s.lat)
    q = quat_mul(rotvec_to_quat(-dx[0:3]), s.q_bn)  # C_c = (I - [phi x]) C
    return NavState(
        s.lat + dx[7] / (rm + s.h),
        s.lon + dx[6] / ((rn + s.h) * math.cos(s.lat)),
        s.h + dx[8],
        s.vel_n + dx[3:6],
        q,
    )


# perturbation sizes: small enough to be linear, large enough to beat rounding
SIZES = [1e-4] * 3 + [0.05] * 3 + [5.0] * 3 + [2e-6] * 3 + [2e-3] * 3


@pytest.mark.parametrize("lat_deg", [34.246, 70.0])
def test_every_column_of_the_error_model_matches_the_mechanization(lat_deg):
    n = 1000  # 5 s
    dth, dv = _motion(n)
    lat = math.radians(lat_deg)
    s0 = NavState(lat, 1.9, 380.0, np.array([8.0, 12.0, 0.5]), euler_to_dcm_q(0.6, 0.03, -0.02))
    truth = Strapdown(s0)
    states = []
    f_sum = np.zeros(3)
    for k in range(n):
        truth.step(dth[k], dv[k], T)
        C = quat_to_dcm(truth.state.q_bn)
        f_sum += C @ dv[k]
        states.append(truth.state)
    end = truth.state
    # F at the middle of the stretch, averaged specific force
    mid = states[n // 2]
    F = np.zeros((N_CORE, N_CORE))
    ins_error_matrix(F, mid.lat, mid.h, mid.vel_n, f_sum / (n * T), quat_to_dcm(mid.q_bn))
    Phi = expm(F * n * T)
    for j in range(N_CORE):
        dx = np.zeros(N_CORE)
        dx[j] = SIZES[j]
        sd = Strapdown(_perturbed(s0, dx))
        for k in range(n):
            sd.step(dth[k] + dx[9:12] * T, dv[k] + dx[12:15] * T, T)
        got = _errors(end, sd.state)
        want = (Phi @ dx)[:9]
        scale = np.abs(want) / np.array(SIZES[:9]) + np.abs(got) / np.array(SIZES[:9])
        rel = np.abs(got - want) / np.array(SIZES[:9])
        # each error component agrees to 3 % of the larger of the two responses (or a
        # floor of 1e-3 of the perturbation unit where both are ~0)
        assert np.all(rel <= 0.03 * scale + 2e-3), (j, got, want)


def euler_to_dcm_q(psi, theta, gamma):
    from bench.nav.rotation import dcm_to_quat

    return dcm_to_quat(euler_to_dcm(psi, theta, gamma))


def test_discretization_matches_the_matrix_exponential():
    rng = np.random.default_rng(3)
    F = rng.normal(size=(6, 6)) * 0.05
    Qc = np.diag(rng.uniform(0.1, 1.0, 6))
    Phi, Qd = np.zeros((6, 6)), np.zeros((6, 6))
    discretize(F, Qc, 0.1, Phi, Qd)
    assert np.allclose(Phi, expm(F * 0.1), atol=1e-5)
    # Van Loan's exact Qd
    n = 6
    A = np.zeros((2 * n, 2 * n))
    A[:n, :n] = -F
    A[:n, n:] = Qc
    A[n:, n:] = F.T
    B = expm(A * 0.1)
    Qd_exact = B[n:, n:].T @ B[:n, n:]
    # second order: agrees to (F T)^2 of the noise injected
    assert np.allclose(Qd, Qd_exact, rtol=0, atol=2e-3 * np.abs(Qd_exact).max())


def test_euler_jacobian_matches_finite_differences():
    from bench.nav.rotation import dcm_to_euler, wrap_pi

    C = euler_to_dcm(2.2, 0.3, -0.4)
    J = np.zeros((3, 3))
    euler_jacobian(C, J)
    for k in range(3):
        phi = np.zeros(3)
        phi[k] = 1e-6
        Cc = (np.eye(3) - np.array([[0, -phi[2], phi[1]], [phi[2], 0, -phi[0]], [-phi[1], phi[0], 0]])) @ C
        d = wrap_pi(np.array(dcm_to_euler(Cc)) - np.array(dcm_to_euler(C)))
        assert np.allclose(d / 1e-6, J[:, k], atol=1e-4)


def test_scale_factor_columns_match_the_mechanization():
    # the linear model integrated interval by interval along the true trajectory (the
    # body rates vary by more than their mean, so one F for the stretch would not do)
    from bench.estimators.ins_model import scale_factor_columns

    n = 1000
    dth, dv = _motion(n)
    s0 = NavState(math.radians(34.0), 1.9, 380.0, np.array([8.0, 12.0, 0.5]), euler_to_dcm_q(0.6, 0.03, -0.02))
    truth = Strapdown(s0)
    Phi = np.eye(N_CORE + 6)
    F = np.zeros((N_CORE + 6, N_CORE + 6))
    for k in range(n):
        before = truth.state
        truth.step(dth[k], dv[k], T)
        C = quat_to_dcm(truth.state.q_bn)
        F[:, :] = 0.0
        sub = np.zeros((N_CORE, N_CORE))
        ins_error_matrix(sub, before.lat, before.h, before.vel_n, C @ dv[k] / T, C)
        F[:N_CORE, :N_CORE] = sub
        scale_factor_columns(F, N_CORE, C, dth[k] / T, dv[k] / T)
        Phi = expm(F * T) @ Phi
    for j in range(6):
        size = 1e-3
        sf = np.zeros(6)
        sf[j] = size
        sd = Strapdown(s0)
        for k in range(n):
            sd.step(dth[k] * (1 + sf[:3]), dv[k] * (1 + sf[3:]), T)
        got = _errors(truth.state, sd.state)
        dx = np.zeros(N_CORE + 6)
        dx[N_CORE + j] = size
        want = (Phi @ dx)[:9]
        assert np.allclose(got, want, rtol=0.05, atol=0.01 * np.abs(want).max()), (j, got, want)
