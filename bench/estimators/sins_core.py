"""Compiled operations on the strapdown state shared by the reference estimators.

The SINS state is the 20-float array of :mod:`bench.nav.strapdown` (lat, lon, h, ENU
velocity, q_bn, the previous increments, the velocity history, a flag); the filters hold
the 15 core error states of :mod:`bench.estimators.ins_model` first in their state
vector. These functions apply the closed-loop feedback of the core states and run the
fine alignment's zero-velocity update, for any estimator whose covariance starts with the
core block.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.estimators.ins_model import DR, DV, EPS, NABLA, PHI, euler_jacobian, position_difference, radii
from bench.estimators.kf import joseph_update
from bench.nav.strapdown import _qmul, _rv2q

__all__ = [
    "quat_dcm",
    "rotate_attitude",
    "move_position",
    "core_feedback",
    "zupt_update",
    "write_output",
    "write_attitude",
    "write_sigmas",
]


@njit(cache=True)
def quat_dcm(q: np.ndarray, off: int, C: np.ndarray) -> None:
    """``C`` (3, 3) = C_bn of the quaternion ``q[off:off+4]`` (scalar first)."""
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
def rotate_attitude(st: np.ndarray, off: int, phi0: float, phi1: float, phi2: float) -> None:
    """Correct the attitude quaternion at ``st[off]`` by the estimated error phi:
    C_true = (I + [phi x]) C_computed."""
    e0, e1, e2, e3 = _rv2q(phi0, phi1, phi2)
    q0, q1, q2, q3 = _qmul(e0, e1, e2, e3, st[off], st[off + 1], st[off + 2], st[off + 3])
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    if q0 < 0.0:
        n = -n
    st[off], st[off + 1], st[off + 2], st[off + 3] = q0 / n, q1 / n, q2 / n, q3 / n


@njit(cache=True)
def move_position(st: np.ndarray, off: int, de: float, dn: float, du: float) -> None:
    """Subtract a metre position error (E, N, U) from lat, lon, h at ``st[off]``."""
    rmh, rnh = radii(st[off], st[off + 2])
    st[off] -= dn / rmh
    st[off + 1] -= de / (math.cos(st[off]) * rnh)
    st[off + 2] -= du


@njit(cache=True)
def core_feedback(sins: np.ndarray, bg: np.ndarray, ba: np.ndarray, x: np.ndarray) -> None:
    """Feed the core estimate ``x[0:15]`` back: attitude, velocity (and its history),
    position of the SINS state ``sins`` (20,), and the gyro and accelerometer bias
    compensations ``bg``, ``ba`` (3,) subtracted from the increments."""
    rotate_attitude(sins, 6, x[PHI], x[PHI + 1], x[PHI + 2])
    for i in range(3):
        sins[3 + i] -= x[DV + i]
        sins[16 + i] -= x[DV + i]  # the velocity history used for extrapolation
        bg[i] += x[EPS + i]
        ba[i] += x[NABLA + i]
    move_position(sins, 0, x[DR], x[DR + 1], x[DR + 2])


@njit(cache=True)
def zupt_update(sins: np.ndarray, P: np.ndarray, p0: np.ndarray, sigma_v: float, sigma_p: float) -> np.ndarray:
    """Fine alignment at rest: zero velocity and the surveyed position ``p0`` (lat, lon,
    h) measured on the core states of ``P`` (n, n), n >= 15. Returns the estimate (n,) to
    feed back (:func:`core_feedback`)."""
    n = P.shape[0]
    z = np.zeros(6)
    H = np.zeros((6, n))
    R = np.zeros((6, 6))
    d = np.zeros(3)
    position_difference(sins[0], sins[1], sins[2], p0[0], p0[1], p0[2], d)
    for i in range(3):
        z[i] = sins[3 + i]
        z[3 + i] = d[i]
        H[i, DV + i] = 1.0
        H[3 + i, DR + i] = 1.0
        R[i, i] = sigma_v**2
        R[3 + i, 3 + i] = sigma_p**2
    x = np.zeros(n)
    joseph_update(x, P, z, H, R)
    return x


@njit(cache=True)
def write_attitude(C: np.ndarray, r) -> None:
    """The Euler angles of C_bn (ENU) into the NAV_SOLUTION record ``r``: heading in [0,
    2 pi) clockwise from north, pitch, roll."""
    hdg = math.atan2(C[0, 1], C[1, 1])
    r.heading = hdg + 2.0 * math.pi if hdg < 0.0 else hdg
    r.pitch = math.asin(min(1.0, max(-1.0, C[2, 1])))
    r.roll = math.atan2(-C[2, 0], C[2, 2])


@njit(cache=True)
def write_sigmas(q, C: np.ndarray, Pr: np.ndarray, Pv: np.ndarray, Pphi: np.ndarray) -> None:
    """The NAV_QUALITY record ``q``'s sigmas from the ENU position, velocity and attitude
    error covariances (3, 3 each) and the attitude C_bn (Euler angles through
    :func:`~bench.estimators.ins_model.euler_jacobian`)."""
    J = np.zeros((3, 3))
    euler_jacobian(C, J)
    Pe = J @ Pphi @ J.T
    for i in range(3):
        q.sigma_pos[i] = math.sqrt(max(Pr[i, i], 0.0))
        q.sigma_vel[i] = math.sqrt(max(Pv[i, i], 0.0))
        q.sigma_att[i] = math.sqrt(max(Pe[i, i], 0.0))


@njit(cache=True)
def write_output(st: np.ndarray, off: int, P: np.ndarray, t: float, r, q) -> None:
    """One output epoch at ``t`` (ns) from the SINS state ``st[off:off+10]`` and the core
    covariance: the NAV_SOLUTION record ``r`` (time, position, velocity, heading in [0, 2
    pi), pitch, roll) and the NAV_QUALITY record ``q`` (time and the 1-sigma position,
    velocity and Euler-angle sigmas). Mode, validity and the fault bytes are the caller's."""
    C = np.zeros((3, 3))
    quat_dcm(st, off + 6, C)
    r.t_ns = np.int64(t)
    r.lat, r.lon, r.h = st[off], st[off + 1], st[off + 2]
    for i in range(3):
        r.vel_n[i] = st[off + 3 + i]
    write_attitude(C, r)
    q.t_ns = np.int64(t)
    write_sigmas(q, C, P[DR : DR + 3, DR : DR + 3].copy(), P[DV : DV + 3, DV : DV + 3].copy(),
                 P[PHI : PHI + 3, PHI : PHI + 3].copy())
