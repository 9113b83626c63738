"""The polar grid frame of seed 003 (bench.nav.grid): its angle, its rotations, the pole."""

from __future__ import annotations

import numpy as np
import pytest

from bench.nav import earth
from bench.nav.grid import C_eG, C_gG, dsigma_denu, grid_angle

RNG = np.random.default_rng(11)
LAT = np.radians(np.concatenate([RNG.uniform(-89.9, 89.9, 300), [88.0, 89.99, -88.0, 31.939, 87.95]]))
LON = np.radians(np.concatenate([RNG.uniform(-180.0, 180.0, 300), [10.0, -170.0, 45.0, 118.790, 0.0]]))


def test_grid_north_is_parallel_to_the_greenwich_meridian_plane_and_sigma_turns_true_north_into_it():
    Ce = C_eG(LAT, LON)
    assert np.allclose(Ce @ np.swapaxes(Ce, -1, -2), np.eye(3), atol=1e-14)  # orthonormal
    assert np.allclose(np.linalg.det(Ce), 1.0)  # right-handed
    assert np.allclose(Ce[:, 1, 1], 0.0, atol=1e-15)  # grid north has no ECEF y component
    n = earth.C_en(LAT, LON)
    assert np.allclose(Ce[:, 2], n[:, 2], atol=1e-15)  # the same up
    sigma = grid_angle(LAT, LON)
    # sigma: from true north to grid north, east positive
    cos_s = np.einsum("ni,ni->n", n[:, 1], Ce[:, 1])
    sin_s = np.einsum("ni,ni->n", n[:, 0], Ce[:, 1])
    assert np.allclose(np.arctan2(sin_s, cos_s), sigma, atol=1e-12)
    assert np.allclose(np.tan(sigma), np.sin(LAT) * np.tan(LON), rtol=1e-9, atol=1e-12)
    # seed eq. 25: v_G = C_gG v_g, so C_eG = C_gG C_en
    assert np.allclose(C_gG(sigma) @ n, Ce, atol=1e-13)


def test_at_the_poles_the_grid_frame_is_defined_and_sigma_is_the_longitude():
    lon = np.radians(np.array([-179.0, -90.0, 0.0, 37.0, 90.0, 180.0]))
    for pole, sign in ((np.pi / 2, 1.0), (-np.pi / 2, -1.0)):
        lat = np.full_like(lon, pole)
        Ce = C_eG(lat, lon)
        assert np.all(np.isfinite(Ce))
        assert np.allclose(Ce @ np.swapaxes(Ce, -1, -2), np.eye(3), atol=1e-14)
        assert np.allclose(np.angle(np.exp(1j * (grid_angle(lat, lon) - sign * lon))), 0.0, atol=1e-12)
        # the grid frame at the pole does not depend on the longitude it is approached along
        assert np.allclose(Ce, Ce[0], atol=1e-12)


def test_the_grid_angle_gradient_matches_a_finite_displacement():
    lat = np.radians(np.array([88.0, 89.9, 60.0, -85.0, 31.939, 87.95]))
    lon = np.radians(np.array([10.0, -120.0, 75.0, 170.0, 118.790, 0.0]))
    h = np.array([60.0, 0.0, 300.0, 10.0, 20.0, 0.0])
    g = dsigma_denu(lat, lon, h)
    step = 0.5  # m
    for k in range(len(lat)):
        for axis in range(3):
            d = np.zeros(3)
            d[axis] = step
            pts = []
            for sgn in (1.0, -1.0):
                xyz = earth.enu_to_ecef(sgn * d, lat[k], lon[k], h[k])
                la, lo, _ = earth.ecef_to_geodetic(xyz)
                pts.append(grid_angle(la, lo))
            fd = float(np.angle(np.exp(1j * (pts[0] - pts[1])))) / (2 * step)
            assert fd == pytest.approx(g[k, axis], rel=1e-5, abs=1e-13), (k, axis)
    # near the pole the grid angle turns fast with a step east: 20 m at 88 N, 10 E is 0.3 arcmin
    assert np.degrees(g[0, 0] * 20.0) * 60.0 == pytest.approx(0.31, abs=0.01)


def test_the_compiled_scalar_ports_equal_the_vectorised_functions():
    from bench.nav.grid import C_eG_s, C_gG_s, dsigma_denu_s, grid_angle_s

    h = 250.0
    lat = np.concatenate([LAT, [np.pi / 2, -np.pi / 2]])
    lon = np.concatenate([LON, [0.7, -2.1]])
    out3, out33 = np.zeros(3), np.zeros((3, 3))
    for la, lo in zip(lat, lon, strict=True):
        s = grid_angle_s(la, lo)
        assert s == pytest.approx(float(grid_angle(la, lo)), abs=1e-15)
        C_gG_s(s, out33)
        assert np.allclose(out33, C_gG(s), atol=1e-15)
        C_eG_s(la, lo, out33)
        assert np.allclose(out33, C_eG(la, lo), atol=1e-15)
        if abs(la) < np.pi / 2 - 1e-6:
            dsigma_denu_s(la, lo, h, out3)
            want = dsigma_denu(la, lo, h)
            assert np.allclose(out3, want, rtol=1e-13, atol=1e-25)
