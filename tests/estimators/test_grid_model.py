"""The grid-frame INS error model (bench.estimators.grid_model) against the nonlinear
continuous-time dynamics in G with an ECEF position, written here independently: the
transport rate of the reference is the rate at which the grid frame of
:func:`bench.nav.grid.C_eG` turns along the motion (a central difference), not the
module's formula. Every column of F is compared with the central difference of the error
rates of a true and a perturbed state, at 60 deg, near the pole, at both poles."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from bench.estimators.grid_model import N_CORE, grid_error_matrix, transport_rate_grid
from bench.estimators.ins_model import ins_error_matrix
from bench.nav import earth, grid
from bench.nav.rotation import euler_to_dcm


def _skew(x: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def _vee(M: np.ndarray) -> np.ndarray:
    return 0.5 * np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])


def _frame(r: np.ndarray) -> tuple[np.ndarray, float, float]:
    lat, lon, h = earth.ecef_to_geodetic(r)
    return grid.C_eG(lat, lon), float(lat), float(h)


def _transport_rate(r: np.ndarray, v_G: np.ndarray) -> np.ndarray:
    """w_eG^G as the turning rate of C_eG along the motion: C_eG' = -[w x] C_eG."""
    C, _, _ = _frame(r)
    v_e = C.T @ v_G
    dt = 20.0
    dC = (_frame(r + v_e * dt)[0] - _frame(r - v_e * dt)[0]) / (2.0 * dt)
    return -_vee(dC @ C.T)


def _rates(r, v_G, C_bG, f_b, w_ib):
    """Nonlinear dynamics in G: (r', v_G', C_bG')."""
    C, lat, h = _frame(r)
    w_ie = C @ np.array([0.0, 0.0, earth.OMEGA_IE])
    w_eG = _transport_rate(r, v_G)
    g = np.array([0.0, 0.0, -float(earth.gravity(lat, h))])
    rdot = C.T @ v_G
    vdot = C_bG @ f_b - np.cross(2.0 * w_ie + w_eG, v_G) + g
    Cdot = C_bG @ _skew(w_ib) - _skew(w_ie + w_eG) @ C_bG
    return rdot, vdot, Cdot


def _error_rate(true, x, f_b, w_ib):
    """The rates of phi_G, dv_G, dP_e of the state ``true`` perturbed by the error ``x``."""
    r, v, Cb = true
    rc, vc, Cc = r + x[6:9], v + x[3:6], expm(-_skew(x[0:3])) @ Cb
    rt_dot, vt_dot, Ct_dot = _rates(r, v, Cb, f_b, w_ib)
    rc_dot, vc_dot, Cc_dot = _rates(rc, vc, Cc, f_b + x[12:15], w_ib + x[9:12])
    # C_c C_t' = I - [phi x]: phi' = -vee(d/dt (C_c C_t'))
    phidot = -_vee(Cc_dot @ Cb.T + Cc @ Ct_dot.T)
    return np.concatenate([phidot, vc_dot - vt_dot, rc_dot - rt_dot])


F_B = np.array([0.4, -0.7, 9.9])
W_IB = np.array([0.01, -0.02, 0.03])
# perturbation sizes (central differences: the second-order terms cancel)
SIZES = [1e-3] * 3 + [1.0] * 3 + [100.0] * 3 + [1e-4] * 3 + [1e-2] * 3


def _setup(lat_deg, lon_deg, v_G):
    lat, lon, h = math.radians(lat_deg), math.radians(lon_deg), 500.0
    r = earth.geodetic_to_ecef(lat, lon, h)
    C, _, _ = _frame(r)
    C_bG = euler_to_dcm(2.3, 0.05, -0.1)
    F = np.zeros((N_CORE + 2, N_CORE + 2))
    F[N_CORE:, :] = 7.0  # outside the core: left alone
    grid_error_matrix(F, lat, h, C, v_G, C_bG @ F_B, C_bG)
    assert np.all(F[N_CORE:, :] == 7.0)
    return (r, v_G, C_bG), F[:N_CORE, :N_CORE], C


CASES = [
    (60.0, 40.0, [14.0, -13.0, 1.5]),
    (88.0, 10.0, [-9.0, 17.0, -0.8]),
    (89.99, -120.0, [19.0, 5.0, 0.3]),
    (90.0, 0.0, [-12.0, -16.0, 2.0]),
    (-90.0, 0.0, [3.0, 19.5, -1.0]),
    (-87.0, 150.0, [200.0, -120.0, 5.0]),  # an aircraft's speed: the position terms of w_eG count
]


@pytest.mark.parametrize(("lat_deg", "lon_deg", "v"), CASES)
def test_every_column_of_the_grid_error_model_matches_the_nonlinear_dynamics(lat_deg, lon_deg, v):
    true, F, C = _setup(lat_deg, lon_deg, np.array(v))
    assert np.all(np.isfinite(F))
    # the columns, then a position error along grid east, north and up (separating the
    # level terms from the much larger free-air gradient)
    dirs = [np.eye(N_CORE)[j] * SIZES[j] for j in range(N_CORE)]
    for k in range(3):
        x = np.zeros(N_CORE)
        x[6:9] = C[k] * 100.0  # C_Ge e_k
        dirs.append(x)
    for x in dirs:
        got = 0.5 * (_error_rate(true, x, F_B, W_IB) - _error_rate(true, -x, F_B, W_IB))
        want = F @ x
        for b in range(3):
            # phi, dv, dP rows: 1e-4 of each element, 1e-5 of the block's largest (the
            # reference's rounding and its central difference in time), and a floor far
            # below the smallest term of the model (the transport rate's position terms,
            # ~5e-11 rad/s for 100 m at 20 m/s; the gravity's latitude term, ~7e-7 m/s^2)
            g, w = got[3 * b : 3 * b + 3], want[3 * b : 3 * b + 3]
            floor = [1e-13, 1e-10, 1e-12][b]  # rad/s, m/s^2, m/s
            tol = 1e-4 * np.abs(w) + 1e-5 * np.abs(w).max() + floor
            assert np.all(np.abs(g - w) <= tol), (b, x, g, w)


def test_the_position_terms_of_the_transport_rate_are_not_negligible_for_an_aircraft():
    # at 250 m/s they are a sizeable part of the attitude rows' position columns
    lat, h = math.radians(-87.0), 500.0
    C = grid.C_eG(lat, math.radians(150.0))
    v = np.array([200.0, -120.0, 5.0])
    F = np.zeros((N_CORE, N_CORE))
    grid_error_matrix(F, lat, h, C, v, np.zeros(3), np.eye(3))
    F0 = np.zeros((N_CORE, N_CORE))
    grid_error_matrix(F0, lat, h, C, np.zeros(3), np.zeros(3), np.eye(3))
    moving = np.abs(F[0:3, 6:9] - F0[0:3, 6:9]).max()
    assert moving > 0.3 * np.abs(F0[0:3, 6:9]).max()


@pytest.mark.parametrize("lat_deg", [90.0, -90.0, 89.99])
def test_the_transport_rate_is_finite_at_the_pole_and_agrees_with_the_turning_of_the_grid_frame(lat_deg):
    lat, h = math.radians(lat_deg), 300.0
    for lon_deg in (0.0, 75.0, -160.0):
        r = earth.geodetic_to_ecef(lat, math.radians(lon_deg), h)
        C, _, _ = _frame(r)
        v = np.array([15.0, -11.0, 0.7])
        out = np.zeros(3)
        transport_rate_grid(lat, h, C, v, out)
        assert np.all(np.isfinite(out))
        assert np.allclose(out, _transport_rate(r, v), rtol=0, atol=1e-13)
        if abs(lat_deg) == 90.0:  # on the axis: the sphere of radius R_N + h, no vertical part
            _, rn = earth.radii(lat)
            want = [-v[1] / (rn + h), v[0] / (rn + h), 0.0]
            assert np.allclose(out, want, rtol=1e-12, atol=1e-20)  # cos(pi/2) is 6e-17


def test_the_grid_transport_rate_is_the_geographic_one_turned_less_the_grid_angle_rate():
    lat, lon, h = math.radians(60.0), math.radians(40.0), 500.0
    sigma = float(grid.grid_angle(lat, lon))
    CgG = grid.C_gG(sigma)
    v_g = np.array([14.0, -13.0, 1.5])
    v_G = CgG @ v_g
    out = np.zeros(3)
    transport_rate_grid(lat, h, grid.C_eG(lat, lon), v_G, out)
    sigma_dot = float(grid.dsigma_denu(lat, lon, h) @ v_g)
    want = CgG @ earth.transport_rate_n(lat, h, v_g) - np.array([0.0, 0.0, sigma_dot])
    assert np.allclose(out, want, rtol=1e-12, atol=1e-20)
    assert abs(sigma_dot) > 1e-7  # the grid angle term is there


@pytest.mark.parametrize("lat_deg", [60.0, 85.0])
def test_the_grid_model_is_the_geographic_one_transformed(lat_deg):
    # X_G = Phi X_g, so F_G = Phi F_g Phi^-1 + Phi' Phi^-1. On the attitude and velocity
    # rows and columns, Phi^-1 maps them by C_Gg alone, and Phi' there is sigma' [e_z x]
    # on both: F_G = C F_g C' + [[0, -T1], [0, T2]] F_g[6:9, 0:6] C' + sigma' [e_z x].
    lat, lon, h = math.radians(lat_deg), math.radians(-35.0), 800.0
    sigma = float(grid.grid_angle(lat, lon))
    CgG = grid.C_gG(sigma)
    v_g = np.array([12.0, -16.0, 0.4])  # 20 m/s
    C_bg = euler_to_dcm(1.1, 0.02, 0.04)
    f_g = C_bg @ F_B
    Fg = np.zeros((N_CORE, N_CORE))
    ins_error_matrix(Fg, lat, h, v_g, f_g, C_bg)
    FG = np.zeros((N_CORE, N_CORE))
    v_G = CgG @ v_g
    grid_error_matrix(FG, lat, h, grid.C_eG(lat, lon), v_G, CgG @ f_g, CgG @ C_bg)
    B = np.kron(np.eye(2), CgG)
    ds = grid.dsigma_denu(lat, lon, h)
    ez = np.array([0.0, 0.0, 1.0])
    T = np.zeros((6, 3))
    T[0:3] = -np.outer(ez, ds)
    T[3:6] = np.outer(np.cross(ez, v_G), ds)
    want = B @ Fg[0:6, 0:6] @ B.T + T @ Fg[6:9, 0:6] @ B.T
    want += np.kron(np.eye(2), float(ds @ v_g) * _skew(ez))
    for r in (0, 3):  # block by block: their scales differ by 1e8
        for c in (0, 3):
            got, w = FG[r : r + 3, c : c + 3], want[r : r + 3, c : c + 3]
            assert np.allclose(got, w, rtol=1e-9, atol=1e-9 * np.abs(w).max()), (r, c, got, w)
    # and the gyro and accelerometer bias columns
    assert np.allclose(FG[0:6, 9:15], B @ Fg[0:6, 9:15], atol=1e-15)
