"""Compiled step of the seed-002 SINS/odometer estimator of a tracked vehicle (numba).

One call per scheduler step runs, for every IMU frame of the step: bias compensation, the
SINS mechanization (:func:`bench.nav.strapdown._step`), the covariance time update, the
body-frame displacement of the INS since the last odometer measurement (seed eq. 11) and
the sums its measurement matrix needs; the odometer and driver-input samples that arrived
by then; and, every ``odometer_period``, the displacement-increment measurement (eq. 9-17)
under the tracked-vehicle constraint of the lever positions (eq. 1-8), tested by the
two-layer residual chi-square test (section 5.3) before it is applied; then the output
epochs with the NAV_QUALITY fault bytes.

State vector (18): the 15 core states of :mod:`bench.estimators.ins_model`, then the
odometer errors of eq. 10: yaw mounting, scale factor, pitch mounting (computed minus
true, fed back into the compensation ``st[S_OD:S_OD+3]``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.dut import FAULT_ODOMETER, MODE_INERTIAL, MODE_ODOMETER
from bench.estimators.ins_model import DV, N_CORE, PHI, discretize, ins_error_matrix
from bench.estimators.kf import time_update
from bench.estimators.seed002_meas import NOT_UPDATED, UPDATED_ALL, tested_update
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

__all__ = ["N_STATES", "ST_SIZE", "PRM_SIZE", "run_step", "MODEL_NAMES", "lever_model"]

N_STATES = N_CORE + 3
D_YAW, D_K, D_PITCH = N_CORE, N_CORE + 1, N_CORE + 2

# constraint models of the lever positions (seed section 3)
M_STRAIGHT_HIGH, M_STRAIGHT_LOW, M_PIVOT, M_CURVE, M_PARKED, M_SHIFTING, M_UNKNOWN = 0, 1, 2, 3, 4, 5, 6
MODEL_NAMES = ("straight high speed", "straight low speed", "turning in place", "turning in curve", "parked",
               "levers moving", "levers unknown")

# st layout
S_SINS = 0  # 20: strapdown state
S_BG, S_BA = 20, 23  # gyro and accelerometer bias compensation
S_OD = 26  # 3: odometer yaw mounting (rad), scale factor error, pitch mounting (rad) compensated
S_PHASE, S_TLAST, S_TSINCE = 29, 30, 31  # 1 fine alignment, 2 navigation; last IMU ns; since time update s
S_FN = 32  # 3: sum of C_bn dvel since the last time update
S_NEXT_OUT, S_ALIGN_END, S_MODE = 35, 36, 37
S_P0 = 38  # 3: surveyed position
S_TNOM = 41  # nominal IMU interval s
S_ACC_T = 42  # s accumulated in the current measurement period
S_DP = 43  # 3: INS body displacement at the odometer point since the period began (m)
S_HV = 46  # 18: (3 x 6) sum of the body-velocity Jacobian (phi, dv) times dt
S_SODO = 64  # odometer travel this period (m, signed, raw)
S_SW, S_SAW = 65, 66  # sum of w_z dt and |w_z| dt this period
S_PULSE = 67  # last pulse count (-1: none yet)
S_OT = 68  # ns of the last odometer sample
S_OBAD = 69  # 1: an invalid or missing odometer sample in this period
S_LL, S_LR, S_LT = 70, 71, 72  # lever positions (-1 unknown), ns of the last change
S_PMODEL = 73  # constraint model the period began in
S_FD, S_EX, S_CLS = 74, 75, 76  # NAV_QUALITY odometer flags of the last decision
S_TMEAS = 77  # ns at which the current period began
S_NUPD, S_NL1, S_NL2, S_NPIV = 78, 79, 80, 81  # full updates, layer-1 rejections, layer-2 rejections, abandoned
S_NIS = 82  # last layer-1 statistic
S_W = 83  # 3: body rate of the last interval, rad/s
S_LASTUPD = 86  # ns of the last odometer-based update
S_VB = 87  # 3: body velocity at the odometer point, last frame (m/s)
S_OCONS = 90  # odometer samples consumed by the last call (the rest wait for the IMU)
S_STILL = 92  # STILL_SIZE: the standstill detector (bench.estimators.sins_core)
ST_SIZE = S_STILL + STILL_SIZE

# prm layout
P_NG, P_NA, P_GB, P_AB, P_TU, P_OUT, P_ZUPT, P_RP0 = 0, 1, 2, 3, 4, 5, 6, 7
P_QG, P_QA = 8, 9  # bias random walks
P_PER = 10  # odometer measurement period, ns
P_PEQ = 11  # pulse equivalent, m
P_DET = 12  # 0 none, 1 single layer, 2 two layer
P_CON = 13  # constraints on
P_G3, P_G2 = 14, 15  # chi-square thresholds, 3 and 2 degrees of freedom
P_RATIO, P_GV, P_GR, P_LLAT = 16, 17, 18, 19  # low-speed ratio, curve gains (eq. 8), lateral length L (eq. 6)
P_SETTLE = 20  # s after a lever change before the odometer is used again
P_RN = 21  # 3: velocity noise sigmas of the model (right, forward, up), m/s
P_RCURVE = 24  # extra lateral and forward sigma in a curve, m/s
P_OL = 25  # 3: odometer point (body RFU, m)
P_KQ, P_AQ = 28, 29  # random walks of the scale factor (1/sqrt(s)) and the mountings (rad/sqrt(s))
P_MOVE = 30  # travel in a period below which the odometer counts as standing, m
P_OGAP = 31  # ns: an odometer sample later than this after the last one means samples were lost
P_LAT = 32  # odometer sample latency: sample time = arrival - this, ns
P_STILL = 34  # STILL_PRM: the standstill detector's parameters
PRM_SIZE = P_STILL + STILL_PRM


@njit(cache=True)
def _feedback(st: np.ndarray, x: np.ndarray) -> None:
    core_feedback(st[S_SINS : S_SINS + 20], st[S_BG : S_BG + 3], st[S_BA : S_BA + 3], x)
    st[S_OD] -= x[D_YAW]
    st[S_OD + 1] -= x[D_K]
    st[S_OD + 2] -= x[D_PITCH]


@njit(cache=True)
def _time_update(st: np.ndarray, P: np.ndarray, prm: np.ndarray, T: float) -> None:
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
    Qc[D_YAW, D_YAW] = prm[P_AQ] ** 2
    Qc[D_K, D_K] = prm[P_KQ] ** 2
    Qc[D_PITCH, D_PITCH] = prm[P_AQ] ** 2
    Phi = np.zeros((n, n))
    Qd = np.zeros((n, n))
    discretize(F, Qc, T, Phi, Qd)
    time_update(P, Phi, Qd)
    for i in range(3):
        st[S_FN + i] = 0.0
    st[S_TSINCE] = 0.0


@njit(cache=True)
def _catch_up(st: np.ndarray, P: np.ndarray, prm: np.ndarray) -> None:
    if st[S_TSINCE] > 0.0:
        _time_update(st, P, prm, st[S_TSINCE])


@njit(cache=True)
def lever_model(left: float, right: float, shifting: bool, constraints: bool) -> int:
    """The constraint model of the lever positions (0 most former, 1 position I, 2
    position II; -1 not known yet)."""
    if left < 0.0 or right < 0.0:
        return M_UNKNOWN
    if shifting:
        return M_SHIFTING
    if not constraints:
        return M_STRAIGHT_HIGH
    if left == 2.0 and right == 2.0:
        return M_PARKED
    if left == 2.0 or right == 2.0:
        return M_PIVOT
    if left == right:
        return M_STRAIGHT_HIGH if left == 0.0 else M_STRAIGHT_LOW
    return M_CURVE


@njit(cache=True)
def _restart_period(st: np.ndarray, t: float, model: int) -> None:
    for i in range(21):
        st[S_DP + i] = 0.0  # S_DP, S_HV
    st[S_SODO] = 0.0
    st[S_SW] = 0.0
    st[S_SAW] = 0.0
    st[S_ACC_T] = 0.0
    st[S_OBAD] = 0.0
    st[S_TMEAS] = t
    st[S_PMODEL] = model


@njit(cache=True)
def _accumulate(st: np.ndarray, prm: np.ndarray, C: np.ndarray, T: float) -> None:
    """Add one IMU interval to the period's INS displacement at the odometer point (eq.
    11, the rectangle rule at the interval's end) and to the Jacobian sums (eq. 17)."""
    v = st[S_SINS + 3 : S_SINS + 6]
    w = st[S_W : S_W + 3]
    lo = prm[P_OL : P_OL + 3]
    for i in range(3):
        vb = C[0, i] * v[0] + C[1, i] * v[1] + C[2, i] * v[2]
        st[S_VB + i] = vb
    # + w x l: the velocity of the odometer point
    st[S_VB] += w[1] * lo[2] - w[2] * lo[1]
    st[S_VB + 1] += w[2] * lo[0] - w[0] * lo[2]
    st[S_VB + 2] += w[0] * lo[1] - w[1] * lo[0]
    for i in range(3):
        st[S_DP + i] += st[S_VB + i] * T
    # d(vb)/d(phi) = -C' [v x], d(vb)/d(dv) = C'
    sk = np.zeros((3, 3))
    sk[0, 1], sk[0, 2] = -v[2], v[1]
    sk[1, 0], sk[1, 2] = v[2], -v[0]
    sk[2, 0], sk[2, 1] = -v[1], v[0]
    for i in range(3):
        for j in range(3):
            m = 0.0
            for k in range(3):
                m += C[k, i] * sk[k, j]
            st[S_HV + 6 * i + j] -= m * T
            st[S_HV + 6 * i + 3 + j] += C[j, i] * T
    st[S_SW] += w[2] * T
    st[S_SAW] += abs(w[2]) * T
    st[S_ACC_T] += T


@njit(cache=True)
def _measure(st: np.ndarray, P: np.ndarray, prm: np.ndarray, t: float, back: float) -> None:
    """The measurement of the period ending ``back`` s before the current IMU time ``t``."""
    model = int(st[S_PMODEL])
    T = st[S_ACC_T] - back
    det = prm[P_DET]
    if model in (M_SHIFTING, M_UNKNOWN) or st[S_OBAD] > 0.0 or T <= 0.0:
        st[S_FD], st[S_EX], st[S_CLS] = 0.0, 1.0, 0.0
        return
    ds = st[S_SODO]
    if model == M_PIVOT and abs(ds) >= prm[P_MOVE]:
        # turning in place: the tracks slide and idle, the odometer is abandoned (eq. 3 and
        # after); pure inertial until the turn ends. A detecting estimator reports it, class 2.
        st[S_NPIV] += 1.0
        st[S_EX] = 1.0
        st[S_FD] = 1.0 if det > 0.0 else 0.0
        st[S_CLS] = 2.0 if det > 0.0 else 0.0
        return
    _catch_up(st, P, prm)
    n = N_STATES
    ya, k, pa = st[S_OD], st[S_OD + 1], st[S_OD + 2]
    dsc = ds * (1.0 - k)  # odometer travel, scale compensated
    # forward travel in the odometer frame and the lateral travel (eq. 1, 2, 6, 8)
    fwd = dsc
    dfwd = ds  # d fwd / d(-k)
    lat = 0.0
    rl = prm[P_RN] ** 2
    rf = prm[P_RN + 1] ** 2
    if model == M_STRAIGHT_LOW:
        fwd = dsc / prm[P_RATIO]
        dfwd = ds / prm[P_RATIO]
    elif model == M_CURVE:
        fwd = prm[P_GV] * dsc + prm[P_GR] * st[S_SAW]
        dfwd = prm[P_GV] * ds
        lat = prm[P_LLAT] * st[S_SW]
        rl += prm[P_RCURVE] ** 2
        rf += prm[P_RCURVE] ** 2
    elif model in (M_PARKED, M_PIVOT):  # standing
        fwd = 0.0
        dfwd = 0.0
    # displacement in the body frame (eq. 9): the forward travel along the odometer's axis
    d0 = math.sin(ya) * math.cos(pa)
    d1 = math.cos(ya) * math.cos(pa)
    d2 = math.sin(pa)
    dp = np.empty(3)
    dp[0] = d0 * fwd + lat
    dp[1] = d1 * fwd
    dp[2] = d2 * fwd
    z = np.zeros(3)
    H = np.zeros((3, n))
    R = np.zeros((3, 3))
    # INS displacement up to the sample time: the part after it taken off
    for i in range(3):
        z[i] = st[S_DP + i] - back * st[S_VB + i] - dp[i]
        for j in range(6):
            H[i, PHI + j] = st[S_HV + 6 * i + j]
    # odometer error states (eq. 10, 17): dp_D = d(a) fwd(k): z = ... - d(dp_D)/d(xi) xi
    H[0, D_YAW] = -math.cos(ya) * math.cos(pa) * fwd
    H[1, D_YAW] = math.sin(ya) * math.cos(pa) * fwd
    H[0, D_K] = d0 * dfwd
    H[1, D_K] = d1 * dfwd
    H[2, D_K] = d2 * dfwd
    H[0, D_PITCH] = math.sin(ya) * math.sin(pa) * fwd
    H[1, D_PITCH] = math.cos(ya) * math.sin(pa) * fwd
    H[2, D_PITCH] = -math.cos(pa) * fwd
    q = prm[P_PEQ]
    R[0, 0] = rl * T * T + 1e-8
    R[1, 1] = rf * T * T + q * q / 6.0 + 1e-8  # two quantized counts
    R[2, 2] = prm[P_RN + 2] ** 2 * T * T + 1e-8
    x = np.zeros(n)
    done, cls, lam = tested_update(P, x, z, H, R, det, prm[P_G3], prm[P_G2])
    st[S_NIS] = lam
    if done != NOT_UPDATED:
        _feedback(st, x)
        st[S_LASTUPD] = t
    if done == UPDATED_ALL:
        st[S_NUPD] += 1.0
        st[S_FD], st[S_EX], st[S_CLS] = 0.0, 0.0, 0.0
        return
    st[S_NL1] += 1.0
    if done == NOT_UPDATED and det == 2.0:
        st[S_NL2] += 1.0
    st[S_FD], st[S_EX], st[S_CLS] = 1.0, 1.0, float(cls)


@njit(cache=True)
def _odo_sample(st: np.ndarray, P: np.ndarray, prm: np.ndarray, t: float, to: float, pulses: float,
                reverse: float, valid: float) -> None:
    """One odometer sample (arrival ``to`` ns) seen at the IMU time ``t`` (>= ``to``)."""
    ts = to - prm[P_LAT]  # the sample's time of validity
    if st[S_OT] > 0.0 and to - st[S_OT] > prm[P_OGAP]:
        st[S_OBAD] = 1.0  # samples lost: their travel with them
    st[S_OT] = to
    if st[S_PULSE] >= 0.0:
        dn = (pulses - st[S_PULSE]) % 65536.0
        st[S_SODO] += -dn * prm[P_PEQ] if reverse > 0.0 else dn * prm[P_PEQ]
    st[S_PULSE] = pulses
    if valid == 0.0:
        st[S_OBAD] = 1.0
    if st[S_PHASE] != 2.0:
        _restart_period(st, ts, st[S_PMODEL])
        return
    if ts - st[S_TMEAS] >= prm[P_PER] - 1e6:
        back = max(0.0, (t - ts) * 1e-9)
        _measure(st, P, prm, t, back)
        # the next period begins at the sample: the INS travel after it carried over
        vb = st[S_VB : S_VB + 3].copy()
        model = lever_model(st[S_LL], st[S_LR], t - st[S_LT] < prm[P_SETTLE] * 1e9, prm[P_CON] > 0.0)
        _restart_period(st, ts, model)
        for i in range(3):
            st[S_DP + i] = vb[i] * back
        st[S_ACC_T] = back


@njit(cache=True)
def _lever_sample(st: np.ndarray, prm: np.ndarray, t: float, left: float, right: float) -> None:
    if left != st[S_LL] or right != st[S_LR]:
        st[S_LL], st[S_LR], st[S_LT] = left, right, t
        st[S_PMODEL] = M_SHIFTING  # the period that saw the change is not used


@njit(cache=True)
def _output(st: np.ndarray, P: np.ndarray, prm: np.ndarray, t: float, sol: np.ndarray, qual: np.ndarray,
            k: int) -> None:
    r = sol[k]
    q = qual[k]
    sat = write_output(st, S_SINS, P, t, r, q)  # sigmas at most the ICD's full scale
    r.mode = np.uint8(st[S_MODE])
    r.valid = np.uint8(1 if st[S_PHASE] == 2.0 and not sat else 0)
    q.fault_detected = np.uint8(FAULT_ODOMETER if st[S_FD] > 0.0 else 0)
    q.excluded = np.uint8(FAULT_ODOMETER if st[S_EX] > 0.0 else 0)
    q.odo_fault_class = np.uint8(st[S_CLS])


@njit(cache=True)
def run_step(st, P, prm, dth, dvel, t_imu, o_t, o_p, o_r, o_ok, d_t, d_l, d_r, sol, qual) -> int:
    """Process one step's IMU frames (``dth``, ``dvel`` (N, 3), ``t_imu`` (N,) ns), its
    odometer samples (arrival ns, pulse count, reverse, valid; (M,)) and driver inputs
    (arrival ns, left lever, right lever; (L,)); epochs into ``sol``/``qual``. Returns the
    number of epochs."""
    n_out = 0
    j = 0
    jd = 0
    th = np.zeros(3)
    dv = np.zeros(3)
    C = np.zeros((3, 3))
    sins = st[S_SINS : S_SINS + 20]
    for k in range(t_imu.shape[0]):
        t = float(t_imu[k])
        while jd < d_t.shape[0] and d_t[jd] <= t:
            _lever_sample(st, prm, float(d_t[jd]), float(d_l[jd]), float(d_r[jd]))
            jd += 1
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
        quat_dcm(st, S_SINS + 6, C)
        standstill_feed(st[S_STILL : S_STILL + STILL_SIZE], C, th, dv, T, t, prm[P_STILL : P_STILL + STILL_PRM])
        for i in range(3):
            st[S_FN + i] += C[i, 0] * dv[0] + C[i, 1] * dv[1] + C[i, 2] * dv[2]
        st[S_TSINCE] += T
        nav = st[S_PHASE] == 2.0
        if nav:
            _accumulate(st, prm, C, T)
        if st[S_TSINCE] >= prm[P_TU] - 1e-6:
            _time_update(st, P, prm, st[S_TSINCE])
            if not nav:
                x = zupt_update(sins, P, st[S_P0 : S_P0 + 3], prm[P_ZUPT], prm[P_RP0])
                _feedback(st, x)
            elif not (st[S_PULSE] >= 0.0 and t - st[S_OT] <= prm[P_OGAP]) \
                    and standstill(st[S_STILL : S_STILL + STILL_SIZE], sins, t, prm[P_STILL : P_STILL + STILL_PRM]):
                # standing without the odometer (its own samples say standing when it reports)
                x = zero_velocity_update(sins, P, prm[P_STILL + 5])
                _feedback(st, x)
        if not nav and t >= st[S_ALIGN_END]:
            _catch_up(st, P, prm)
            x = zupt_update(sins, P, st[S_P0 : S_P0 + 3], prm[P_ZUPT], prm[P_RP0])
            _feedback(st, x)
            st[S_PHASE] = 2.0
            st[S_MODE] = MODE_INERTIAL
            model = lever_model(st[S_LL], st[S_LR], t - st[S_LT] < prm[P_SETTLE] * 1e9, prm[P_CON] > 0.0)
            _restart_period(st, t, model)
        while j < o_t.shape[0] and o_t[j] <= t:
            _odo_sample(st, P, prm, t, float(o_t[j]), float(o_p[j]), float(o_r[j]), float(o_ok[j]))
            j += 1
        if nav:
            st[S_MODE] = MODE_ODOMETER if t - st[S_LASTUPD] <= 2.0 * prm[P_PER] else MODE_INERTIAL
        if t >= st[S_NEXT_OUT] and t % prm[P_OUT] == 0.0:
            _output(st, P, prm, t, sol, qual, n_out)
            n_out += 1
            st[S_NEXT_OUT] = t + prm[P_OUT]
    st[S_OCONS] = j
    while jd < d_t.shape[0]:
        _lever_sample(st, prm, float(d_t[jd]), float(d_l[jd]), float(d_r[jd]))
        jd += 1
    return n_out
