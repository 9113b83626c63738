"""Compiled operations on the strapdown state shared by the reference estimators.

The SINS state is the 20-float array of :mod:`bench.nav.strapdown` (lat, lon, h, ENU
velocity, q_bn, the previous increments, the velocity history, a flag); the filters hold
the 15 core error states of :mod:`bench.estimators.ins_model` first in their state
vector. These functions apply the closed-loop feedback of the core states and run the
fine alignment's zero-velocity update, the standstill detector and its zero-velocity
update, and write the output epochs with NAV_QUALITY's sigmas saturated at the ICD's full
scale, for any estimator whose covariance starts with the core block.

The standstill detector (:func:`standstill_feed`, :func:`standstill`) works on the IMU:
the specific force put into the navigation frame and the body rate, each low-passed over
``standstill_time``; the vehicle stands when, for ``standstill_time``, the horizontal
specific force stays within ``standstill_accel`` (no acceleration, no tilt beyond it:
engine vibration and a rocking body average out), the rate within ``standstill_rate``,
and the INS speed within ``standstill_speed`` (a vehicle cruising straight at a constant
speed is as quiet as a parked one: its INS speed tells them apart). The estimator adds
its own aiding: a speed sensor that reads more than ``standstill_speed`` vetoes it.
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
    "zero_velocity",
    "zero_velocity_update",
    "standstill_feed",
    "standstill",
    "STILL_SIZE",
    "STILL_PRM",
    "SIGMA_POS_MAX",
    "SIGMA_VEL_MAX",
    "SIGMA_ATT_MAX",
]

#: NAV_QUALITY's full scale (ICD 2.2: uint16 at 0.01 m, 0.001 m/s, 0.01 arcmin): a sigma
#: beyond it is sent at full scale ("at least") and the epoch's solution flagged not valid
SIGMA_POS_MAX = 655.35  # m
SIGMA_VEL_MAX = 65.535  # m/s
SIGMA_ATT_MAX = math.radians(655.35 / 60.0)  # rad

#: the standstill detector's state: low-passed specific force ENU (3, m/s^2), low-passed
#: body rate (3, rad/s), quiet since (ns, -1 when not), primed flag
STILL_SIZE = 8
#: its parameters: on, time (s), horizontal specific force (m/s^2), rate (rad/s), speed
#: (m/s), zero-velocity noise (m/s)
STILL_PRM = 6


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
def zero_velocity(P: np.ndarray, x: np.ndarray, sins: np.ndarray, sigma: float) -> None:
    """Zero-velocity update (the vehicle stands): the ENU velocity of the SINS state
    ``sins`` measured zero (noise ``sigma``) on the core states of ``P``, into the estimate
    ``x`` (n,)."""
    n = P.shape[0]
    z = np.zeros(3)
    H = np.zeros((3, n))
    R = np.zeros((3, 3))
    for i in range(3):
        z[i] = sins[3 + i]
        H[i, DV + i] = 1.0
        R[i, i] = sigma**2
    joseph_update(x, P, z, H, R)


@njit(cache=True)
def zero_velocity_update(sins: np.ndarray, P: np.ndarray, sigma_v: float) -> np.ndarray:
    """A standstill: :func:`zero_velocity` from a zero estimate. Returns the estimate (n,)
    to feed back."""
    x = np.zeros(P.shape[0])
    zero_velocity(P, x, sins, sigma_v)
    return x


@njit(cache=True)
def standstill_feed(ss: np.ndarray, C: np.ndarray, th: np.ndarray, dv: np.ndarray, T: float, t: float,
                    prm: np.ndarray) -> None:
    """Feed one IMU interval (compensated increments ``th``, ``dv`` over ``T`` s ending at
    ``t`` ns, attitude C_bn ``C``) to the standstill detector ``ss`` (STILL_SIZE) with the
    parameters ``prm`` (STILL_PRM)."""
    if T <= 0.0:
        return
    tau = max(prm[1], 1e-3)
    a = 1.0 if ss[7] == 0.0 else min(T / tau, 1.0)
    for i in range(3):
        f = (C[i, 0] * dv[0] + C[i, 1] * dv[1] + C[i, 2] * dv[2]) / T
        ss[i] += a * (f - ss[i])
        ss[3 + i] += a * (th[i] / T - ss[3 + i])
    if ss[7] == 0.0:
        ss[7] = 1.0
        ss[6] = -1.0
        return
    quiet = math.sqrt(ss[0] ** 2 + ss[1] ** 2) <= prm[2] and math.sqrt(ss[3] ** 2 + ss[4] ** 2 + ss[5] ** 2) <= prm[3]
    if quiet:
        if ss[6] < 0.0:
            ss[6] = t
    else:
        ss[6] = -1.0


@njit(cache=True)
def standstill(ss: np.ndarray, sins: np.ndarray, t: float, prm: np.ndarray) -> bool:
    """True when the detector ``ss`` has been quiet for the standstill time at ``t`` (ns)
    and the INS speed of ``sins`` is within the standstill speed (detector switched on)."""
    if prm[0] <= 0.0 or ss[6] < 0.0 or t - ss[6] < prm[1] * 1e9:
        return False
    return math.sqrt(sins[3] ** 2 + sins[4] ** 2 + sins[5] ** 2) <= prm[4]


@njit(cache=True)
def write_attitude(C: np.ndarray, r) -> None:
    """The Euler angles of C_bn (ENU) into the NAV_SOLUTION record ``r``: heading in [0,
    2 pi) clockwise from north, pitch, roll."""
    hdg = math.atan2(C[0, 1], C[1, 1])
    r.heading = hdg + 2.0 * math.pi if hdg < 0.0 else hdg
    r.pitch = math.asin(min(1.0, max(-1.0, C[2, 1])))
    r.roll = math.atan2(-C[2, 0], C[2, 2])


@njit(cache=True)
def write_sigmas(q, C: np.ndarray, Pr: np.ndarray, Pv: np.ndarray, Pphi: np.ndarray) -> bool:
    """The NAV_QUALITY record ``q``'s sigmas from the ENU position, velocity and attitude
    error covariances (3, 3 each) and the attitude C_bn (Euler angles through
    :func:`~bench.estimators.ins_model.euler_jacobian`), each at most NAV_QUALITY's full
    scale. Returns True when one was beyond it (saturated: the caller flags the epoch's
    solution not valid)."""
    J = np.zeros((3, 3))
    euler_jacobian(C, J)
    Pe = J @ Pphi @ J.T
    sat = False
    for i in range(3):
        sp = math.sqrt(max(Pr[i, i], 0.0))
        sv = math.sqrt(max(Pv[i, i], 0.0))
        sa = math.sqrt(max(Pe[i, i], 0.0))
        if not (sp <= SIGMA_POS_MAX and sv <= SIGMA_VEL_MAX and sa <= SIGMA_ATT_MAX):  # NaN saturates too
            sat = True
        q.sigma_pos[i] = sp if sp <= SIGMA_POS_MAX else SIGMA_POS_MAX
        q.sigma_vel[i] = sv if sv <= SIGMA_VEL_MAX else SIGMA_VEL_MAX
        q.sigma_att[i] = sa if sa <= SIGMA_ATT_MAX else SIGMA_ATT_MAX
    return sat


@njit(cache=True)
def write_output(st: np.ndarray, off: int, P: np.ndarray, t: float, r, q) -> bool:
    """One output epoch at ``t`` (ns) from the SINS state ``st[off:off+10]`` and the core
    covariance: the NAV_SOLUTION record ``r`` (time, position, velocity, heading in [0, 2
    pi), pitch, roll) and the NAV_QUALITY record ``q`` (time and the 1-sigma position,
    velocity and Euler-angle sigmas, saturated at full scale). Mode, validity and the
    fault bytes are the caller's; returns True when a sigma saturated (the solution is
    then to be flagged not valid)."""
    C = np.zeros((3, 3))
    quat_dcm(st, off + 6, C)
    r.t_ns = np.int64(t)
    r.lat, r.lon, r.h = st[off], st[off + 1], st[off + 2]
    for i in range(3):
        r.vel_n[i] = st[off + 3 + i]
    write_attitude(C, r)
    q.t_ns = np.int64(t)
    return write_sigmas(q, C, P[DR : DR + 3, DR : DR + 3].copy(), P[DV : DV + 3, DV : DV + 3].copy(),
                        P[PHI : PHI + 3, PHI : PHI + 3].copy())
