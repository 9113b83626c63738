"""The geographic/grid filter-parameter conversion (bench.estimators.frame_switch)
against the nonlinear conversion of a true and a perturbed navigation state: each is
converted to the grid frame exactly (ECEF position, C_gG at its own grid angle) and their
difference compared with Phi x_g."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from bench.estimators.frame_switch import (
    conversion_matrix,
    covariance_to_geographic,
    covariance_to_grid,
    inverse_conversion_matrix,
    state_to_geographic,
    state_to_grid,
    switch_defined,
    to_geographic,
    to_grid,
)
from bench.nav import earth, grid
from bench.nav.rotation import euler_to_dcm


def _skew(x: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def _to_grid_exact(lat, lon, h, v_g, C_bg):
    """(r_e, v_G, C_bG) of a geographic navigation state."""
    CgG = grid.C_gG(float(grid.grid_angle(lat, lon)))
    return earth.geodetic_to_ecef(lat, lon, h), CgG @ v_g, CgG @ C_bg


def _perturbed(lat, lon, h, v_g, C_bg, x):
    """The computed state of a true one and an error x (phi_g, dv_g, dr in m E, N, U)."""
    rm, rn = earth.radii(lat)
    return (
        lat + x[7] / (rm + h),
        lon + x[6] / ((rn + h) * math.cos(lat)),
        h + x[8],
        v_g + x[3:6],
        expm(-_skew(x[0:3])) @ C_bg,
    )


def _grid_errors(true, comp):
    """phi_G, dv_G, dP_e of a computed grid state against the true one."""
    M = comp[2] @ true[2].T  # I - [phi x]
    phi = -0.5 * np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])
    return np.concatenate([phi, comp[1] - true[1], comp[0] - true[0]])


SITES = {
    "S003a 88 N 10 E": (88.0, 10.0),
    "S003b Nanjing, sigma 136 deg": (31.939, 118.790),
    "89.9 N": (89.899, -63.0),
    "70 S": (-70.0, -150.0),
}
V_G_SITE = np.array([-14.0, 13.0, 0.6])


def _site(name):
    lat_deg, lon_deg = SITES[name]
    lat, lon, h = math.radians(lat_deg), math.radians(lon_deg), 350.0
    sigma = float(grid.grid_angle(lat, lon))
    v_g = grid.C_gG(sigma).T @ V_G_SITE
    return lat, lon, h, v_g, euler_to_dcm(0.8, 0.03, -0.05)


def test_the_nanjing_site_has_a_grid_angle_of_136_degrees():
    lat, lon, *_ = _site("S003b Nanjing, sigma 136 deg")
    assert math.degrees(float(grid.grid_angle(lat, lon))) == pytest.approx(136.1, abs=0.1)


@pytest.mark.parametrize("name", list(SITES))
def test_phi_maps_geographic_errors_to_the_grid_errors_of_the_nonlinear_conversion(name):
    lat, lon, h, v_g, C_bg = _site(name)
    rng = np.random.default_rng(7)
    true = _to_grid_exact(lat, lon, h, v_g, C_bg)
    Phi = np.zeros((15, 15))
    assert conversion_matrix(lat, lon, h, true[1], Phi)
    for _ in range(5):
        x = np.zeros(15)
        x[0:3] = rng.uniform(-1e-5, 1e-5, 3)  # rad
        x[3:6] = rng.uniform(-0.01, 0.01, 3)  # m/s
        x[6:9] = rng.uniform(-1.0, 1.0, 3)  # m
        residual = []
        for k in (1.0, 0.5):
            got = _grid_errors(true, _to_grid_exact(*_perturbed(lat, lon, h, v_g, C_bg, k * x)))
            want = (Phi @ (k * x))[0:9]
            residual.append(np.abs(got - want))
            for b in (0, 3, 6):
                # the first-order terms of the block (the grid angle's near the pole are
                # ~1e-4 rad and ~1e-3 m/s a metre); what is left is second order, up to
                # dr^2 / (R cos L) near the pole (a metre east is on a small circle)
                first = np.abs(want[b : b + 3]).max()
                assert residual[-1][b : b + 3].max() <= 1e-3 * first, (name, b, got, want)
        # and it is second order: halving the error quarters it (above the rounding)
        floor = np.repeat([1e-15, 1e-13, 1e-8], 3)
        assert np.all(residual[1] <= 0.3 * residual[0] + floor), (name, residual)
        # the grid angle's terms (T1 on phi, T2 on dv) are resolved far above the residual
        T = Phi[0:9, 6:9] @ x[6:9]
        assert abs(T[2]) > 100 * residual[0][2]
        assert np.abs(T[3:5]).max() > 100 * residual[0][3:5].max()


def test_east_and_north_are_not_swapped():
    # at 88 N 10 E the grid angle turns 27 times faster per metre east than north
    lat, lon, h, v_g, C_bg = _site("S003a 88 N 10 E")
    true = _to_grid_exact(lat, lon, h, v_g, C_bg)
    ds = grid.dsigma_denu(lat, lon, h)
    assert abs(ds[0]) > 20 * abs(ds[1])
    Phi = np.zeros((15, 15))
    conversion_matrix(lat, lon, h, true[1], Phi)
    for axis in (0, 1):
        x = np.zeros(15)
        x[6 + axis] = 1.0
        got = _grid_errors(true, _to_grid_exact(*_perturbed(lat, lon, h, v_g, C_bg, x)))
        # the computed grid frame turns by d sigma: phi_G = -d sigma e_z
        assert got[2] == pytest.approx(-ds[axis], rel=1e-5)
        assert (Phi @ x)[2] == pytest.approx(-ds[axis], rel=1e-12)
        # the ECEF position error is one metre along that axis, east or north
        assert np.allclose(got[6:9], earth.C_en(lat, lon)[axis], atol=1e-6)


def _random_covariance(n, rng):
    A = rng.normal(size=(n, n))
    s = np.concatenate([[1e-4] * 3, [0.1] * 3, [10.0] * 3, [1e-6] * 3, [1e-3] * 3, [0.5] * (n - 15)])
    return (A @ A.T / n + np.eye(n)) * np.outer(s, s)


@pytest.mark.parametrize("name", list(SITES))
def test_the_round_trip_restores_state_and_covariance(name):
    lat, lon, h, _, _ = _site(name)
    v_G = V_G_SITE
    rng = np.random.default_rng(3)
    n = 17  # two extra states beyond the core
    P0 = _random_covariance(n, rng)
    x0 = rng.normal(size=n) * np.sqrt(np.diag(P0))
    P, x = P0.copy(), x0.copy()
    assert covariance_to_grid(P, lat, lon, h, v_G)
    assert state_to_grid(x, lat, lon, h, v_G)
    Phi = np.zeros((15, 15))
    conversion_matrix(lat, lon, h, v_G, Phi)
    assert np.allclose(x[:15], Phi @ x0[:15], rtol=1e-14, atol=1e-14 * np.abs(x0).max())
    assert np.array_equal(x[15:], x0[15:])
    # the extra states: own block untouched, cross terms transformed with the core
    assert np.array_equal(P[15:, 15:], P0[15:, 15:])
    assert np.allclose(P[:15, 15:], Phi @ P0[:15, 15:], rtol=1e-13, atol=1e-20)
    assert np.array_equal(P, P.T)
    assert np.linalg.eigvalsh(P).min() > 0.0
    assert np.allclose(P[:15, :15], Phi @ P0[:15, :15] @ Phi.T, rtol=1e-12, atol=1e-25)
    assert covariance_to_geographic(P, lat, lon, h, v_G)
    assert state_to_geographic(x, lat, lon, h, v_G)
    scale = np.sqrt(np.outer(np.diag(P0), np.diag(P0)))
    assert np.all(np.abs(P - P0) <= 1e-12 * scale)
    assert np.all(np.abs(x - x0) <= 1e-12 * np.sqrt(np.diag(P0)))
    assert np.array_equal(P, P.T)
    # the closed-form inverse is the inverse
    Psi = np.zeros((15, 15))
    inverse_conversion_matrix(lat, lon, h, v_G, Psi)
    assert np.allclose(Psi @ Phi, np.eye(15), atol=1e-12)
    assert np.allclose(Phi @ Psi, np.eye(15), atol=1e-12)


@pytest.mark.parametrize(
    ("lat_deg", "lon_deg"),
    [(89.95, 10.0), (-90.0, 0.0), (0.5, 88.0), (3.0, -92.0)],
    ids=["near the pole", "the south pole", "grid frame at 88 E", "grid frame at 92 W"],
)
def test_the_switch_is_refused_where_a_frame_is_singular(lat_deg, lon_deg):
    lat, lon, h = math.radians(lat_deg), math.radians(lon_deg), 0.0
    assert not switch_defined(lat, lon)
    rng = np.random.default_rng(1)
    P0 = _random_covariance(15, rng)
    x0 = rng.normal(size=15)
    P, x, Phi = P0.copy(), x0.copy(), np.full((15, 15), 3.0)
    v = np.array([10.0, 0.0, 0.0])
    assert not conversion_matrix(lat, lon, h, v, Phi)
    assert not inverse_conversion_matrix(lat, lon, h, v, Phi)
    assert not covariance_to_grid(P, lat, lon, h, v)
    assert not covariance_to_geographic(P, lat, lon, h, v)
    assert not state_to_grid(x, lat, lon, h, v)
    assert not state_to_geographic(x, lat, lon, h, v)
    assert np.array_equal(P, P0) and np.array_equal(x, x0) and np.all(Phi == 3.0)
    for convert in (to_grid, to_geographic):
        with pytest.raises(ValueError, match="refused"):
            convert(x, P, lat, lon, h, v)
    assert np.array_equal(P, P0) and np.array_equal(x, x0)


def test_the_python_wrappers_convert_both_and_check_shapes():
    lat, lon, h, _, _ = _site("S003a 88 N 10 E")
    rng = np.random.default_rng(5)
    P0 = _random_covariance(15, rng)
    x0 = rng.normal(size=15) * np.sqrt(np.diag(P0))
    P, x = P0.copy(), x0.copy()
    to_grid(x, P, lat, lon, h, V_G_SITE)
    assert not np.allclose(x, x0)
    to_geographic(x, P, lat, lon, h, V_G_SITE)
    assert np.allclose(x, x0, rtol=1e-12, atol=0) and np.allclose(P, P0, rtol=1e-11, atol=0)
    with pytest.raises(ValueError, match="n >= 15"):
        to_grid(np.zeros(9), np.zeros((9, 9)), lat, lon, h, V_G_SITE)
