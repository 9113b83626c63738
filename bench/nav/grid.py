"""The polar grid frame G of seed 003: the local level frame whose north axis is parallel
to the Greenwich meridian plane.

G shares the up axis (the ellipsoid normal ``u``) with the geographic ENU frame g; its
north axis is ``u x y_e`` normalised (perpendicular to the ECEF y axis, so parallel to the
x-z plane that holds the Greenwich meridian), its east axis north x up. Unlike true north,
grid north stays defined at the geographic pole; it is undefined only where ``u`` is the
ECEF y axis itself (the equator at 90 deg E or W), far from where the grid frame is used.

The grid angle ``sigma`` turns true north into grid north, east positive (clockwise seen
from above): ``sin(sigma) = xi sin(L) sin(lam)``, ``cos(sigma) = xi cos(lam)``, ``xi = 1 /
sqrt(1 - cos^2 L sin^2 lam)``, so ``tan(sigma) = sin(L) tan(lam)``; at the pole sigma is
the longitude. Grid heading = true heading - sigma, and vectors turn by

    v_G = C_gG v_g,  C_gG = [[cos s, -sin s, 0], [sin s, cos s, 0], [0, 0, 1]]   (seed eq. 25)

The functions without a suffix are vectorised like :mod:`bench.nav.earth`: latitude and
longitude in radians, scalars or arrays of shape (N,) in. Those ending in ``_s`` are their
scalar, compiled (numba) ports for estimators' compiled steps: floats in, results in a
preallocated array.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav import earth
from bench.nav.earth import E2, A

__all__ = ["grid_angle", "C_gG", "C_eG", "dsigma_denu", "grid_angle_s", "C_gG_s", "C_eG_s", "dsigma_denu_s"]


def grid_angle(lat: np.ndarray | float, lon: np.ndarray | float) -> np.ndarray:
    """The grid angle sigma (rad, east of true north), in (-pi, pi]."""
    # sin and cos of sigma over xi (> 0): atan2 does not need xi
    return np.arctan2(np.sin(lat) * np.sin(lon), np.cos(lon) + np.zeros_like(np.asarray(lat, dtype=float)))


def C_gG(sigma: np.ndarray | float) -> np.ndarray:
    """Rotation from the geographic ENU frame to the grid frame, shape (..., 3, 3)."""
    s, c = np.sin(sigma), np.cos(sigma)
    out = np.zeros((*np.shape(sigma), 3, 3))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    out[..., 2, 2] = 1.0
    return out


def C_eG(lat: np.ndarray | float, lon: np.ndarray | float) -> np.ndarray:
    """Rotation from ECEF to the grid frame (rows: grid east, grid north, up in ECEF),
    shape (..., 3, 3), built from the normal alone: defined at the pole."""
    cl = np.cos(lat)
    u = np.stack(np.broadcast_arrays(cl * np.cos(lon), cl * np.sin(lon), np.sin(lat)), axis=-1)
    north = np.stack([-u[..., 2], np.zeros_like(u[..., 0]), u[..., 0]], axis=-1)  # u x y_e
    north /= np.linalg.norm(north, axis=-1, keepdims=True)
    east = np.cross(north, u)
    return np.stack([east, north, u], axis=-2)


def dsigma_denu(lat: np.ndarray | float, lon: np.ndarray | float, h: np.ndarray | float) -> np.ndarray:
    """How the grid angle changes with a displacement, rad per metre east, north, up,
    shape (..., 3): the gradient of ``atan2(sin L sin lam, cos lam)`` through
    ``dlam = dE / ((R_N + h) cos L)`` and ``dL = dN / (R_M + h)``. Not defined at the pole
    itself (sigma is the longitude there, which a metre east changes without bound)."""
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    rm, rn = earth.radii(lat)
    d = co**2 + (sl * so) ** 2  # = 1 / xi^2
    ds_dlat = cl * so * co / d
    ds_dlon = sl / d
    out = np.zeros((*np.shape(d), 3))
    out[..., 0] = ds_dlon / ((rn + h) * cl)
    out[..., 1] = ds_dlat / (rm + h)
    return out


@njit(cache=True)
def grid_angle_s(lat: float, lon: float) -> float:
    """Scalar :func:`grid_angle`: sigma (rad, east of true north), in (-pi, pi]."""
    return math.atan2(math.sin(lat) * math.sin(lon), math.cos(lon))


@njit(cache=True)
def C_gG_s(sigma: float, out: np.ndarray) -> None:
    """Scalar :func:`C_gG`: ``out`` (3, 3) the rotation from ENU to the grid frame."""
    s, c = math.sin(sigma), math.cos(sigma)
    out[0, 0], out[0, 1], out[0, 2] = c, -s, 0.0
    out[1, 0], out[1, 1], out[1, 2] = s, c, 0.0
    out[2, 0], out[2, 1], out[2, 2] = 0.0, 0.0, 1.0


@njit(cache=True)
def C_eG_s(lat: float, lon: float, out: np.ndarray) -> None:
    """Scalar :func:`C_eG`: ``out`` (3, 3) the rotation from ECEF to the grid frame (rows:
    grid east, grid north, up in ECEF), from the normal alone."""
    cl = math.cos(lat)
    ux, uy, uz = cl * math.cos(lon), cl * math.sin(lon), math.sin(lat)
    k = 1.0 / math.sqrt(ux * ux + uz * uz)  # |u x y_e|, 1 / xi
    nx, nz = -uz * k, ux * k  # u x y_e, normalised; its y component is zero
    out[0, 0], out[0, 1], out[0, 2] = -nz * uy, nz * ux - nx * uz, nx * uy  # north x up
    out[1, 0], out[1, 1], out[1, 2] = nx, 0.0, nz
    out[2, 0], out[2, 1], out[2, 2] = ux, uy, uz


@njit(cache=True)
def dsigma_denu_s(lat: float, lon: float, h: float, out: np.ndarray) -> None:
    """Scalar :func:`dsigma_denu`: ``out`` (3,) rad per metre east, north, up. Not defined
    at the pole itself (it divides by cos(lat))."""
    sl, cl = math.sin(lat), math.cos(lat)
    so, co = math.sin(lon), math.cos(lon)
    w2 = 1.0 - E2 * sl * sl
    rn = A / math.sqrt(w2)
    rm = rn * (1.0 - E2) / w2
    d = co * co + (sl * so) ** 2
    out[0] = sl / d / ((rn + h) * cl)
    out[1] = cl * so * co / d / (rm + h)
    out[2] = 0.0
