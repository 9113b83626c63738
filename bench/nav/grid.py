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

All functions are vectorised like :mod:`bench.nav.earth`: latitude and longitude in
radians, scalars or arrays of shape (N,) in.
"""

from __future__ import annotations

import numpy as np

from bench.nav import earth

__all__ = ["grid_angle", "C_gG", "C_eG", "dsigma_denu"]


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
