"""Compiled inner loop of the dead-reckoning estimator (numba)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav.earth import E2, OMEGA_IE, A
from bench.nav.strapdown import _qmul, _rv2q

__all__ = ["propagate"]


@njit(cache=True)
def _forward(q0, q1, q2, q3):
    """The body forward axis (y) in ENU: second column of C_bn."""
    return 2.0 * (q1 * q2 - q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2.0 * (q2 * q3 + q0 * q1)


@njit(cache=True)
def propagate(state: np.ndarray, dtheta: np.ndarray, dt: np.ndarray, speed: np.ndarray, out: np.ndarray) -> None:
    """Advance the dead-reckoning state over N IMU frames.

    ``state`` (12): lat, lon, h, q_bn (4), previous dtheta (3), previous speed, distance.
    ``out`` (N, 8): lat, lon, h, q_bn (4), speed after each frame.
    """
    lat, lon, h = state[0], state[1], state[2]
    q0, q1, q2, q3 = state[3], state[4], state[5], state[6]
    p0, p1, p2 = state[7], state[8], state[9]
    s_prev, dist = state[10], state[11]
    for k in range(dtheta.shape[0]):
        t0, t1, t2 = dtheta[k, 0], dtheta[k, 1], dtheta[k, 2]
        T = dt[k]
        fe, fn, fu = _forward(q0, q1, q2, q3)
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
        s = speed[k]
        fe, fn, fu = _forward(q0, q1, q2, q3)
        ne, nn, nu = s * fe, s * fn, s * fu
        h += 0.5 * T * (vu + nu)
        lat += 0.5 * T * (vn + nn) / (R_M + h)
        lon += 0.5 * T * (ve + ne) / ((R_N + h) * cl)
        dist += 0.5 * T * (abs(s) + abs(s_prev))
        s_prev = s
        p0, p1, p2 = t0, t1, t2
        out[k, 0], out[k, 1], out[k, 2] = lat, lon, h
        out[k, 3], out[k, 4], out[k, 5], out[k, 6] = q0, q1, q2, q3
        out[k, 7] = s
    state[0], state[1], state[2] = lat, lon, h
    state[3], state[4], state[5], state[6] = q0, q1, q2, q3
    state[7], state[8], state[9] = p0, p1, p2
    state[10], state[11] = s_prev, dist
