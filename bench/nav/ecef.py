"""Strapdown mechanization in the Earth frame (ECEF), compiled, and the frames a polar
estimator needs from an ECEF position: geodetic coordinates, the ENU frame, and seed
003's grid frame G (:mod:`bench.nav.grid`), all defined at the poles.

The grid-frame navigation of seed 003 (section 3, eq. 19-22) carries the attitude C_b^G,
the velocity v_G and the ECEF position. This module integrates the same quantities in
ECEF, ``C_b^e`` and ``v_e``, and the grid-frame ones are their projections
(``C_b^G = C_e^G C_b^e``, ``v_G = C_e^G v_e``, :func:`grid_frame`): the same navigation
solution, without the grid frame's transport rate, whose vertical part is singular at the
equator and whose geographic counterpart (``tan L``) is singular at the pole. Nothing here
divides by ``cos(lat)``.

The algorithms mirror :func:`bench.nav.strapdown._step` one for one (two-sample coning and
sculling, rotation compensation, gravity and Coriolis at the extrapolated mid-interval
state, trapezoidal position), so the two mechanizations agree to their common truncation
error wherever both are defined (tests/nav/test_ecef.py). Gravity is the same normal
gravity along the ellipsoid normal.

State layout (float64 array of 20, like the ENU one's): x, y, z (m), v_e (3, m/s), q_be
(4, scalar first: C_b^e), previous dtheta (3), previous dvel (3), previous v_e (3),
initialised flag.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav.earth import E2, OMEGA_IE, A, B
from bench.nav.strapdown import _gravity, _qmul, _rv2q

__all__ = [
    "geodetic",
    "ecef_position",
    "enu_frame",
    "grid_frame",
    "dcm_quat",
    "step_e",
    "from_geographic",
    "to_geographic",
]

_EP2 = E2 / (1.0 - E2)


@njit(cache=True)
def geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    """(lat, lon, h) of an ECEF point: Bowring's start and two Newton steps (as
    :func:`bench.nav.earth.ecef_to_geodetic`); longitude 0 on the polar axis."""
    p = math.hypot(x, y)
    lon = math.atan2(y, x) if p > 0.0 else 0.0
    beta = math.atan2(z * A, p * B)
    lat = math.atan2(z + _EP2 * B * math.sin(beta) ** 3, p - E2 * A * math.cos(beta) ** 3)
    for _ in range(2):
        s, c = math.sin(lat), math.cos(lat)
        rn = A / math.sqrt(1.0 - E2 * s * s)
        h = p * c + z * s - A * math.sqrt(1.0 - E2 * s * s)
        lat = math.atan2(z, p * (1.0 - E2 * rn / (rn + h)))
    s, c = math.sin(lat), math.cos(lat)
    h = p * c + z * s - A * math.sqrt(1.0 - E2 * s * s)
    return lat, lon, h


@njit(cache=True)
def ecef_position(lat: float, lon: float, h: float, out: np.ndarray) -> None:
    """``out`` (3,): the ECEF point of (lat, lon, h) (seed eq. 23, WGS-84)."""
    s, c = math.sin(lat), math.cos(lat)
    rn = A / math.sqrt(1.0 - E2 * s * s)
    out[0] = (rn + h) * c * math.cos(lon)
    out[1] = (rn + h) * c * math.sin(lon)
    out[2] = (rn * (1.0 - E2) + h) * s


@njit(cache=True)
def enu_frame(lat: float, lon: float, C: np.ndarray) -> None:
    """``C`` (3, 3) = C_e^n, ECEF to ENU (rows east, north, up)."""
    sl, cl = math.sin(lat), math.cos(lat)
    so, co = math.sin(lon), math.cos(lon)
    C[0, 0], C[0, 1], C[0, 2] = -so, co, 0.0
    C[1, 0], C[1, 1], C[1, 2] = -sl * co, -sl * so, cl
    C[2, 0], C[2, 1], C[2, 2] = cl * co, cl * so, sl


@njit(cache=True)
def grid_frame(lat: float, lon: float, C: np.ndarray) -> None:
    """``C`` (3, 3) = C_e^G, ECEF to the grid frame (rows grid east, grid north, up), from
    the ellipsoid normal alone (:func:`bench.nav.grid.C_eG`): defined at the poles."""
    cl = math.cos(lat)
    u0, u1, u2 = cl * math.cos(lon), cl * math.sin(lon), math.sin(lat)
    n0, n2 = -u2, u0  # u x y_e
    nn = math.hypot(n0, n2)
    n0, n2 = n0 / nn, n2 / nn
    # east = north x up
    C[0, 0], C[0, 1], C[0, 2] = -n2 * u1, n2 * u0 - n0 * u2, n0 * u1
    C[1, 0], C[1, 1], C[1, 2] = n0, 0.0, n2
    C[2, 0], C[2, 1], C[2, 2] = u0, u1, u2


@njit(cache=True)
def dcm_quat(C: np.ndarray, out: np.ndarray, off: int) -> None:
    """``out[off:off+4]``: the quaternion (scalar first, q0 >= 0) of the rotation ``C``."""
    tr = C[0, 0] + C[1, 1] + C[2, 2]
    if tr > 0.0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q0, q1, q2, q3 = 0.25 * s, (C[2, 1] - C[1, 2]) / s, (C[0, 2] - C[2, 0]) / s, (C[1, 0] - C[0, 1]) / s
    elif C[0, 0] > C[1, 1] and C[0, 0] > C[2, 2]:
        s = 2.0 * math.sqrt(1.0 + C[0, 0] - C[1, 1] - C[2, 2])
        q0, q1, q2, q3 = (C[2, 1] - C[1, 2]) / s, 0.25 * s, (C[0, 1] + C[1, 0]) / s, (C[0, 2] + C[2, 0]) / s
    elif C[1, 1] > C[2, 2]:
        s = 2.0 * math.sqrt(1.0 + C[1, 1] - C[0, 0] - C[2, 2])
        q0, q1, q2, q3 = (C[0, 2] - C[2, 0]) / s, (C[0, 1] + C[1, 0]) / s, 0.25 * s, (C[1, 2] + C[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + C[2, 2] - C[0, 0] - C[1, 1])
        q0, q1, q2, q3 = (C[1, 0] - C[0, 1]) / s, (C[0, 2] + C[2, 0]) / s, (C[1, 2] + C[2, 1]) / s, 0.25 * s
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    if q0 < 0.0:
        n = -n
    out[off], out[off + 1], out[off + 2], out[off + 3] = q0 / n, q1 / n, q2 / n, q3 / n


@njit(cache=True)
def _quat_dcm(q: np.ndarray, off: int, C: np.ndarray) -> None:
    q0, q1, q2, q3 = q[off], q[off + 1], q[off + 2], q[off + 3]
    C[0, 0] = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    C[0, 1] = 2.0 * (q1 * q2 - q0 * q3)
    C[0, 2] = 2.0 * (q1 * q3 + q0 * q2)
    C[1, 0] = 2.0 * (q1 * q2 + q0 * q3)
    C[1, 1] = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    C[1, 2] = 2.0 * (q2 * q3 - q0 * q1)
    C[2, 0] = 2.0 * (q1 * q3 - q0 * q2)
    C[2, 1] = 2.0 * (q2 * q3 + q0 * q1)
    C[2, 2] = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3


@njit(cache=True)
def step_e(st: np.ndarray, dth: np.ndarray, dv: np.ndarray, T: float) -> None:
    """One interval of the ECEF mechanization on the 20-float state ``st`` (module
    docstring) from the body increments ``dth`` (rad) and ``dv`` (m/s) over ``T`` s."""
    x, y, z = st[0], st[1], st[2]
    ve0, ve1, ve2 = st[3], st[4], st[5]
    if st[19] == 0.0:
        pth0, pth1, pth2 = 0.0, 0.0, 0.0
        pdv0, pdv1, pdv2 = 0.0, 0.0, 0.0
        pv0, pv1, pv2 = ve0, ve1, ve2
    else:
        pth0, pth1, pth2 = st[10], st[11], st[12]
        pdv0, pdv1, pdv2 = st[13], st[14], st[15]
        pv0, pv1, pv2 = st[16], st[17], st[18]
    t0, t1, t2 = dth[0], dth[1], dth[2]
    d0, d1, d2 = dv[0], dv[1], dv[2]
    phi0 = t0 + (pth1 * t2 - pth2 * t1) / 12.0
    phi1 = t1 + (pth2 * t0 - pth0 * t2) / 12.0
    phi2 = t2 + (pth0 * t1 - pth1 * t0) / 12.0
    r0 = 0.5 * (t1 * d2 - t2 * d1)
    r1 = 0.5 * (t2 * d0 - t0 * d2)
    r2 = 0.5 * (t0 * d1 - t1 * d0)
    s0 = ((pth1 * d2 - pth2 * d1) + (pdv1 * t2 - pdv2 * t1)) / 12.0
    s1 = ((pth2 * d0 - pth0 * d2) + (pdv2 * t0 - pdv0 * t2)) / 12.0
    s2 = ((pth0 * d1 - pth1 * d0) + (pdv0 * t1 - pdv1 * t0)) / 12.0
    b0, b1, b2 = d0 + r0 + s0, d1 + r1 + s1, d2 + r2 + s2
    # mid-interval extrapolation
    vm0 = ve0 + 0.5 * (ve0 - pv0)
    vm1 = ve1 + 0.5 * (ve1 - pv1)
    vm2 = ve2 + 0.5 * (ve2 - pv2)
    latm, lonm, hm = geodetic(x + 0.5 * T * vm0, y + 0.5 * T * vm1, z + 0.5 * T * vm2)
    zeta = OMEGA_IE * T  # the Earth frame's turn over the interval, about its z axis
    C = np.empty((3, 3))
    _quat_dcm(st, 6, C)
    n0 = C[0, 0] * b0 + C[0, 1] * b1 + C[0, 2] * b2
    n1 = C[1, 0] * b0 + C[1, 1] * b1 + C[1, 2] * b2
    n2 = C[2, 0] * b0 + C[2, 1] * b1 + C[2, 2] * b2
    # (I - 1/2 skew(zeta e_z)) n
    f0 = n0 + 0.5 * zeta * n1
    f1 = n1 - 0.5 * zeta * n0
    f2 = n2
    g = _gravity(latm, hm)
    cl = math.cos(latm)
    u0, u1, u2 = cl * math.cos(lonm), cl * math.sin(lonm), math.sin(latm)
    w2 = 2.0 * OMEGA_IE
    cor0 = w2 * vm1 - g * u0  # -2 w_ie x v - g u
    cor1 = -w2 * vm0 - g * u1
    cor2 = -g * u2
    nv0 = ve0 + f0 + cor0 * T
    nv1 = ve1 + f1 + cor1 * T
    nv2 = ve2 + f2 + cor2 * T
    q0, q1, q2, q3 = st[6], st[7], st[8], st[9]
    a0, a1, a2, a3 = _rv2q(phi0, phi1, phi2)
    q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, a0, a1, a2, a3)
    e0, e1, e2, e3 = _rv2q(0.0, 0.0, -zeta)
    q0, q1, q2, q3 = _qmul(e0, e1, e2, e3, q0, q1, q2, q3)
    qn = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    if q0 < 0.0:
        qn = -qn
    st[0] = x + 0.5 * T * (ve0 + nv0)
    st[1] = y + 0.5 * T * (ve1 + nv1)
    st[2] = z + 0.5 * T * (ve2 + nv2)
    st[3], st[4], st[5] = nv0, nv1, nv2
    st[6], st[7], st[8], st[9] = q0 / qn, q1 / qn, q2 / qn, q3 / qn
    st[10], st[11], st[12] = t0, t1, t2
    st[13], st[14], st[15] = d0, d1, d2
    st[16], st[17], st[18] = ve0, ve1, ve2
    st[19] = 1.0


@njit(cache=True)
def from_geographic(sg: np.ndarray, se: np.ndarray) -> None:
    """The ECEF state ``se`` (20,) of the ENU state ``sg`` (20,) of
    :mod:`bench.nav.strapdown` (seed eq. 23 and 26, through ECEF): the same point,
    velocity, attitude and increment history."""
    lat, lon = sg[0], sg[1]
    Cen = np.empty((3, 3))
    enu_frame(lat, lon, Cen)
    Cbn = np.empty((3, 3))
    _quat_dcm(sg, 6, Cbn)
    ecef_position(lat, lon, sg[2], se[0:3])
    se[3:6] = Cen.T @ sg[3:6]
    dcm_quat(Cen.T @ Cbn, se, 6)
    se[10:16] = sg[10:16]
    se[16:19] = Cen.T @ sg[16:19]
    se[19] = sg[19]


@njit(cache=True)
def to_geographic(se: np.ndarray, sg: np.ndarray) -> None:
    """The ENU state ``sg`` of the ECEF state ``se`` (inverse of :func:`from_geographic`)."""
    lat, lon, h = geodetic(se[0], se[1], se[2])
    Cen = np.empty((3, 3))
    enu_frame(lat, lon, Cen)
    Cbe = np.empty((3, 3))
    _quat_dcm(se, 6, Cbe)
    sg[0], sg[1], sg[2] = lat, lon, h
    sg[3:6] = Cen @ se[3:6]
    dcm_quat(Cen @ Cbe, sg, 6)
    sg[10:16] = se[10:16]
    sg[16:19] = Cen @ se[16:19]
    sg[19] = se[19]
