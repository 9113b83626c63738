"""The strapdown INS error model in the polar grid frame G with an ECEF position error
(seed 003, eq. 18-20), pole-safe.

G is the local level frame of :mod:`bench.nav.grid`: up is the ellipsoid normal, grid
north is parallel to the Greenwich meridian plane, ``C_eG`` (rows grid east, grid north,
up in ECEF) is defined at the geographic poles. Conventions are those of
:mod:`bench.estimators.ins_model`: every error is computed minus true, each quantity in
its own frame (the computed one at the computed position, the true one at the true
position); ``C_bG_computed = (I - [phi x]) C_bG_true``.

The 15 core states::

    0-2   phi_G   attitude error, rad (grid E, N, U)
    3-5   dv_G    velocity error, m/s (grid E, N, U)
    6-8   dP_e    position error, m (ECEF x, y, z; r_computed - r_true)
    9-11  eps     gyro bias, rad/s (body)
    12-14 nabla   accelerometer bias, m/s^2 (body)

Transport rate (the rate of G against the Earth, in G). The level part is the curvature
of the ellipsoid applied to the horizontal velocity, ``w_h = u x (K v)``; in ENU ``K =
diag(1/(R_N+h), 1/(R_M+h))``, written without true north as::

    K = I / (R_N + h) + kappa z_h z_h^T,   kappa = (1/(R_M+h) - 1/(R_N+h)) / cos^2 L
                                                 = e^2 R_N / (W^2 (R_M+h) (R_N+h))

where ``z_h`` is the level part of the ECEF z axis in G (``cos L`` times true north:
``C_eG[0:2, 2]``), so ``w_x = -(K v)_y``, ``w_y = (K v)_x``. The vertical part follows
from the defining constraint of G, that grid north stays perpendicular to the ECEF y axis
``y_e``: in G, ``y_e = (y_x, 0, y_z)`` (``y_x = C_eG[0, 1] = 1/xi > 0``, ``y_z = C_eG[2,
1] = cos L sin lam``) and its grid-north component must stay zero, ``d/dt (y_e . n_G) =
(y_e x w)_y = y_z w_x - y_x w_z = 0``::

    w_z = (y_z / y_x) w_x = xi cos L sin lam w_x

This is exact on the ellipsoid (the seed's ``-cot L sin sigma v_Gy / R`` is its spherical
form, ``cot L sin sigma = xi cos L sin lam``) and has no tan or sec of latitude: at the
poles ``y_z = 0`` and ``y_x = 1``, so ``w_z = 0``. It is singular only where G is (``y_x =
0``: the equator at 90 deg E or W).

Error dynamics (``theta = C_P dP_e`` is the rotation of the grid frame at the computed
position from the one at the true position, ``C_P = C_v C_eG`` with ``C_v = d w_eG / d
v_G``; ``D`` is the change of the transport rate with position at a fixed ``v_G``)::

    phi'  = -w_iG x phi + C_v dv + (w_ie x theta + D dP) - C_bG eps
    dv'   = f x phi + v x (C_v dv + 2 w_ie x theta + D dP) - (2 w_ie + w_eG) x dv
            + dg + C_bG nabla
    dP'   = C_Ge dv - C_Ge (v x) C_P dP

``dg`` is the change of normal gravity (the bench's Somigliana model with its free-air
reduction, exactly differentiated) along up. The seed's eq. 18 leaves out the position
terms of the attitude and velocity rows (``w_ie x theta``, ``D``, ``dg``); the Earth-rate
and gravity ones are of the same order as their counterparts in the ENU model and the
free-air gradient drives the vertical channel, so all are kept here.

All functions are compiled (numba) and work on preallocated arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav.earth import E2, OMEGA_IE, A

__all__ = ["PHI", "DV", "DP", "EPS", "NABLA", "N_CORE", "transport_rate_grid", "grid_error_matrix"]

PHI, DV, DP, EPS, NABLA = 0, 3, 6, 9, 12
N_CORE = 15

# normal gravity (Somigliana with the free-air reduction; as bench.nav.earth.gravity)
_GAMMA_E = 9.7803253359
_K_SOM = 0.00193185265241
_F = 1.0 / 298.257223563
_M = OMEGA_IE**2 * A**2 * (A * (1.0 - _F)) / 3.986004418e14


@njit(cache=True, inline="always")
def _curvature(s: float, h: float) -> tuple[float, float, float, float, float]:
    """For sin(lat) ``s``: R_M + h, R_N + h, 1/(R_N+h), kappa, W^2 = 1 - e^2 s^2."""
    w2 = 1.0 - E2 * s * s
    rn = A / math.sqrt(w2)
    rmh = rn * (1.0 - E2) / w2 + h
    rnh = rn + h
    return rmh, rnh, 1.0 / rnh, E2 * rn / (w2 * rmh * rnh), w2


@njit(cache=True)
def transport_rate_grid(lat: float, h: float, C_eG: np.ndarray, v_G: np.ndarray, out: np.ndarray) -> None:
    """``out`` (3,): the transport rate w_eG^G (rad/s) of velocity ``v_G`` (3,), m/s in G,
    at latitude ``lat`` (rad), height ``h`` (m), grid frame ``C_eG`` (3, 3). Exact on the
    ellipsoid and finite at the poles (see the module docstring)."""
    _, _, a, kappa, _ = _curvature(math.sin(lat), h)
    zx, zy = C_eG[0, 2], C_eG[1, 2]
    c = zx * v_G[0] + zy * v_G[1]
    px = a * v_G[0] + kappa * zx * c
    py = a * v_G[1] + kappa * zy * c
    out[0] = -py
    out[1] = px
    out[2] = -py * C_eG[2, 1] / C_eG[0, 1]


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
def grid_error_matrix(
    F: np.ndarray,
    lat: float,
    h: float,
    C_eG: np.ndarray,
    v_G: np.ndarray,
    f_G: np.ndarray,
    C_bG: np.ndarray,
) -> None:
    """Fill the core block ``F[0:15, 0:15]`` of the continuous error dynamics in G.

    Parameters
    ----------
    F:
        (n, n) with n >= 15; only the core block is written (it is zeroed first).
    lat, h:
        Latitude (rad; only its sine is used, so +-pi/2 is fine) and height (m).
    C_eG:
        (3, 3) rotation from ECEF to G (:func:`bench.nav.grid.C_eG_s`).
    v_G:
        (3,) velocity in G, m/s.
    f_G:
        (3,) specific force in G over the interval, m/s^2.
    C_bG:
        (3, 3) attitude, body to G.
    """
    for i in range(N_CORE):
        for j in range(N_CORE):
            F[i, j] = 0.0
    C = C_eG
    s = math.sin(lat)
    rmh, rnh, a, kappa, w2 = _curvature(s, h)
    vx, vy, vz = v_G[0], v_G[1], v_G[2]
    zx, zy = C[0, 2], C[1, 2]  # level part of the ECEF z axis (cos L times true north)
    rho = C[2, 1] / C[0, 1]  # y_z / y_x of the ECEF y axis
    # level curvature K (2x2) and the velocity map C_v = d w_eG / d v_G (columns x, y)
    k00, k01, k11 = a + kappa * zx * zx, kappa * zx * zy, a + kappa * zy * zy
    Cv = np.zeros((3, 3))
    Cv[0, 0], Cv[0, 1] = -k01, -k11
    Cv[1, 0], Cv[1, 1] = k00, k01
    Cv[2, 0], Cv[2, 1] = -rho * k01, -rho * k11
    c = zx * vx + zy * vy
    px, py = a * vx + kappa * zx * c, a * vy + kappa * zy * c  # K v
    wex, wey, wez = -py, px, -rho * py  # w_eG
    wix, wiy, wiz = OMEGA_IE * zx, OMEGA_IE * zy, OMEGA_IE * s  # w_ie = Omega C_eG z_e
    # derivatives with sin(lat) and h of 1/(R_N+h), ln kappa and normal gravity
    drn_ds = (rnh - h) * E2 * s / w2
    drm_ds = 3.0 * (rmh - h) * E2 * s / w2
    da_ds, da_dh = -drn_ds * a * a, -a * a
    dlk_ds = 3.0 * E2 * s / w2 - drm_ds / rmh - drn_ds / rnh
    dlk_dh = -1.0 / rmh - 1.0 / rnh
    g0 = _GAMMA_E * (1.0 + _K_SOM * s * s) / math.sqrt(w2)
    hred = 1.0 - 2.0 / A * (1.0 + _F + _M - 2.0 * _F * s * s) * h + 3.0 * h * h / (A * A)
    dg_ds = g0 * (2.0 * _K_SOM * s / (1.0 + _K_SOM * s * s) + E2 * s / w2) * hred + g0 * 8.0 * _F * s * h / A
    dg_dh = g0 * (-2.0 / A * (1.0 + _F + _M - 2.0 * _F * s * s) + 6.0 * h / (A * A))
    # per ECEF axis j of dP: d = C_eG e_j in G; theta (C_P), dw_eG (D C), dg_up
    CP = np.zeros((3, 3))
    DC = np.zeros((3, 3))
    for j in range(3):
        dx, dy, dz = C[0, j], C[1, j], C[2, j]
        tx = -(k01 * dx + k11 * dy)
        ty = k00 * dx + k01 * dy
        tz = rho * tx
        CP[0, j], CP[1, j], CP[2, j] = tx, ty, tz
        ds = (zx * dx + zy * dy) / rmh  # d sin(lat)
        dh = dz
        da = da_ds * ds + da_dh * dh
        dk = kappa * (dlk_ds * ds + dlk_dh * dh)
        dzx = zy * tz - s * ty  # d z = z x theta (the frame turns by theta)
        dzy = s * tx - zx * tz
        dc = dzx * vx + dzy * vy
        dpx = da * vx + dk * zx * c + kappa * (dzx * c + zx * dc)
        dpy = da * vy + dk * zy * c + kappa * (dzy * c + zy * dc)
        drho = ty * (1.0 + rho * rho)  # d (y_z / y_x), y_e turning by theta
        DC[0, j], DC[1, j], DC[2, j] = -dpy, dpx, drho * wex - rho * dpy
        F[DV + 2, DP + j] = -(dg_ds * ds + dg_dh * dh)
    # w_ie x theta
    EC = np.zeros((3, 3))
    for j in range(3):
        EC[0, j] = wiy * CP[2, j] - wiz * CP[1, j]
        EC[1, j] = wiz * CP[0, j] - wix * CP[2, j]
        EC[2, j] = wix * CP[1, j] - wiy * CP[0, j]
    # attitude
    _skew_into(F, PHI, PHI, wix + wex, wiy + wey, wiz + wez, -1.0)
    for i in range(3):
        for j in range(3):
            F[PHI + i, DV + j] = Cv[i, j]
            F[PHI + i, DP + j] = EC[i, j] + DC[i, j]
            F[PHI + i, EPS + j] = -C_bG[i, j]
            F[DV + i, NABLA + j] = C_bG[i, j]
            F[DP + i, DV + j] = C[j, i]
    # velocity: f x phi, v x (C_v dv + (2 w_ie x theta + D) dP), -(2 w_ie + w_eG) x dv, dg
    _skew_into(F, DV, PHI, f_G[0], f_G[1], f_G[2], 1.0)
    _skew_into(F, DV, DV, 2.0 * wix + wex, 2.0 * wiy + wey, 2.0 * wiz + wez, -1.0)
    for j in range(3):
        a0, a1, a2 = Cv[0, j], Cv[1, j], Cv[2, j]
        F[DV + 0, DV + j] += vy * a2 - vz * a1
        F[DV + 1, DV + j] += vz * a0 - vx * a2
        F[DV + 2, DV + j] += vx * a1 - vy * a0
        a0 = 2.0 * EC[0, j] + DC[0, j]
        a1 = 2.0 * EC[1, j] + DC[1, j]
        a2 = 2.0 * EC[2, j] + DC[2, j]
        F[DV + 0, DP + j] += vy * a2 - vz * a1
        F[DV + 1, DP + j] += vz * a0 - vx * a2
        F[DV + 2, DP + j] += vx * a1 - vy * a0
    # position: dP' = C_Ge dv - C_Ge (v x theta), theta = C_P dP
    VT = np.zeros((3, 3))
    for j in range(3):
        VT[0, j] = vy * CP[2, j] - vz * CP[1, j]
        VT[1, j] = vz * CP[0, j] - vx * CP[2, j]
        VT[2, j] = vx * CP[1, j] - vy * CP[0, j]
    for i in range(3):
        for j in range(3):
            F[DP + i, DP + j] = -(C[0, i] * VT[0, j] + C[1, i] * VT[1, j] + C[2, i] * VT[2, j])
