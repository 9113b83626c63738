"""Measurement updates of the seed-001 BDS/SINS estimator (compiled, numba).

State vector (20)::

    0-14  the core 15 (bench.estimators.ins_model: phi, dv, dr (m), gyro bias, accel bias)
    15    dk    odometer scale-factor error of the compensated speed (computed minus true)
    16    ddt   receiver time-offset error (estimate minus true), s
    17-19 m     the receiver's correlated position error (first-order Markov, E N U, m)

BDS (seed eq. 1-10, 14): the INS at the fix's true measurement time ``t_stamp - dt_hat``
(interpolated in a short history of INS states), carried to the antenna by the lever arm,
minus the fix, in metres (E, N, U) and m/s (E, N)::

    z_p = dr + [(C l) x] phi - v ddt - m + noise
    z_v = dv + [(C (w x l)) x] phi - a ddt + noise

Odometer with the non-holonomic constraint (eq. 20): the INS velocity in the body frame
(right, forward, up) minus (0, v_odo (1 - k), 0), the forward row at the wheel and the
lateral and vertical rows at the point the constraint holds at; zero velocity when
stopped.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.estimators.ins_model import DR, DV, PHI, position_difference
from bench.estimators.kf import joseph_update
from bench.estimators.sins_core import quat_dcm, zero_velocity  # zero_velocity: re-exported, shared

__all__ = ["N_STATES", "DK", "DDT", "MK", "H_COLS", "hist_push", "hist_at", "bds_update", "nhc_update", "zero_velocity"]

N_STATES = 20
DK, DDT, MK = 15, 16, 17
#: history row: t, lat, lon, h, ve, vn, vu, q0..q3, wx, wy, wz
H_COLS = 14


@njit(cache=True)
def hist_push(hist: np.ndarray, meta: np.ndarray, t: float, sins: np.ndarray, w: np.ndarray) -> None:
    """Append the INS state at ``t`` to the ring ``hist`` (N, 14); ``meta`` = (count, head)."""
    n = hist.shape[0]
    i = int(meta[1])
    hist[i, 0] = t
    for k in range(10):
        hist[i, 1 + k] = sins[k]
    for k in range(3):
        hist[i, 11 + k] = w[k]
    meta[1] = (i + 1) % n
    meta[0] = min(meta[0] + 1, n)


@njit(cache=True)
def hist_at(hist: np.ndarray, meta: np.ndarray, t: float, out: np.ndarray) -> None:
    """``out`` (14,): the history interpolated linearly at ``t`` (clamped to its ends; the
    quaternion renormalised)."""
    n = hist.shape[0]
    cnt = int(meta[0])
    head = int(meta[1])
    newest = (head - 1) % n
    oldest = (head - cnt) % n
    if t >= hist[newest, 0]:
        out[:] = hist[newest]
        return
    if t <= hist[oldest, 0]:
        out[:] = hist[oldest]
        return
    j = newest
    for _ in range(cnt - 1):
        i = (j - 1) % n
        if hist[i, 0] <= t:
            a = (t - hist[i, 0]) / (hist[j, 0] - hist[i, 0])
            for k in range(H_COLS):
                out[k] = hist[i, k] + a * (hist[j, k] - hist[i, k])
            qn = math.sqrt(out[7] ** 2 + out[8] ** 2 + out[9] ** 2 + out[10] ** 2)
            for k in range(7, 11):
                out[k] /= qn
            return
        j = i
    out[:] = hist[oldest]


@njit(cache=True, inline="always")
def _skew_rows(H: np.ndarray, r: int, c: int, x: float, y: float, z: float) -> None:
    """H[r:r+3, c:c+3] = [u x] for u = (x, y, z)."""
    H[r, c + 1], H[r, c + 2] = -z, y
    H[r + 1, c], H[r + 1, c + 2] = z, -x
    H[r + 2, c], H[r + 2, c + 1] = -y, x


@njit(cache=True)
def bds_update(
    P: np.ndarray,
    x: np.ndarray,
    fix: np.ndarray,
    hist: np.ndarray,
    meta: np.ndarray,
    dt_hat: float,
    lever: np.ndarray,
    use_dt: bool,
    ms: np.ndarray,
    floor: float,
    r_vel: float,
    gate3: float,
    gate5: float,
) -> float:
    """One fix ``fix`` (t_stamp ns, lat, lon, h, ve, vn, sigma_lat, sigma_lon, sigma_alt,
    quality): the update into ``x`` (n,) and ``P`` when its normalised innovation squared is
    within the gate (returned: the NIS, negative when gated out and nothing changed)."""
    n = P.shape[0]
    s = np.zeros(H_COLS)
    tau = fix[0] - dt_hat * 1e9
    hist_at(hist, meta, tau, s)
    back = np.zeros(H_COLS)
    hist_at(hist, meta, tau - 2e8, back)
    ta = (s[0] - back[0]) * 1e-9
    C = np.zeros((3, 3))
    quat_dcm(s, 7, C)
    cl = C @ lever
    wl = np.array([s[12] * lever[2] - s[13] * lever[1], s[13] * lever[0] - s[11] * lever[2],
                   s[11] * lever[1] - s[12] * lever[0]])
    cwl = C @ wl
    has_v = math.isfinite(fix[4]) and math.isfinite(fix[5]) and r_vel > 0.0
    m = 5 if has_v else 3
    z = np.zeros(m)
    H = np.zeros((m, n))
    R = np.zeros((m, m))
    d = np.zeros(3)
    position_difference(s[1], s[2], s[3], fix[1], fix[2], fix[3], d)
    sig = (fix[7], fix[6], fix[8])  # GST: E from sigma_lon, N from sigma_lat
    for i in range(3):
        z[i] = d[i] + cl[i]
        H[i, DR + i] = 1.0
        H[i, MK + i] = -1.0
        if use_dt:
            H[i, DDT] = -s[4 + i]
        R[i, i] = max(sig[i] ** 2 - ms[i] ** 2, (floor * sig[i]) ** 2)
    _skew_rows(H, 0, PHI, cl[0], cl[1], cl[2])
    if has_v:
        Hv = np.zeros((3, n))
        _skew_rows(Hv, 0, PHI, cwl[0], cwl[1], cwl[2])
        for i in range(2):
            z[3 + i] = s[4 + i] + cwl[i] - fix[4 + i]
            for j in range(n):
                H[3 + i, j] = Hv[i, j]
            H[3 + i, DV + i] = 1.0
            if use_dt and ta > 0.0:
                H[3 + i, DDT] = -(s[4 + i] - back[4 + i]) / ta
            R[3 + i, 3 + i] = r_vel**2
    S = H @ P @ H.T + R
    q = float(z @ np.linalg.solve(S, z))
    if q > (gate5 if has_v else gate3):
        return -q
    joseph_update(x, P, z, H, R)
    return q


@njit(cache=True)
def nhc_update(
    P: np.ndarray, x: np.ndarray, sins: np.ndarray, w: np.ndarray, speed: float, lever: np.ndarray,
    nhc_lever: np.ndarray, r: np.ndarray
) -> None:
    """Odometer forward speed ``speed`` (compensated, m/s) at the wheel (lever arm
    ``lever``, body, m) and the non-holonomic constraint at the point ``nhc_lever`` (the
    rear axle's centre, where the body neither slides nor lifts): body velocity (right,
    forward, up) = (0 there, ``speed`` at the wheel, 0 there); ``w`` the body rate, rad/s;
    ``r`` (3,) noise sigmas, m/s."""
    n = P.shape[0]
    C = np.zeros((3, 3))
    quat_dcm(sins, 6, C)
    v = sins[3:6]
    vb = C.T @ v
    # the body velocity at a point l: vb + w x l (row 1 at the wheel, rows 0 and 2 at the NHC point)
    vb[0] += w[1] * nhc_lever[2] - w[2] * nhc_lever[1]
    vb[1] += w[2] * lever[0] - w[0] * lever[2]
    vb[2] += w[0] * nhc_lever[1] - w[1] * nhc_lever[0]
    sk = np.zeros((3, 3))
    _skew_rows(sk, 0, 0, v[0], v[1], v[2])
    Mphi = -(C.T @ sk)
    z = np.zeros(3)
    H = np.zeros((3, n))
    R = np.zeros((3, 3))
    for i in range(3):
        z[i] = vb[i] - (speed if i == 1 else 0.0)
        for j in range(3):
            H[i, DV + j] = C[j, i]
            H[i, PHI + j] = Mphi[i, j]
        R[i, i] = r[i] ** 2
    H[1, DK] = -speed
    joseph_update(x, P, z, H, R)
