"""The strapdown INS error model in ENU (phi-angle form) and its discretization.

Error convention: every error is computed minus true. The attitude error ``phi`` (rad,
ENU) is the rotation of the computed navigation frame from the true one,
``C_bn_computed = (I - [phi x]) C_bn_true``; the position error is in metres along E, N,
U (``dE = dlon cos(lat) (R_N + h)``, ``dN = dlat (R_M + h)``), the gyro and accelerometer
biases are in the body frame (rad/s, m/s^2), as in Savage (Strapdown Analytics, ch. 12)
and Yan (PSINS ``etm``), with the position states taken from radians to metres.

The 15 core states (indices below), shared by every reference estimator::

    0-2  phi       attitude error, rad (E, N, U)
    3-5  dv        velocity error, m/s (E, N, U)
    6-8  dr        position error, m (E, N, U)
    9-11 eps       gyro bias, rad/s (body x, y, z)
    12-14 nabla    accelerometer bias, m/s^2 (body x, y, z)

    phi'   = -w_in x phi + dw_in(dv, dr) - C_bn eps
    dv'    = f_n x phi + v x (2 dw_ie + dw_en) - (2 w_ie + w_en) x dv + dg + C_bn nabla
    dr'    = dv + F_rr dr

All functions are compiled (numba) and work on preallocated arrays, so an estimator can
call them from its own compiled step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav.earth import E2, OMEGA_IE, A

__all__ = [
    "PHI",
    "DV",
    "DR",
    "EPS",
    "NABLA",
    "N_CORE",
    "radii",
    "rates",
    "ins_error_matrix",
    "scale_factor_columns",
    "discretize",
    "euler_jacobian",
    "position_difference",
]

PHI, DV, DR, EPS, NABLA = 0, 3, 6, 9, 12
N_CORE = 15

# normal gravity: its derivative with latitude (Savage; PSINS etm), m/s^2 per rad
_G0 = 9.7803267714
_DG_DH = 3.086e-6


@njit(cache=True, inline="always")
def radii(lat: float, h: float) -> tuple[float, float]:
    """(R_M + h, R_N + h), meridian and prime-vertical radii plus height, m."""
    sl = math.sin(lat)
    w2 = 1.0 - E2 * sl * sl
    rn = A / math.sqrt(w2)
    return rn * (1.0 - E2) / w2 + h, rn + h


@njit(cache=True)
def rates(lat: float, h: float, ve: float, vn: float, out: np.ndarray) -> None:
    """``out`` (2, 3): Earth rate and transport rate in ENU, rad/s."""
    rmh, rnh = radii(lat, h)
    sl, cl = math.sin(lat), math.cos(lat)
    out[0, 0], out[0, 1], out[0, 2] = 0.0, OMEGA_IE * cl, OMEGA_IE * sl
    out[1, 0], out[1, 1], out[1, 2] = -vn / rmh, ve / rnh, ve * sl / cl / rnh


@njit(cache=True, inline="always")
def _skew_into(M: np.ndarray, r: int, c: int, x: float, y: float, z: float, s: float) -> None:
    """M[r:r+3, c:c+3] += s * [v x]."""
    M[r, c + 1] += -s * z
    M[r, c + 2] += s * y
    M[r + 1, c] += s * z
    M[r + 1, c + 2] += -s * x
    M[r + 2, c] += -s * y
    M[r + 2, c + 1] += s * x


@njit(cache=True)
def ins_error_matrix(F: np.ndarray, lat: float, h: float, v: np.ndarray, f_n: np.ndarray, C: np.ndarray) -> None:
    """Fill the core block ``F[0:15, 0:15]`` of the continuous error dynamics.

    Parameters
    ----------
    F:
        (n, n) with n >= 15; only the core block is written (it is zeroed first).
    lat, h:
        Position, rad and m.
    v:
        (3,) velocity, ENU m/s.
    f_n:
        (3,) specific force in ENU over the interval, m/s^2.
    C:
        (3, 3) C_bn.
    """
    for i in range(N_CORE):
        for j in range(N_CORE):
            F[i, j] = 0.0
    rmh, rnh = radii(lat, h)
    sl, cl = math.sin(lat), math.cos(lat)
    tl = sl / cl
    ve, vn, vu = v[0], v[1], v[2]
    wie_n, wie_u = OMEGA_IE * cl, OMEGA_IE * sl
    win0, win1, win2 = -vn / rmh, wie_n + ve / rnh, wie_u + ve * tl / rnh
    # Mav = d w_en / d v
    Mav = np.zeros((3, 3))
    Mav[0, 1] = -1.0 / rmh
    Mav[1, 0] = 1.0 / rnh
    Mav[2, 0] = tl / rnh
    # d w_ie / d dr (north) and d w_en / d dr (north, up), position in metres
    Mie = np.zeros((3, 3))
    Mie[1, 1] = -OMEGA_IE * sl / rmh
    Mie[2, 1] = OMEGA_IE * cl / rmh
    Men = np.zeros((3, 3))
    Men[0, 2] = vn / (rmh * rmh)
    Men[1, 2] = -ve / (rnh * rnh)
    Men[2, 2] = -ve * tl / (rnh * rnh)
    Men[2, 1] = ve / (cl * cl * rnh) / rmh
    # attitude
    _skew_into(F, PHI, PHI, win0, win1, win2, -1.0)
    for i in range(3):
        for j in range(3):
            F[PHI + i, DV + j] = Mav[i, j]
            F[PHI + i, DR + j] = Mie[i, j] + Men[i, j]
            F[PHI + i, EPS + j] = -C[i, j]
            F[DV + i, NABLA + j] = C[i, j]
    # velocity: f x phi, v x (2 dw_ie + dw_en), -(2 w_ie + w_en) x dv
    _skew_into(F, DV, PHI, f_n[0], f_n[1], f_n[2], 1.0)
    W = np.zeros((3, 3))  # v x (Mav) for dv, v x (2 Mie + Men) for dr
    for j in range(3):
        a0, a1, a2 = Mav[0, j], Mav[1, j], Mav[2, j]
        W[0, j], W[1, j], W[2, j] = vn * a2 - vu * a1, vu * a0 - ve * a2, ve * a1 - vn * a0
    for i in range(3):
        for j in range(3):
            F[DV + i, DV + j] += W[i, j]
    _skew_into(F, DV, DV, win0 + 0.0, win1 + wie_n, win2 + wie_u, -1.0)  # 2 w_ie + w_en
    for j in range(3):
        a0 = 2.0 * Mie[0, j] + Men[0, j]
        a1 = 2.0 * Mie[1, j] + Men[1, j]
        a2 = 2.0 * Mie[2, j] + Men[2, j]
        F[DV + 0, DR + j] += vn * a2 - vu * a1
        F[DV + 1, DR + j] += vu * a0 - ve * a2
        F[DV + 2, DR + j] += ve * a1 - vn * a0
    # gravity: dg/dlat (normal gravity) and the free-air gradient (the unstable vertical channel)
    F[DV + 2, DR + 1] += -_G0 * (5.27094e-3 * 2.0 * sl * cl + 2.32718e-5 * 4.0 * sl**3 * cl) / rmh
    F[DV + 2, DR + 2] += _DG_DH
    # position (metres): dr' = dv + F_rr dr
    F[DR + 0, DV + 0] = 1.0
    F[DR + 1, DV + 1] = 1.0
    F[DR + 2, DV + 2] = 1.0
    F[DR + 0, DR + 0] = vu / rnh - vn * tl / rmh
    F[DR + 0, DR + 1] = ve * tl / rmh
    F[DR + 0, DR + 2] = -ve / rnh
    F[DR + 1, DR + 1] = vu / rmh
    F[DR + 1, DR + 2] = -vn / rmh


@njit(cache=True)
def scale_factor_columns(F: np.ndarray, col: int, C: np.ndarray, w_b: np.ndarray, f_b: np.ndarray) -> None:
    """Optional scale-factor states: fill ``F[:, col:col+6]`` for gyro (3) then
    accelerometer (3) scale-factor errors (sensed = (1 + s) true, per axis), given the
    body rate ``w_b`` (rad/s) and specific force ``f_b`` (m/s^2) over the interval:
    ``phi' += -C diag(w_b) s_g``, ``dv' += C diag(f_b) s_a``. The states themselves are
    random constants (their rows stay zero)."""
    for i in range(3):
        for j in range(3):
            F[PHI + i, col + j] = -C[i, j] * w_b[j]
            F[DV + i, col + 3 + j] = C[i, j] * f_b[j]


@njit(cache=True)
def position_rate_matrix(lat: float, h: float, v: np.ndarray, out: np.ndarray) -> None:
    """``out`` (3, 3): F_rr of a metre position error carried by velocity ``v``."""
    rmh, rnh = radii(lat, h)
    tl = math.tan(lat)
    ve, vn, vu = v[0], v[1], v[2]
    out[:, :] = 0.0
    out[0, 0] = vu / rnh - vn * tl / rmh
    out[0, 1] = ve * tl / rmh
    out[0, 2] = -ve / rnh
    out[1, 1] = vu / rmh
    out[1, 2] = -vn / rmh


@njit(cache=True)
def discretize(F: np.ndarray, Qc: np.ndarray, T: float, Phi: np.ndarray, Qd: np.ndarray) -> None:
    """Second-order discretization over ``T`` s: ``Phi = I + F T + (F T)^2 / 2``,
    ``Qd = (Phi Qc Phi' + Qc) T / 2`` (trapezoid of the noise injected over the interval).

    ``F``, ``Qc``, ``Phi``, ``Qd``: (n, n).
    """
    n = F.shape[0]
    FT = F * T
    Phi[:, :] = FT @ FT
    for i in range(n):
        for j in range(n):
            Phi[i, j] = 0.5 * Phi[i, j] + FT[i, j]
        Phi[i, i] += 1.0
    Qd[:, :] = Phi @ Qc @ Phi.T
    for i in range(n):
        for j in range(n):
            Qd[i, j] = 0.5 * T * (Qd[i, j] + Qc[i, j])


@njit(cache=True)
def euler_jacobian(C: np.ndarray, out: np.ndarray) -> None:
    """``out`` (3, 3): d(heading, pitch, roll) / d(phi), ICD Euler angles (heading
    clockwise from north), for the attitude C_bn; from ``C_c = (I - [phi x]) C``."""
    # heading = atan2(C01, C11), pitch = asin(C21), roll = atan2(-C20, C22); dC = -[phi x] C
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0
        # dC = -[e x] C: row i of (e x c_j) for the columns j we need
        d = np.zeros((3, 3))
        for j in range(3):
            c0, c1, c2 = C[0, j], C[1, j], C[2, j]
            d[0, j] = -(e[1] * c2 - e[2] * c1)
            d[1, j] = -(e[2] * c0 - e[0] * c2)
            d[2, j] = -(e[0] * c1 - e[1] * c0)
        n_h = C[0, 1] ** 2 + C[1, 1] ** 2
        out[0, k] = (C[1, 1] * d[0, 1] - C[0, 1] * d[1, 1]) / n_h
        out[1, k] = d[2, 1] / math.sqrt(max(1.0 - C[2, 1] ** 2, 1e-12))
        n_r = C[2, 0] ** 2 + C[2, 2] ** 2
        out[2, k] = (-C[2, 2] * d[2, 0] + C[2, 0] * d[2, 2]) / n_r


@njit(cache=True)
def position_difference(
    lat1: float, lon1: float, h1: float, lat2: float, lon2: float, h2: float, out: np.ndarray
) -> None:
    """``out`` (3,): position 1 minus position 2 in metres, E N U at position 2."""
    rmh, rnh = radii(lat2, h2)
    out[0] = (lon1 - lon2) * math.cos(lat2) * rnh
    out[1] = (lat1 - lat2) * rmh
    out[2] = h1 - h2
