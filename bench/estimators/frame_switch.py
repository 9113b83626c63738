"""Conversion of the filter state and covariance between the geographic frame g (ENU,
position error in metres E, N, U) and the polar grid frame G (position error in ECEF
metres) at a navigation-frame switch: seed 003, eq. 28-38, in the bench's states.

The 15 core states are those of :mod:`bench.estimators.ins_model` (g) and
:mod:`bench.estimators.grid_model` (G); the biases (9-14) are the same in both. Every
error is computed minus true, each quantity in its own frame. With the grid angle sigma
of :mod:`bench.nav.grid`, the grid frame at the computed position is turned from the one
at the true position by ``d sigma = (d sigma / d r) . dr`` about up, and ``C_gG(sigma +
d sigma) C_Gg(sigma) = I + d sigma [e_z x]``, so, to first order::

    phi_G = C_gG phi_g - T1 dr         T1 = e_z (d sigma / d r)^T
    dv_G  = C_gG dv_g  + T2 dr         T2 = (e_z x v_G) (d sigma / d r)^T
    dP_e  = T3 dr                      T3 = C_n^e (ENU to ECEF)

``X_G = Phi X_g``, ``P_G = Phi P_g Phi^T`` (eq. 36-37). The way back (eq. 38) is written
in closed form, never as a numerical inverse::

    dr = C_e^n dP_e,  phi_g = C_Gg (phi_G + T1 dr),  dv_g = C_Gg (dv_G - T2 dr)

``d sigma / d r`` is ``bench.nav.grid.dsigma_denu``: it grows as 1 / cos(lat) and is not
defined at the pole, so both directions are refused above 89.9 deg of latitude; they are
also refused where the grid frame is near its own singularity (``cos^2 L sin^2 lam >
0.99``, the equator near 90 deg E or W). The compiled kernels return False there and
leave their arrays untouched; :func:`to_grid` and :func:`to_geographic` raise ValueError.

The matrices are evaluated at the navigation solution (the computed position and grid
velocity ``v_G``); using the true one instead changes them to second order only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav.grid import dsigma_denu_s, grid_angle_s

__all__ = [
    "MAX_LAT",
    "MAX_GRID_SINGULARITY",
    "switch_defined",
    "conversion_matrix",
    "inverse_conversion_matrix",
    "state_to_grid",
    "state_to_geographic",
    "covariance_to_grid",
    "covariance_to_geographic",
    "to_grid",
    "to_geographic",
]

#: Latitude (rad) above which d sigma / d r, hence the conversion, is refused.
MAX_LAT = math.radians(89.9)
#: Bound on cos^2 L sin^2 lam (1 at the grid frame's singular points).
MAX_GRID_SINGULARITY = 0.99


@njit(cache=True)
def switch_defined(lat: float, lon: float) -> bool:
    """Whether the conversion is defined at (lat, lon) (rad): the geographic frame's grid
    angle gradient (``|lat| <= 89.9 deg``) and the grid frame (``cos^2 L sin^2 lam <=
    0.99``) both regular."""
    g = (math.cos(lat) * math.sin(lon)) ** 2
    return abs(lat) <= MAX_LAT and g <= MAX_GRID_SINGULARITY


@njit(cache=True)
def _core(lat: float, lon: float, h: float, v_G: np.ndarray, inverse: bool, B: np.ndarray) -> None:
    """``B`` (9, 9): the phi, dv, position block of Phi (g to G), or of its inverse."""
    ds = np.empty(3)
    dsigma_denu_s(lat, lon, h, ds)
    sg = grid_angle_s(lat, lon)
    s, c = math.sin(sg), math.cos(sg)
    sl, cl = math.sin(lat), math.cos(lat)
    so, co = math.sin(lon), math.cos(lon)
    # C_en rows (ECEF to ENU): east, north, up
    Ce = np.empty((3, 3))
    Ce[0, 0], Ce[0, 1], Ce[0, 2] = -so, co, 0.0
    Ce[1, 0], Ce[1, 1], Ce[1, 2] = -sl * co, -sl * so, cl
    Ce[2, 0], Ce[2, 1], Ce[2, 2] = cl * co, cl * so, sl
    wx, wy = -v_G[1], v_G[0]  # e_z x v_G
    for i in range(9):
        for j in range(9):
            B[i, j] = 0.0
    if not inverse:
        # C_gG on phi and dv; -T1, T2 and T3 = C_ne on dr
        for k in (0, 3):
            B[k, k], B[k, k + 1] = c, -s
            B[k + 1, k], B[k + 1, k + 1] = s, c
            B[k + 2, k + 2] = 1.0
        for j in range(3):
            B[2, 6 + j] = -ds[j]
            B[3, 6 + j] = wx * ds[j]
            B[4, 6 + j] = wy * ds[j]
            for i in range(3):
                B[6 + i, 6 + j] = Ce[j, i]
        return
    # C_Gg on phi and dv; on dP: C_Gg T1 C_en = e_z (C_ne ds)^T, -C_Gg T2 C_en, C_en
    for k in (0, 3):
        B[k, k], B[k, k + 1] = c, s
        B[k + 1, k], B[k + 1, k + 1] = -s, c
        B[k + 2, k + 2] = 1.0
    ux, uy = c * wx + s * wy, -s * wx + c * wy  # C_Gg (e_z x v_G)
    for j in range(3):
        q = ds[0] * Ce[0, j] + ds[1] * Ce[1, j] + ds[2] * Ce[2, j]  # (ds^T C_en)_j
        B[2, 6 + j] = q
        B[3, 6 + j] = -ux * q
        B[4, 6 + j] = -uy * q
        for i in range(3):
            B[6 + i, 6 + j] = Ce[i, j]


@njit(cache=True)
def conversion_matrix(lat: float, lon: float, h: float, v_G: np.ndarray, Phi: np.ndarray) -> bool:
    """Fill ``Phi`` (15, 15) with the g-to-G conversion ``X_G = Phi X_g`` (seed eq. 36) at
    (lat, lon, h) (rad, rad, m) for the grid velocity ``v_G`` (3,) m/s. Returns False,
    ``Phi`` untouched, where :func:`switch_defined` is False."""
    if not switch_defined(lat, lon):
        return False
    B = np.empty((9, 9))
    _core(lat, lon, h, v_G, False, B)
    _embed(B, Phi)
    return True


@njit(cache=True)
def inverse_conversion_matrix(lat: float, lon: float, h: float, v_G: np.ndarray, Psi: np.ndarray) -> bool:
    """Fill ``Psi`` (15, 15) with ``Phi^-1`` in closed form (``X_g = Psi X_G``, seed eq.
    38). Returns False, ``Psi`` untouched, where :func:`switch_defined` is False."""
    if not switch_defined(lat, lon):
        return False
    B = np.empty((9, 9))
    _core(lat, lon, h, v_G, True, B)
    _embed(B, Psi)
    return True


@njit(cache=True)
def _embed(B: np.ndarray, Phi: np.ndarray) -> None:
    for i in range(15):
        for j in range(15):
            Phi[i, j] = 0.0
    for i in range(9):
        for j in range(9):
            Phi[i, j] = B[i, j]
    for i in range(9, 15):
        Phi[i, i] = 1.0


@njit(cache=True)
def _apply_state(x: np.ndarray, B: np.ndarray) -> None:
    t = np.empty(9)
    for i in range(9):
        acc = 0.0
        for k in range(9):
            acc += B[i, k] * x[k]
        t[i] = acc
    x[0:9] = t


@njit(cache=True)
def _apply_covariance(P: np.ndarray, B: np.ndarray) -> None:
    """``P <- Phi P Phi^T`` in place, Phi = diag(B, I): rows 0-8, then columns 0-8."""
    n = P.shape[0]
    t = np.empty(9)
    for j in range(n):
        for i in range(9):
            acc = 0.0
            for k in range(9):
                acc += B[i, k] * P[k, j]
            t[i] = acc
        for i in range(9):
            P[i, j] = t[i]
    for r in range(n):
        for i in range(9):
            acc = 0.0
            for k in range(9):
                acc += P[r, k] * B[i, k]
            t[i] = acc
        for i in range(9):
            P[r, i] = t[i]
    for i in range(9):
        for j in range(n):
            if j != i:
                m = 0.5 * (P[i, j] + P[j, i])
                P[i, j] = m
                P[j, i] = m


@njit(cache=True)
def _convert_state(x: np.ndarray, lat: float, lon: float, h: float, v_G: np.ndarray, inverse: bool) -> bool:
    if not switch_defined(lat, lon):
        return False
    B = np.empty((9, 9))
    _core(lat, lon, h, v_G, inverse, B)
    _apply_state(x, B)
    return True


@njit(cache=True)
def state_to_grid(x: np.ndarray, lat: float, lon: float, h: float, v_G: np.ndarray) -> bool:
    """``x`` (n,), n >= 15, in place from g states to G states (only 0-8 change).
    Returns False, ``x`` untouched, where the conversion is not defined."""
    return _convert_state(x, lat, lon, h, v_G, False)


@njit(cache=True)
def state_to_geographic(x: np.ndarray, lat: float, lon: float, h: float, v_G: np.ndarray) -> bool:
    """``x`` (n,), n >= 15, in place from G states to g states (closed-form inverse).
    Returns False, ``x`` untouched, where the conversion is not defined."""
    return _convert_state(x, lat, lon, h, v_G, True)


@njit(cache=True)
def _convert_covariance(P: np.ndarray, lat: float, lon: float, h: float, v_G: np.ndarray, inverse: bool) -> bool:
    if not switch_defined(lat, lon):
        return False
    B = np.empty((9, 9))
    _core(lat, lon, h, v_G, inverse, B)
    _apply_covariance(P, B)
    return True


@njit(cache=True)
def covariance_to_grid(P: np.ndarray, lat: float, lon: float, h: float, v_G: np.ndarray) -> bool:
    """``P`` (n, n), n >= 15, in place: ``P <- Phi P Phi^T`` on the core, the cross terms
    of the extra states transformed with it, their own block untouched; kept symmetric.
    Returns False, ``P`` untouched, where the conversion is not defined."""
    return _convert_covariance(P, lat, lon, h, v_G, False)


@njit(cache=True)
def covariance_to_geographic(P: np.ndarray, lat: float, lon: float, h: float, v_G: np.ndarray) -> bool:
    """``P`` (n, n), n >= 15, in place: ``P <- Psi P Psi^T`` with the closed-form inverse
    ``Psi`` of Phi. Returns False, ``P`` untouched, where the conversion is not defined."""
    return _convert_covariance(P, lat, lon, h, v_G, True)


def _refuse(lat: float, lon: float, direction: str) -> ValueError:
    g = (math.cos(lat) * math.sin(lon)) ** 2
    return ValueError(
        f"frame switch to {direction} refused at lat {math.degrees(lat):.6f} deg, lon {math.degrees(lon):.6f} deg: "
        f"expected |lat| <= 89.9 deg (the grid angle's gradient) and cos^2 L sin^2 lon <= "
        f"{MAX_GRID_SINGULARITY} (the grid frame), found |lat| {abs(math.degrees(lat)):.6f} deg and {g:.6f}"
    )


def _checked(x: np.ndarray, P: np.ndarray) -> None:
    n = x.shape[0]
    if n < 15 or P.shape != (n, n):
        raise ValueError(f"expected x (n,) and P (n, n) with n >= 15, found {x.shape} and {P.shape}")


def to_grid(x: np.ndarray, P: np.ndarray, lat: float, lon: float, h: float, v_G: np.ndarray) -> None:
    """Convert a filter's state ``x`` (n,) and covariance ``P`` (n, n) in place from the
    geographic to the grid frame; raises ValueError where the conversion is not defined."""
    _checked(x, P)
    if not switch_defined(lat, lon):
        raise _refuse(lat, lon, "grid")
    state_to_grid(x, lat, lon, h, v_G)
    covariance_to_grid(P, lat, lon, h, v_G)


def to_geographic(x: np.ndarray, P: np.ndarray, lat: float, lon: float, h: float, v_G: np.ndarray) -> None:
    """Convert a filter's state ``x`` (n,) and covariance ``P`` (n, n) in place from the
    grid to the geographic frame; raises ValueError where the conversion is not defined."""
    _checked(x, P)
    if not switch_defined(lat, lon):
        raise _refuse(lat, lon, "geographic")
    state_to_geographic(x, lat, lon, h, v_G)
    covariance_to_geographic(P, lat, lon, h, v_G)
