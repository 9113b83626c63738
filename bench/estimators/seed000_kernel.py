"""Compiled step of the seed-000 SINS / Doppler-radar estimator (numba).

One call per scheduler step runs, for every IMU frame of the step: the bias compensation,
the SINS mechanization (:func:`bench.nav.strapdown._step`, the bench's own), the
dead-reckoning system (DRS) on the same gyro increments with the Doppler speed
(:func:`bench.estimators._dr_kernel.dr_step`), the covariance time update, the fine
alignment's zero-velocity updates or the integrated filter's measurement update with
closed-loop feedback, and the output epochs. Layouts of ``st`` and ``prm`` below; the
state vector (24) is the core's 15 (:mod:`bench.estimators.ins_model`) and::

    15-17 phi_D   DRS attitude error, rad (E, N, U)
    18-20 dr_D    DRS position error, m (E, N, U)
    21    dK      Doppler scale-factor error (first-order Markov)
    22-23 dkx, dkz  direction of motion in the body frame (yaw right, pitch up), rad
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.dut import FAULT_DOPPLER, MODE_DOPPLER, MODE_INERTIAL
from bench.estimators._dr_kernel import dr_step, motion_direction
from bench.estimators.ins_model import (
    DR,
    DV,
    N_CORE,
    PHI,
    discretize,
    ins_error_matrix,
    position_difference,
    position_rate_matrix,
)
from bench.estimators.kf import joseph_update, time_update
from bench.estimators.sins_core import (
    STILL_PRM,
    STILL_SIZE,
    core_feedback,
    move_position,
    quat_dcm,
    rotate_attitude,
    standstill,
    standstill_feed,
    write_output,
    zero_velocity_update,
    zupt_update,
)
from bench.nav.strapdown import _step

__all__ = ["N_STATES", "ST_SIZE", "PRM_SIZE", "run_step"]

N_STATES = 24
PHID, DRD, DK, KX, KZ = 15, 18, 21, 22, 23

# st layout
S_SINS = 0  # 20: strapdown state (lat, lon, h, v (3), q (4), history, flag)
S_DR = 20  # 12: DRS state (lat, lon, h, q (4), prev dtheta (3), prev speed, distance)
S_BG, S_BA = 32, 35  # gyro and accelerometer bias compensation (3 each)
S_K, S_UX, S_UZ = 38, 39, 40  # Doppler scale compensation, direction of motion (x, z)
S_PHASE = 41  # 1 fine alignment, 2 navigation
S_TLAST, S_TSINCE = 42, 43  # last IMU time (ns), time since the last time update (s)
S_FN = 44  # 3: sum of C_bn dvel since the last time update
S_DV, S_DOK, S_DLOW, S_DT = 47, 48, 49, 50  # latest Doppler: speed, valid, low signal, arrival (ns)
S_NEXT_OUT, S_ALIGN_END, S_NEXT_MU = 51, 53, 54  # 52 unused
S_DR_ON, S_MODE = 55, 56
S_P0 = 57  # 3: the surveyed position (lat, lon, h) held in the alignment
S_UPDATES, S_EXCL, S_TNOM = 60, 61, 62  # updates made, Doppler excluded, nominal IMU interval (s)
S_STILL = 64  # STILL_SIZE: the standstill detector (bench.estimators.sins_core)
ST_SIZE = S_STILL + STILL_SIZE

# prm layout
P_NG, P_NA, P_SD, P_DRATE, P_SK, P_TK = 0, 1, 2, 3, 4, 5
P_TU, P_MU, P_MODE, P_RATT, P_RPOS, P_RVEL, P_ZUPT, P_RP0 = 6, 7, 8, 9, 10, 11, 12, 13
P_OUT, P_LOWF, P_DTIMEOUT, P_SMOUNT, P_GB, P_AB, P_SHARED = 14, 15, 16, 17, 18, 19, 20
P_STILL = 24  # STILL_PRM: the standstill detector's parameters
PRM_SIZE = P_STILL + STILL_PRM



@njit(cache=True)
def _feedback(st: np.ndarray, x: np.ndarray, nav: bool) -> None:
    """Closed loop: the estimate into the SINS, the DRS and the sensor compensations."""
    core_feedback(st[S_SINS : S_SINS + 20], st[S_BG : S_BG + 3], st[S_BA : S_BA + 3], x)
    if nav:
        rotate_attitude(st, S_DR + 3, x[PHID], x[PHID + 1], x[PHID + 2])
        move_position(st, S_DR, x[DRD], x[DRD + 1], x[DRD + 2])
        st[S_K] += x[DK]
        st[S_UX] -= x[KX]
        st[S_UZ] -= x[KZ]


@njit(cache=True)
def _dr_from_sins(st: np.ndarray, P: np.ndarray, prm: np.ndarray, first: bool) -> None:
    """Start (or restart after a Doppler outage) the DRS from the SINS: same attitude and
    position, so its errors are the SINS's; the covariance copied accordingly."""
    for i in range(3):
        st[S_DR + i] = st[S_SINS + i]
        st[S_DR + 7 + i] = 0.0
    for i in range(4):
        st[S_DR + 3 + i] = st[S_SINS + 6 + i]
    st[S_DR + 10] = st[S_DV] / (1.0 + st[S_K]) if st[S_DOK] > 0.0 else 0.0
    n = N_STATES
    M = np.eye(n)
    for i in range(3):
        M[PHID + i, PHID + i] = 0.0
        M[PHID + i, PHI + i] = 1.0
        M[DRD + i, DRD + i] = 0.0
        M[DRD + i, DR + i] = 1.0
    P[:, :] = M @ P @ M.T
    if first:
        P[DK, DK] = prm[P_SK] ** 2
        P[KX, KX] = prm[P_SMOUNT] ** 2
        P[KZ, KZ] = prm[P_SMOUNT] ** 2
    st[S_DR_ON] = 1.0


@njit(cache=True)
def _time_update(st: np.ndarray, P: np.ndarray, prm: np.ndarray, T: float) -> None:
    n = N_STATES
    F = np.zeros((n, n))
    Qc = np.zeros((n, n))
    C = np.zeros((3, 3))
    quat_dcm(st, S_SINS + 6, C)
    v = st[S_SINS + 3 : S_SINS + 6].copy()
    f_n = st[S_FN : S_FN + 3] / T
    lat, h = st[S_SINS], st[S_SINS + 2]
    ins_error_matrix(F, lat, h, v, f_n, C)
    ng2, na2 = prm[P_NG] ** 2, prm[P_NA] ** 2
    for i in range(3):
        Qc[PHI + i, PHI + i] = ng2
        Qc[DV + i, DV + i] = na2
    if st[S_PHASE] == 2.0 and st[S_DR_ON] == 1.0:
        Cd = np.zeros((3, 3))
        quat_dcm(st, S_DR + 3, Cd)
        s = st[S_DR + 10]
        ux, uz = st[S_UX], st[S_UZ]
        u0, u1, u2 = motion_direction(st[S_DR + 3], st[S_DR + 4], st[S_DR + 5], st[S_DR + 6], ux, uz)
        vd = np.array([s * u0, s * u1, s * u2])
        # dv_D = [v x] phi_D + v dK + s C[:,0] dkx + s C[:,2] dkz, as columns on the states
        Bv = np.zeros((3, n))
        Bv[0, PHID + 1], Bv[0, PHID + 2] = -vd[2], vd[1]
        Bv[1, PHID + 0], Bv[1, PHID + 2] = vd[2], -vd[0]
        Bv[2, PHID + 0], Bv[2, PHID + 1] = -vd[1], vd[0]
        for i in range(3):
            Bv[i, DK] = vd[i]
            Bv[i, KX] = s * Cd[i, 0]
            Bv[i, KZ] = s * Cd[i, 2]
        # the DRS attitude: the core's attitude rows with its own velocity and position
        Fd = np.zeros((N_CORE, N_CORE))
        ins_error_matrix(Fd, st[S_DR], st[S_DR + 2], vd, f_n, Cd)
        Frr = np.zeros((3, 3))
        position_rate_matrix(st[S_DR], st[S_DR + 2], vd, Frr)
        for i in range(3):
            for j in range(3):
                F[PHID + i, PHID + j] += Fd[PHI + i, PHI + j]
                F[PHID + i, DRD + j] += Fd[PHI + i, DR + j]
                F[PHID + i, 9 + j] = -Cd[i, j]
                F[DRD + i, DRD + j] += Frr[i, j]
            for j in range(n):
                acc = 0.0
                for m in range(3):
                    acc += Fd[PHI + i, DV + m] * Bv[m, j]
                F[PHID + i, j] += acc
                F[DRD + i, j] += Bv[i, j]
        F[DK, DK] = -1.0 / prm[P_TK]
        # the gyro noise drives both attitudes: fully correlated (the same gyros), unless
        # the configuration asks for the independent noises of a filter that ignores it
        for i in range(3):
            Qc[PHID + i, PHID + i] = ng2
            if prm[P_SHARED] > 0.0:
                Qc[PHI + i, PHID + i] = ng2
                Qc[PHID + i, PHI + i] = ng2
        low = prm[P_LOWF] if st[S_DLOW] > 0.0 else 1.0
        qd = (prm[P_SD] * low) ** 2 / prm[P_DRATE]  # white speed noise, m^2/s along the motion
        for i in range(3):
            for j in range(3):
                Qc[DRD + i, DRD + j] = qd * Cd[i, 1] * Cd[j, 1]
        Qc[DK, DK] = 2.0 * prm[P_SK] ** 2 / prm[P_TK]
    Phi = np.zeros((n, n))
    Qd = np.zeros((n, n))
    discretize(F, Qc, T, Phi, Qd)
    time_update(P, Phi, Qd)
    for i in range(3):
        st[S_FN + i] = 0.0
    st[S_TSINCE] = 0.0


@njit(cache=True)
def _zupt(st: np.ndarray, P: np.ndarray, prm: np.ndarray) -> None:
    """Fine alignment: zero velocity and the surveyed position."""
    x = zupt_update(st[S_SINS : S_SINS + 20], P, st[S_P0 : S_P0 + 3], prm[P_ZUPT], prm[P_RP0])
    _feedback(st, x, False)


@njit(cache=True)
def _standstill(st: np.ndarray, P: np.ndarray, prm: np.ndarray, t: float) -> None:
    """Navigating: a zero-velocity update when the vehicle stands (the detector quiet, the
    INS slow, and the Doppler radar, when it reports, reading no more than the standstill
    speed)."""
    ps = prm[P_STILL : P_STILL + STILL_PRM]
    if not standstill(st[S_STILL : S_STILL + STILL_SIZE], st[S_SINS : S_SINS + 20], t, ps):
        return
    if st[S_DOK] > 0.0 and t - st[S_DT] <= prm[P_DTIMEOUT] and abs(st[S_DV]) > ps[4]:
        return
    x = zero_velocity_update(st[S_SINS : S_SINS + 20], P, ps[5])
    _feedback(st, x, st[S_DR_ON] == 1.0)


@njit(cache=True)
def _measure(st: np.ndarray, P: np.ndarray, prm: np.ndarray) -> None:
    """The integrated filter's update: SINS minus DRS attitude (or velocity) and position."""
    n = N_STATES
    z = np.zeros(6)
    H = np.zeros((6, n))
    R = np.zeros((6, 6))
    d = np.zeros(3)
    position_difference(st[S_SINS], st[S_SINS + 1], st[S_SINS + 2], st[S_DR], st[S_DR + 1], st[S_DR + 2], d)
    for i in range(3):
        z[3 + i] = d[i]
        H[3 + i, DR + i] = 1.0
        H[3 + i, DRD + i] = -1.0
        R[3 + i, 3 + i] = prm[P_RPOS] ** 2
    Cd = np.zeros((3, 3))
    quat_dcm(st, S_DR + 3, Cd)
    if prm[P_MODE] == 0.0:  # attitude + position: rotation vector of C_D C_S' = phi - phi_D
        Cs = np.zeros((3, 3))
        quat_dcm(st, S_SINS + 6, Cs)
        M = Cd @ Cs.T
        z[0] = 0.5 * (M[2, 1] - M[1, 2])
        z[1] = 0.5 * (M[0, 2] - M[2, 0])
        z[2] = 0.5 * (M[1, 0] - M[0, 1])
        for i in range(3):
            H[i, PHI + i] = 1.0
            H[i, PHID + i] = -1.0
            R[i, i] = prm[P_RATT] ** 2
    else:  # velocity + position: v_S - C_D s u
        s = st[S_DV] / (1.0 + st[S_K])
        u0, u1, u2 = motion_direction(st[S_DR + 3], st[S_DR + 4], st[S_DR + 5], st[S_DR + 6], st[S_UX], st[S_UZ])
        vd = np.array([s * u0, s * u1, s * u2])
        for i in range(3):
            z[i] = st[S_SINS + 3 + i] - vd[i]
            H[i, DV + i] = 1.0
            H[i, DK] = -vd[i]
            H[i, KX] = -s * Cd[i, 0]
            H[i, KZ] = -s * Cd[i, 2]
        H[0, PHID + 1], H[0, PHID + 2] = vd[2], -vd[1]
        H[1, PHID + 0], H[1, PHID + 2] = -vd[2], vd[0]
        H[2, PHID + 0], H[2, PHID + 1] = vd[1], -vd[0]
        low = prm[P_LOWF] if st[S_DLOW] > 0.0 else 1.0
        sd2 = (prm[P_SD] * low) ** 2
        for i in range(3):
            for j in range(3):
                R[i, j] = sd2 * Cd[i, 1] * Cd[j, 1]
            R[i, i] += prm[P_RVEL] ** 2
    x = np.zeros(n)
    joseph_update(x, P, z, H, R)
    _feedback(st, x, True)
    st[S_UPDATES] += 1.0


@njit(cache=True)
def _output(st: np.ndarray, P: np.ndarray, t: float, sol: np.ndarray, qual: np.ndarray, k: int) -> None:
    r = sol[k]
    q = qual[k]
    sat = write_output(st, S_SINS, P, t, r, q)
    r.mode = np.uint8(st[S_MODE])
    r.valid = np.uint8(1 if st[S_PHASE] == 2.0 and not sat else 0)
    q.excluded = np.uint8(FAULT_DOPPLER if st[S_EXCL] > 0.0 else 0)


@njit(cache=True)
def run_step(
    st: np.ndarray,
    P: np.ndarray,
    prm: np.ndarray,
    dth: np.ndarray,
    dvel: np.ndarray,
    t_imu: np.ndarray,
    d_t: np.ndarray,
    d_v: np.ndarray,
    d_ok: np.ndarray,
    d_low: np.ndarray,
    sol: np.ndarray,
    qual: np.ndarray,
) -> int:
    """Process one step's IMU frames (``dth``, ``dvel`` (N, 3), ``t_imu`` (N,) ns) and
    Doppler samples (arrival ns, speed m/s, valid, low signal; (M,)), writing the output
    epochs into ``sol``/``qual`` (length >= N). Returns the number of epochs written."""
    n_out = 0
    j = 0
    th = np.zeros(3)
    dv = np.zeros(3)
    C = np.zeros((3, 3))
    sins = st[S_SINS : S_SINS + 20]
    for k in range(t_imu.shape[0]):
        t = float(t_imu[k])
        while j < d_t.shape[0] and d_t[j] <= t:
            st[S_DV] = d_v[j]
            st[S_DOK] = 1.0 if d_ok[j] else 0.0
            st[S_DLOW] = 1.0 if d_low[j] else 0.0
            st[S_DT] = float(d_t[j])
            j += 1
        T = (t - st[S_TLAST]) * 1e-9
        st[S_TLAST] = t
        if T <= 0.0:
            continue
        if st[S_TNOM] * 1.5 < T:  # frames lost on the wire: their increments are lost with them
            T = st[S_TNOM]
        for i in range(3):
            th[i] = dth[k, i] - st[S_BG + i] * T
            dv[i] = dvel[k, i] - st[S_BA + i] * T
        _step(sins, th, dv, T)
        quat_dcm(st, S_SINS + 6, C)
        standstill_feed(st[S_STILL : S_STILL + STILL_SIZE], C, th, dv, T, t, prm[P_STILL : P_STILL + STILL_PRM])
        for i in range(3):
            st[S_FN + i] += C[i, 0] * dv[0] + C[i, 1] * dv[1] + C[i, 2] * dv[2]
        st[S_TSINCE] += T
        nav = st[S_PHASE] == 2.0
        if nav:
            usable = st[S_DOK] > 0.0 and t - st[S_DT] <= prm[P_DTIMEOUT]
            if usable and st[S_DR_ON] == 1.0:
                s = st[S_DV] / (1.0 + st[S_K])
                dr_step(st[S_DR : S_DR + 12], th[0], th[1], th[2], T, s, st[S_UX], st[S_UZ])
            elif usable:
                if st[S_TSINCE] > 0.0:
                    _time_update(st, P, prm, st[S_TSINCE])
                _dr_from_sins(st, P, prm, False)
            else:
                st[S_DR_ON] = 0.0
            st[S_MODE] = MODE_DOPPLER if st[S_DR_ON] == 1.0 else MODE_INERTIAL
            st[S_EXCL] = 0.0 if st[S_DR_ON] == 1.0 else 1.0
            st[S_K] *= math.exp(-T / prm[P_TK])
        if st[S_TSINCE] >= prm[P_TU] - 1e-6:
            _time_update(st, P, prm, st[S_TSINCE])
            if not nav:
                _zupt(st, P, prm)
            else:
                _standstill(st, P, prm, t)
        if not nav and t >= st[S_ALIGN_END]:
            if st[S_TSINCE] > 0.0:
                _time_update(st, P, prm, st[S_TSINCE])
            _zupt(st, P, prm)
            st[S_PHASE] = 2.0
            _dr_from_sins(st, P, prm, True)
            st[S_MODE] = MODE_DOPPLER
            st[S_NEXT_MU] = t + prm[P_MU]
        elif nav and t >= st[S_NEXT_MU]:
            st[S_NEXT_MU] += prm[P_MU]
            if st[S_DR_ON] == 1.0:
                if st[S_TSINCE] > 0.0:
                    _time_update(st, P, prm, st[S_TSINCE])
                _measure(st, P, prm)
        if t >= st[S_NEXT_OUT] and t % prm[P_OUT] == 0.0:
            _output(st, P, t, sol, qual, n_out)
            n_out += 1
            st[S_NEXT_OUT] = t + prm[P_OUT]
    while j < d_t.shape[0]:  # samples after the step's last IMU frame (or a step without one)
        st[S_DV] = d_v[j]
        st[S_DOK] = 1.0 if d_ok[j] else 0.0
        st[S_DLOW] = 1.0 if d_low[j] else 0.0
        st[S_DT] = float(d_t[j])
        j += 1
    return n_out
