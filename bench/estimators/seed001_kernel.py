"""Compiled step of the seed-001 BDS/SINS loose-integration estimator (numba).

One call per scheduler step runs, for every IMU frame of the step: bias compensation,
the SINS mechanization (:func:`bench.nav.strapdown._step`), the history of INS states
the fixes are compared at, the covariance time update, and the updates: the fine
alignment at rest (zero velocity and the surveyed position), BDS fixes when the INS
reaches their measurement time, the odometer with the non-holonomic constraint or a zero
velocity when stopped, with closed-loop feedback; then the output epochs. The state
vector is :mod:`bench.estimators.seed001_meas`'s; layouts of ``st`` and ``prm`` below.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.dut import FAULT_BDS, MODE_BDS, MODE_INERTIAL, MODE_MULTI_SENSOR, MODE_ODOMETER
from bench.estimators.ins_model import DV, PHI, discretize, ins_error_matrix, radii
from bench.estimators.kf import time_update
from bench.estimators.seed001_meas import DDT, DK, MK, N_STATES, bds_update, hist_push, nhc_update, zero_velocity
from bench.estimators.sins_core import (
    STILL_PRM,
    STILL_SIZE,
    core_feedback,
    quat_dcm,
    standstill,
    standstill_feed,
    write_output,
    zero_velocity_update,
    zupt_update,
)
from bench.nav.strapdown import _step

__all__ = ["N_STATES", "ST_SIZE", "PRM_SIZE", "HIST_LEN", "FIX_COLS", "run_step"]

# st layout
S_SINS = 0  # 20: strapdown state
S_BG, S_BA = 20, 23  # gyro and accelerometer bias compensation
S_K, S_DT = 26, 27  # odometer scale compensation, receiver time offset estimate (s)
S_PHASE, S_TLAST, S_TSINCE = 28, 29, 30  # 1 fine alignment, 2 navigation; last IMU ns; since time update s
S_FN = 31  # 3: sum of C_bn dvel since the last time update
S_OV, S_OOK, S_OT, S_STILL = 34, 35, 36, 37  # odometer speed, valid, arrival ns; ns since when ~0 (-1 moving)
S_NEXT_OUT, S_ALIGN_END, S_NEXT_ODO = 38, 39, 40
S_LAST_BDS, S_LAST_ODO, S_MODE = 41, 42, 43  # ns of the last accepted fix / odometer update
S_P0 = 44  # 3: surveyed position
S_TNOM, S_FD_UNTIL, S_EX_UNTIL = 47, 48, 49  # nominal IMU interval s; BDS fault / excluded flags until ns
S_EF, S_VF, S_EW = 50, 51, 52  # IMU stillness: mean |f|, its variance, mean |w| (exponential)
S_HMETA = 53  # 2: history count, head
S_NBDS, S_NREJ, S_NIS, S_NSKIP = 55, 56, 57, 58  # fixes accepted, gated out, last NIS, no-fix skipped
S_W = 59  # 3: body rate of the last interval, rad/s
S_CONSUMED = 62  # fixes consumed this call
S_SS = 64  # STILL_SIZE: the IMU standstill detector (bench.estimators.sins_core; S_STILL is the odometer's)
ST_SIZE = S_SS + STILL_SIZE

# prm layout
P_NG, P_NA, P_GB, P_AB, P_TU, P_OUT, P_ZUPT, P_RP0 = 0, 1, 2, 3, 4, 5, 6, 7
P_LA = 8  # 3: antenna lever arm (body RFU, m; zero when compensation is off)
P_TOE, P_DTS, P_DTQ = 11, 12, 13  # time-offset estimation on, prior sigma s, random walk s/sqrt(s)
P_MS = 14  # 3: Markov sigma of the receiver position error, m
P_MTAU, P_RVEL, P_GATE3, P_GATE5, P_FLOOR = 17, 18, 19, 20, 21
P_ODO, P_ODOPER, P_ODOR = 22, 23, 24  # odometer on, period ns, 3 noise sigmas (right, fwd, up) 24-26
P_OL = 27  # 3: odometer lever arm
P_KS, P_KQ = 30, 31  # scale-factor prior sigma, random walk 1/sqrt(s)
P_ZT, P_ZA, P_ZW, P_ZS, P_ZN = 32, 33, 34, 35, 36  # still time s, accel std, rate, speed, ZUPT noise
P_BDSAGE, P_ODOTO = 37, 38  # ns: BDS counts as aiding for, odometer sample valid for
P_QG, P_QA = 39, 40  # random-walk densities of the gyro and accelerometer biases (instability)
P_NL = 41  # 3: the point the non-holonomic constraint holds at (body RFU, m)
P_STILL = 44  # STILL_PRM: the standstill detector's parameters
PRM_SIZE = P_STILL + STILL_PRM
HIST_LEN = 400  # 2 s of 200 Hz frames
FIX_COLS = 10


@njit(cache=True)
def _feedback(st: np.ndarray, x: np.ndarray) -> None:
    core_feedback(st[S_SINS : S_SINS + 20], st[S_BG : S_BG + 3], st[S_BA : S_BA + 3], x)
    st[S_K] += x[DK]
    st[S_DT] -= x[DDT]
    # the Markov states are the receiver's, not the INS's: they stay in the state vector
    # (no feedback into the INS), carried by the next update as its prior


@njit(cache=True)
def _time_update(st: np.ndarray, P: np.ndarray, prm: np.ndarray, T: float, xm: np.ndarray) -> None:
    n = N_STATES
    F = np.zeros((n, n))
    Qc = np.zeros((n, n))
    C = np.zeros((3, 3))
    quat_dcm(st, S_SINS + 6, C)
    v = st[S_SINS + 3 : S_SINS + 6].copy()
    f_n = st[S_FN : S_FN + 3] / T
    ins_error_matrix(F, st[S_SINS], st[S_SINS + 2], v, f_n, C)
    for i in range(3):
        Qc[PHI + i, PHI + i] = prm[P_NG] ** 2
        Qc[DV + i, DV + i] = prm[P_NA] ** 2
        Qc[9 + i, 9 + i] = prm[P_QG] ** 2
        Qc[12 + i, 12 + i] = prm[P_QA] ** 2
        F[MK + i, MK + i] = -1.0 / prm[P_MTAU]
        Qc[MK + i, MK + i] = 2.0 * prm[P_MS + i] ** 2 / prm[P_MTAU]
    Qc[DK, DK] = prm[P_KQ] ** 2
    if prm[P_TOE] > 0.0:
        Qc[DDT, DDT] = prm[P_DTQ] ** 2
    Phi = np.zeros((n, n))
    Qd = np.zeros((n, n))
    discretize(F, Qc, T, Phi, Qd)
    time_update(P, Phi, Qd)
    d = math.exp(-T / prm[P_MTAU])
    for i in range(3):
        xm[i] *= d
        st[S_FN + i] = 0.0
    st[S_TSINCE] = 0.0


@njit(cache=True)
def _catch_up(st: np.ndarray, P: np.ndarray, prm: np.ndarray, xm: np.ndarray) -> None:
    if st[S_TSINCE] > 0.0:
        _time_update(st, P, prm, st[S_TSINCE], xm)


@njit(cache=True)
def _apply(st: np.ndarray, x: np.ndarray, xm: np.ndarray) -> None:
    """Feed an update's estimate back; the Markov part kept as the receiver's state."""
    for i in range(3):
        xm[i] += x[MK + i]
    _feedback(st, x)


@njit(cache=True)
def _fix(st, P, prm, fix, hist, xm, t) -> None:
    """One BDS fix at the IMU time ``t`` (ns): skipped without a fix, gated, or applied."""
    if fix[9] == 0.0 or not (math.isfinite(fix[1]) and math.isfinite(fix[2]) and math.isfinite(fix[3])):
        st[S_NSKIP] += 1.0
        st[S_EX_UNTIL] = t + 1.1e9
        return
    _catch_up(st, P, prm, xm)
    x = np.zeros(N_STATES)
    # the receiver's Markov estimate is the prior mean of its states: subtract it from z by
    # shifting the fix (z = ... - m): equivalent to a non-zero prior of those states
    f = fix.copy()
    lever = prm[P_LA : P_LA + 3].copy()
    ms = prm[P_MS : P_MS + 3].copy()
    _shift_fix(f, xm)
    q = bds_update(P, x, f, hist, st[S_HMETA : S_HMETA + 2], st[S_DT], lever, prm[P_TOE] > 0.0, ms,
                   prm[P_FLOOR], prm[P_RVEL], prm[P_GATE3], prm[P_GATE5])
    st[S_NIS] = abs(q)
    if q < 0.0:
        st[S_NREJ] += 1.0
        st[S_FD_UNTIL] = t + 1.1e9
        st[S_EX_UNTIL] = t + 1.1e9
        return
    _apply(st, x, xm)
    st[S_NBDS] += 1.0
    st[S_LAST_BDS] = t


@njit(cache=True)
def _shift_fix(f: np.ndarray, xm: np.ndarray) -> None:
    """Remove the estimated correlated error ``xm`` (E, N, U, m) from the fix position."""
    rmh, rnh = radii(f[1], f[3])
    f[1] -= xm[1] / rmh
    f[2] -= xm[0] / (math.cos(f[1]) * rnh)
    f[3] -= xm[2]


@njit(cache=True)
def _odometer(st, P, prm, xm, t) -> None:
    """At the odometer period: zero velocity when stopped, else speed + NHC."""
    fresh = st[S_OOK] > 0.0 and t - st[S_OT] <= prm[P_ODOTO]
    if not fresh:
        return
    _catch_up(st, P, prm, xm)
    x = np.zeros(N_STATES)
    sins = st[S_SINS : S_SINS + 20]
    still = (
        st[S_STILL] >= 0.0
        and t - st[S_STILL] >= prm[P_ZT] * 1e9
        and math.sqrt(max(st[S_VF], 0.0)) < prm[P_ZA]
        and st[S_EW] < prm[P_ZW]
    )
    if still:
        zero_velocity(P, x, sins, prm[P_ZN])
    else:
        r = prm[P_ODOR : P_ODOR + 3].copy()
        nhc_update(P, x, sins, st[S_W : S_W + 3].copy(), st[S_OV] * (1.0 - st[S_K]),
                   prm[P_OL : P_OL + 3].copy(), prm[P_NL : P_NL + 3].copy(), r)
    _apply(st, x, xm)
    st[S_LAST_ODO] = t


@njit(cache=True)
def _output(st: np.ndarray, P: np.ndarray, prm: np.ndarray, t: float, sol: np.ndarray, qual: np.ndarray,
            k: int) -> None:
    r = sol[k]
    q = qual[k]
    sat = write_output(st, S_SINS, P, t, r, q)
    r.mode = np.uint8(st[S_MODE])
    r.valid = np.uint8(1 if st[S_PHASE] == 2.0 and not sat else 0)
    q.fault_detected = np.uint8(FAULT_BDS if t < st[S_FD_UNTIL] else 0)
    q.excluded = np.uint8(FAULT_BDS if t < st[S_EX_UNTIL] else 0)


@njit(cache=True)
def _stillness(st: np.ndarray, th: np.ndarray, dv: np.ndarray, T: float) -> None:
    a = min(T / 0.5, 1.0)  # 0.5 s exponential windows
    f = math.sqrt(dv[0] ** 2 + dv[1] ** 2 + dv[2] ** 2) / T
    w = math.sqrt(th[0] ** 2 + th[1] ** 2 + th[2] ** 2) / T
    e = f - st[S_EF]
    st[S_EF] += a * e
    st[S_VF] = (1.0 - a) * (st[S_VF] + a * e * e)
    st[S_EW] += a * (w - st[S_EW])


@njit(cache=True)
def _odo_sample(st: np.ndarray, prm: np.ndarray, t: float, v: float, ok: int) -> None:
    st[S_OV] = v
    st[S_OOK] = 1.0 if ok else 0.0
    st[S_OT] = t
    if ok and abs(v) <= prm[P_ZS]:
        if st[S_STILL] < 0.0:
            st[S_STILL] = t
    else:
        st[S_STILL] = -1.0


@njit(cache=True)
def run_step(st, P, prm, xm, hist, dth, dvel, t_imu, o_t, o_v, o_ok, fixes, sol, qual) -> int:
    """Process one step's IMU frames (``dth``, ``dvel`` (N, 3), ``t_imu`` (N,) ns), its
    odometer samples (arrival ns, speed m/s, valid; (M,)) and the pending fixes
    ``fixes`` (K, 10), oldest first; epochs into ``sol``/``qual``. Returns the number of
    epochs; ``st[S_CONSUMED]`` the fixes used or dropped (the rest wait for the INS)."""
    n_out = 0
    j = 0
    nf = 0
    th = np.zeros(3)
    dv = np.zeros(3)
    C = np.zeros((3, 3))
    sins = st[S_SINS : S_SINS + 20]
    meta = st[S_HMETA : S_HMETA + 2]
    for k in range(t_imu.shape[0]):
        t = float(t_imu[k])
        while j < o_t.shape[0] and o_t[j] <= t:
            _odo_sample(st, prm, float(o_t[j]), o_v[j], o_ok[j])
            j += 1
        T = (t - st[S_TLAST]) * 1e-9
        st[S_TLAST] = t
        if T <= 0.0:
            continue
        if st[S_TNOM] * 1.5 < T:  # frames lost on the wire: their increments with them
            T = st[S_TNOM]
        for i in range(3):
            th[i] = dth[k, i] - st[S_BG + i] * T
            dv[i] = dvel[k, i] - st[S_BA + i] * T
            st[S_W + i] = th[i] / T
        _step(sins, th, dv, T)
        _stillness(st, th, dv, T)
        quat_dcm(st, S_SINS + 6, C)
        standstill_feed(st[S_SS : S_SS + STILL_SIZE], C, th, dv, T, t, prm[P_STILL : P_STILL + STILL_PRM])
        for i in range(3):
            st[S_FN + i] += C[i, 0] * dv[0] + C[i, 1] * dv[1] + C[i, 2] * dv[2]
        st[S_TSINCE] += T
        hist_push(hist, meta, t, sins, st[S_W : S_W + 3])
        nav = st[S_PHASE] == 2.0
        if st[S_TSINCE] >= prm[P_TU] - 1e-6:
            _time_update(st, P, prm, st[S_TSINCE], xm)
            if not nav:
                x = zupt_update(sins, P, st[S_P0 : S_P0 + 3], prm[P_ZUPT], prm[P_RP0])
                _feedback(st, x)
            elif not (prm[P_ODO] > 0.0 and st[S_OOK] > 0.0 and t - st[S_OT] <= prm[P_ODOTO]) \
                    and standstill(st[S_SS : S_SS + STILL_SIZE], sins, t, prm[P_STILL : P_STILL + STILL_PRM]):
                # standing without a fresh odometer (with one, its own zero-velocity update)
                x = zero_velocity_update(sins, P, prm[P_STILL + 5])
                _apply(st, x, xm)
        if not nav:
            while nf < fixes.shape[0] and fixes[nf, 0] <= t:  # fixes of the alignment: not used
                nf += 1
            if t >= st[S_ALIGN_END]:
                _catch_up(st, P, prm, xm)
                x = zupt_update(sins, P, st[S_P0 : S_P0 + 3], prm[P_ZUPT], prm[P_RP0])
                _feedback(st, x)
                st[S_PHASE] = 2.0
                st[S_NEXT_ODO] = t + prm[P_ODOPER]
                st[S_MODE] = MODE_INERTIAL
        else:
            while nf < fixes.shape[0] and fixes[nf, 0] - st[S_DT] * 1e9 <= t:
                _fix(st, P, prm, fixes[nf], hist, xm, t)
                nf += 1
            if prm[P_ODO] > 0.0 and t >= st[S_NEXT_ODO]:
                st[S_NEXT_ODO] += prm[P_ODOPER]
                _odometer(st, P, prm, xm, t)
            bds = t - st[S_LAST_BDS] <= prm[P_BDSAGE]
            odo = prm[P_ODO] > 0.0 and t - st[S_LAST_ODO] <= 2.0 * prm[P_ODOPER]
            if bds and odo:
                st[S_MODE] = MODE_MULTI_SENSOR
            elif bds:
                st[S_MODE] = MODE_BDS
            elif odo:
                st[S_MODE] = MODE_ODOMETER
            else:
                st[S_MODE] = MODE_INERTIAL
        if t >= st[S_NEXT_OUT] and t % prm[P_OUT] == 0.0:
            _output(st, P, prm, t, sol, qual, n_out)
            n_out += 1
            st[S_NEXT_OUT] = t + prm[P_OUT]
    while j < o_t.shape[0]:  # samples after the step's last IMU frame
        _odo_sample(st, prm, float(o_t[j]), o_v[j], o_ok[j])
        j += 1
    st[S_CONSUMED] = nf
    return n_out
