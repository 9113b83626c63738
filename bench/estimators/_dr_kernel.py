"""Compiled dead-reckoning interval (numba): gyro attitude plus a ground speed along the
direction of motion, shared by the ``dead_reckoning`` estimator and the seed-000 DRS."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav.earth import E2, OMEGA_IE, A
from bench.nav.strapdown import _qmul, _rv2q

__all__ = ["propagate", "dr_step", "motion_direction"]


@njit(cache=True, inline="always")
def motion_direction(q0, q1, q2, q3, ux, uz):
    """The direction of motion in ENU: C_bn (ux, 1, uz), ``ux`` towards the right and
    ``uz`` up (small mounting angles of the direction of motion in the body frame)."""
    c01 = 2.0 * (q1 * q2 - q0 * q3)
    c11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    c21 = 2.0 * (q2 * q3 + q0 * q1)
    c00 = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    c10 = 2.0 * (q1 * q2 + q0 * q3)
    c20 = 2.0 * (q1 * q3 - q0 * q2)
    c02 = 2.0 * (q1 * q3 + q0 * q2)
    c12 = 2.0 * (q2 * q3 - q0 * q1)
    c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    return c01 + ux * c00 + uz * c02, c11 + ux * c10 + uz * c12, c21 + ux * c20 + uz * c22


@njit(cache=True)
def dr_step(state: np.ndarray, t0: float, t1: float, t2: float, T: float, s: float, ux: float, uz: float) -> None:
    """Advance the dead-reckoning state over one IMU interval of ``T`` s.

    ``state`` (12): lat, lon, h, q_bn (4), previous dtheta (3), previous speed, distance.
    ``t0..t2``: the interval's angle increments (rad, compensated); ``s``: ground speed at
    the end of the interval (m/s); ``ux``, ``uz``: see :func:`motion_direction`.
    """
    lat, lon, h = state[0], state[1], state[2]
    q0, q1, q2, q3 = state[3], state[4], state[5], state[6]
    p0, p1, p2 = state[7], state[8], state[9]
    s_prev = state[10]
    fe, fn, fu = motion_direction(q0, q1, q2, q3, ux, uz)
    ve, vn, vu = s_prev * fe, s_prev * fn, s_prev * fu
    sl, cl = math.sin(lat), math.cos(lat)
    w2 = 1.0 - E2 * sl * sl
    R_N = A / math.sqrt(w2)
    R_M = R_N * (1.0 - E2) / w2
    z0 = -vn / (R_M + h) * T
    z1 = (OMEGA_IE * cl + ve / (R_N + h)) * T
    z2 = (OMEGA_IE * sl + ve * sl / cl / (R_N + h)) * T
    # coning-corrected body rotation, then the rotation of the navigation frame
    a0, a1, a2, a3 = _rv2q(
        t0 + (p1 * t2 - p2 * t1) / 12.0, t1 + (p2 * t0 - p0 * t2) / 12.0, t2 + (p0 * t1 - p1 * t0) / 12.0
    )
    q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, a0, a1, a2, a3)
    e0, e1, e2, e3 = _rv2q(-z0, -z1, -z2)
    q0, q1, q2, q3 = _qmul(e0, e1, e2, e3, q0, q1, q2, q3)
    qn = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    q0, q1, q2, q3 = q0 / qn, q1 / qn, q2 / qn, q3 / qn
    fe, fn, fu = motion_direction(q0, q1, q2, q3, ux, uz)
    ne, nn, nu = s * fe, s * fn, s * fu
    h += 0.5 * T * (vu + nu)
    lat += 0.5 * T * (vn + nn) / (R_M + h)
    lon += 0.5 * T * (ve + ne) / ((R_N + h) * cl)
    state[0], state[1], state[2] = lat, lon, h
    state[3], state[4], state[5], state[6] = q0, q1, q2, q3
    state[7], state[8], state[9] = t0, t1, t2
    state[11] += 0.5 * T * (abs(s) + abs(s_prev))
    state[10] = s


@njit(cache=True)
def propagate(state: np.ndarray, dtheta: np.ndarray, dt: np.ndarray, speed: np.ndarray, out: np.ndarray) -> None:
    """Advance the dead-reckoning state over N IMU frames.

    ``state`` (12): as :func:`dr_step`. ``out`` (N, 8): lat, lon, h, q_bn (4), speed after
    each frame.
    """
    for k in range(dtheta.shape[0]):
        dr_step(state, dtheta[k, 0], dtheta[k, 1], dtheta[k, 2], dt[k], speed[k], 0.0, 0.0)
        for i in range(7):
            out[k, i] = state[i]
        out[k, 7] = speed[k]
