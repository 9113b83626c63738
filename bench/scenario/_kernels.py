"""Compiled kernels of the scenario layer (numba): the position integration grid.

Kept apart so that the numerical code stays readable in :mod:`bench.scenario.profile`
and the compiler is used in one place of the layer.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav.earth import E2, A, B

__all__ = ["integrate_profile_position", "integrate_profile_ecef", "hermite_position"]


@njit(cache=True)
def _channels(c: np.ndarray, x: np.ndarray, t: float, j: int, out: np.ndarray) -> int:
    """Evaluate channels 0..5 of the merged PPoly at t; j is the piece hint (returned)."""
    m = x.shape[0] - 1
    while j + 1 < m and t >= x[j + 1]:
        j += 1
    tau = t - x[j]
    deg = c.shape[0] - 1
    for ch in range(6):
        acc = 0.0
        for n in range(deg + 1):
            acc = acc * tau + c[n, j, ch]
        out[ch] = acc
    return j


@njit(cache=True)
def integrate_profile_position(
    c: np.ndarray,
    x: np.ndarray,
    n: int,
    dt: float,
    lat0: float,
    lon0: float,
    h0: float,
    grid: np.ndarray,
    grid_rate: np.ndarray,
    lat_limit: float = 4.0,
) -> int:
    """Integrate latitude, longitude and height on ``n`` grid points ``k * dt``.

    ``c`` (deg+1, m, 8) and ``x`` (m+1,) are the merged profile channels (speed, accel,
    heading, heading rate, pitch, pitch rate, ...). Trapezoidal rule with the
    Euler-Maclaurin end correction, which telescopes to ``dt^2/12 (f'(0) - f'(t))``.
    Writes ``grid`` (n, 3) and the rates ``grid_rate`` (n, 3). Stops at the first grid
    point whose latitude exceeds ``lat_limit`` in magnitude and returns its index (the
    equations are singular at the poles); returns -1 when the whole grid is written.
    """
    ch = np.empty(6)
    j = 0
    lat, lon, h = lat0, lon0, h0
    d0 = np.empty(3)
    prev = np.empty(3)
    corr = dt * dt / 12.0
    for k in range(n):
        t = k * dt
        j = _channels(c, x, t, j, ch)
        s, a, psi, r, th, thd = ch[0], ch[1], ch[2], ch[3], ch[4], ch[5]
        sp, cp, st, ct = math.sin(psi), math.cos(psi), math.sin(th), math.cos(th)
        ve, vn, vu = s * sp * ct, s * cp * ct, s * st
        ae = a * sp * ct + s * (cp * ct * r - sp * st * thd)
        an = a * cp * ct + s * (-sp * ct * r - cp * st * thd)
        au = a * st + s * ct * thd
        if k > 0:
            # trapezoid; the radii are taken at the predicted latitude (their change over
            # one step moves the result by far less than a micrometre)
            h = h + 0.5 * dt * (prev[2] + vu)
            sl = math.sin(lat + dt * prev[0])
            w2 = 1.0 - E2 * sl * sl
            R_N = A / math.sqrt(w2)
            R_M = R_N * (1.0 - E2) / w2
            lat = lat + 0.5 * dt * (prev[0] + vn / (R_M + h))
        sl, cl = math.sin(lat), math.cos(lat)
        w2 = 1.0 - E2 * sl * sl
        R_N = A / math.sqrt(w2)
        R_M = R_N * (1.0 - E2) / w2
        f_lat = vn / (R_M + h)
        f_lon = ve / ((R_N + h) * cl)
        if k > 0:
            lon = lon + 0.5 * dt * (prev[1] + f_lon)
        d_lat = an / (R_M + h) - vn * vu / (R_M + h) ** 2
        d_lon = ae / ((R_N + h) * cl) - ve * vu / ((R_N + h) ** 2 * cl) + ve * sl * f_lat / ((R_N + h) * cl * cl)
        if k == 0:
            d0[0], d0[1], d0[2] = d_lat, d_lon, au
        if abs(lat) > lat_limit:
            return k
        grid[k, 0] = lat + corr * (d0[0] - d_lat)
        grid[k, 1] = lon + corr * (d0[1] - d_lon)
        grid[k, 2] = h + corr * (d0[2] - au)
        grid_rate[k, 0] = f_lat
        grid_rate[k, 1] = f_lon
        grid_rate[k, 2] = vu
        prev[0], prev[1], prev[2] = f_lat, f_lon, vu
    return -1


@njit(cache=True)
def hermite_position(grid: np.ndarray, grid_rate: np.ndarray, dt: float, t: np.ndarray, out: np.ndarray) -> None:
    """Cubic Hermite interpolation of a grid (n, m) with its rates at times ``t`` into ``out`` (N, m)."""
    last = grid.shape[0] - 2
    for n in range(t.shape[0]):
        u = t[n] / dt
        i = math.floor(u)
        i = 0 if i < 0 else (last if i > last else i)
        x = u - i
        x2 = x * x
        x3 = x2 * x
        h00 = 2.0 * x3 - 3.0 * x2 + 1.0
        h10 = (x3 - 2.0 * x2 + x) * dt
        h01 = -2.0 * x3 + 3.0 * x2
        h11 = (x3 - x2) * dt
        for c in range(grid.shape[1]):
            out[n, c] = (h00 * grid[i, c] + h10 * grid_rate[i, c] + h01 * grid[i + 1, c]
                         + h11 * grid_rate[i + 1, c])


@njit(cache=True)
def _geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    """Latitude, longitude, height of an ECEF point (as :func:`bench.nav.earth.ecef_to_geodetic`)."""
    lon = math.atan2(y, x)
    p = math.hypot(x, y)
    beta = math.atan2(z * A, p * B)
    ep2 = E2 / (1.0 - E2)
    lat = math.atan2(z + ep2 * B * math.sin(beta) ** 3, p - E2 * A * math.cos(beta) ** 3)
    for _ in range(2):
        s, c = math.sin(lat), math.cos(lat)
        R_N = A / math.sqrt(1.0 - E2 * s * s)
        h = p * c + z * s - A * math.sqrt(1.0 - E2 * s * s)
        lat = math.atan2(z, p * (1.0 - E2 * R_N / (R_N + h)))
    s, c = math.sin(lat), math.cos(lat)
    return lat, lon, p * c + z * s - A * math.sqrt(1.0 - E2 * s * s)


@njit(cache=True)
def _ecef_rhs(
    c: np.ndarray, x: np.ndarray, t: float, j: int, r: np.ndarray, q: np.ndarray, ch: np.ndarray,
    dr: np.ndarray, dq: np.ndarray,
) -> int:
    """Time derivatives of the ECEF position ``r`` and of the wander frame ``q`` (w -> e).

    The velocity is the profile's, taken in the wander-azimuth frame w (heading channel =
    heading from w's y axis); w turns with the transport rate's horizontal part only,
    written without the north direction so that nothing is singular at the poles:
    ``omega_ew = u x (v_h / (R_N + h) + (v . z_h) z_h R_N e^2 / (w^2 (R_M + h)(R_N + h)))``
    with ``u`` the normal and ``z_h = e_z - (e_z . u) u = cos(lat) north``.
    """
    j = _channels(c, x, t, j, ch)
    s, psi, th = ch[0], ch[2], ch[4]
    ct = math.cos(th)
    vw0, vw1, vw2 = s * math.sin(psi) * ct, s * math.cos(psi) * ct, s * math.sin(th)
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    c00 = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    c11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    ve0 = c00 * vw0 + 2.0 * (q1 * q2 - q0 * q3) * vw1 + 2.0 * (q1 * q3 + q0 * q2) * vw2
    ve1 = 2.0 * (q1 * q2 + q0 * q3) * vw0 + c11 * vw1 + 2.0 * (q2 * q3 - q0 * q1) * vw2
    ve2 = 2.0 * (q1 * q3 - q0 * q2) * vw0 + 2.0 * (q2 * q3 + q0 * q1) * vw1 + c22 * vw2
    lat, lon, h = _geodetic(r[0], r[1], r[2])
    sl, cl = math.sin(lat), math.cos(lat)
    u0, u1, u2 = cl * math.cos(lon), cl * math.sin(lon), sl
    w2 = 1.0 - E2 * sl * sl
    R_N = A / math.sqrt(w2)
    R_M = R_N * (1.0 - E2) / w2
    vu = ve0 * u0 + ve1 * u1 + ve2 * u2
    h0, h1, h2 = ve0 - vu * u0, ve1 - vu * u1, ve2 - vu * u2
    z0, z1, z2 = -sl * u0, -sl * u1, cl * cl
    g = (h0 * z0 + h1 * z1 + h2 * z2) * R_N * E2 / (w2 * (R_M + h) * (R_N + h))
    k0, k1, k2 = h0 / (R_N + h) + g * z0, h1 / (R_N + h) + g * z1, h2 / (R_N + h) + g * z2
    w0, w1, ww2 = u1 * k2 - u2 * k1, u2 * k0 - u0 * k2, u0 * k1 - u1 * k0
    dr[0], dr[1], dr[2] = ve0, ve1, ve2
    # dq/dt = 1/2 (0, omega_ew_e) * q
    dq[0] = 0.5 * (-w0 * q1 - w1 * q2 - ww2 * q3)
    dq[1] = 0.5 * (w0 * q0 + w1 * q3 - ww2 * q2)
    dq[2] = 0.5 * (-w0 * q3 + w1 * q0 + ww2 * q1)
    dq[3] = 0.5 * (w0 * q2 - w1 * q1 + ww2 * q0)
    return j


@njit(cache=True)
def integrate_profile_ecef(
    c: np.ndarray,
    x: np.ndarray,
    n: int,
    dt: float,
    r0: np.ndarray,
    q0: np.ndarray,
    grid_r: np.ndarray,
    grid_v: np.ndarray,
    grid_q: np.ndarray,
    grid_qdot: np.ndarray,
) -> None:
    """Integrate the ECEF position and the wander frame (w -> e) on ``n`` grid points ``k * dt``.

    Classical Runge-Kutta (fourth order) from ``r0`` (3,) and ``q0`` (4,); the quaternion is
    renormalised after each step. Writes positions ``grid_r`` (n, 3) with their rates
    ``grid_v`` (n, 3) and the frame ``grid_q`` (n, 4) with its rates ``grid_qdot`` (n, 4):
    the grid read by cubic Hermite interpolation. Nothing here divides by cos(lat).
    """
    ch = np.empty(6)
    r = r0.copy()
    q = q0.copy()
    k1r, k2r, k3r, k4r = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    k1q, k2q, k3q, k4q = np.empty(4), np.empty(4), np.empty(4), np.empty(4)
    rt, qt = np.empty(3), np.empty(4)
    j = 0
    for k in range(n):
        t = k * dt
        j = _ecef_rhs(c, x, t, j, r, q, ch, k1r, k1q)
        grid_r[k, :] = r
        grid_v[k, :] = k1r
        grid_q[k, :] = q
        grid_qdot[k, :] = k1q
        if k == n - 1:
            break
        for i in range(3):
            rt[i] = r[i] + 0.5 * dt * k1r[i]
        for i in range(4):
            qt[i] = q[i] + 0.5 * dt * k1q[i]
        j = _ecef_rhs(c, x, t + 0.5 * dt, j, rt, qt, ch, k2r, k2q)
        for i in range(3):
            rt[i] = r[i] + 0.5 * dt * k2r[i]
        for i in range(4):
            qt[i] = q[i] + 0.5 * dt * k2q[i]
        j = _ecef_rhs(c, x, t + 0.5 * dt, j, rt, qt, ch, k3r, k3q)
        for i in range(3):
            rt[i] = r[i] + dt * k3r[i]
        for i in range(4):
            qt[i] = q[i] + dt * k3q[i]
        j = _ecef_rhs(c, x, (k + 1) * dt, j, rt, qt, ch, k4r, k4q)
        for i in range(3):
            r[i] += dt / 6.0 * (k1r[i] + 2.0 * k2r[i] + 2.0 * k3r[i] + k4r[i])
        norm = 0.0
        for i in range(4):
            q[i] += dt / 6.0 * (k1q[i] + 2.0 * k2q[i] + 2.0 * k3q[i] + k4q[i])
            norm += q[i] * q[i]
        norm = math.sqrt(norm)
        for i in range(4):
            q[i] /= norm
