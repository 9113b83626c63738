"""Compiled kernels of the scenario layer (numba): the position integration grid.

Kept apart so that the numerical code stays readable in :mod:`bench.scenario.profile`
and the compiler is used in one place of the layer.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav.earth import E2, A

__all__ = ["integrate_profile_position"]


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
) -> None:
    """Integrate latitude, longitude and height on ``n`` grid points ``k * dt``.

    ``c`` (deg+1, m, 8) and ``x`` (m+1,) are the merged profile channels (speed, accel,
    heading, heading rate, pitch, pitch rate, ...). Trapezoidal rule with the
    Euler-Maclaurin end correction, which telescopes to ``dt^2/12 (f'(0) - f'(t))``.
    Writes ``grid`` (n, 3) and the rates ``grid_rate`` (n, 3).
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
        grid[k, 0] = lat + corr * (d0[0] - d_lat)
        grid[k, 1] = lon + corr * (d0[1] - d_lon)
        grid[k, 2] = h + corr * (d0[2] - au)
        grid_rate[k, 0] = f_lat
        grid_rate[k, 1] = f_lon
        grid_rate[k, 2] = vu
        prev[0], prev[1], prev[2] = f_lat, f_lon, vu


@njit(cache=True)
def hermite_position(grid: np.ndarray, grid_rate: np.ndarray, dt: float, t: np.ndarray, out: np.ndarray) -> None:
    """Cubic Hermite interpolation of the position grid at times ``t`` into ``out`` (N, 3)."""
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
        for c in range(3):
            out[n, c] = (h00 * grid[i, c] + h10 * grid_rate[i, c] + h01 * grid[i + 1, c]
                         + h11 * grid_rate[i + 1, c])
