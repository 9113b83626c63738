"""The state of the seed-003 estimator's compiled step and what reads and writes it in
either navigation frame: the layouts of ``st`` and ``prm``, the frame's direction-cosine
matrices, the closed-loop feedback, the output epoch (geographic whatever the frame, ICD
2.2) and the output mode. The step itself: :mod:`bench.estimators.seed003_kernel`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from bench.dut import MODE_ALIGNING, MODE_BDS, MODE_DOPPLER, MODE_INERTIAL, MODE_MULTI_SENSOR
from bench.estimators.ins_model import DR, DV, EPS, N_CORE, NABLA, PHI
from bench.estimators.sins_core import (
    STILL_PRM,
    STILL_SIZE,
    core_feedback,
    quat_dcm,
    rotate_attitude,
    write_attitude,
    write_output,
    write_sigmas,
)
from bench.nav.ecef import enu_frame, geodetic, grid_frame

FRAME_GEOGRAPHIC, FRAME_GRID = 0.0, 1.0

N_STATES = N_CORE

# st layout
S_SINS = 0  # 20: ENU strapdown state (frame g) or ECEF state (frame G)
S_BG, S_BA = 20, 23  # gyro and accelerometer bias compensation
S_FRAME, S_MANUAL, S_PHASE = 26, 27, 28  # frame in use; 1 once a command chose it; 1 alignment, 2 navigation
S_TLAST, S_TSINCE = 29, 30  # last IMU time (ns), time since the last time update (s)
S_FN = 31  # 3: sum of C_b^n dvel (g) or C_b^e dvel (G) since the last time update
S_NEXT_OUT, S_ALIGN_END = 34, 35
S_P0 = 36  # 3: the surveyed position (alignment)
S_DV, S_DOK, S_DT = 39, 40, 41  # latest Doppler: speed, valid, arrival (ns)
S_NEXT_VEL, S_MODE, S_TNOM = 42, 43, 44  # next velocity update (ns), output mode, nominal IMU interval (s)
S_LAST_BDS, S_LAST_VEL = 45, 46  # ns of the last position / velocity update
S_NSWITCH, S_NREFUSED, S_NBDS, S_NREJ, S_NVEL = 47, 48, 49, 50, 51  # counters
S_CONSUMED, S_CCONSUMED = 52, 53  # fixes, commands consumed in this call
S_NIS, S_TSWITCH = 54, 55  # last position NIS; ns of the last switch
S_W = 56  # 3: body rate of the last interval, rad/s
S_STILL = 64  # STILL_SIZE: the standstill detector (bench.estimators.sins_core; geographic frame only)
ST_SIZE = S_STILL + STILL_SIZE

# prm layout
P_NG, P_NA, P_QG, P_QA, P_TU, P_OUT, P_ZUPT, P_RP0 = 0, 1, 2, 3, 4, 5, 6, 7
P_SWLAT, P_HYST, P_GLIM, P_AUTO, P_CONV = 8, 9, 10, 11, 12  # rad, rad, rad, 0/1, 1 convert / 0 restart / 2 copy
P_RDOP, P_RNHC, P_VELPER, P_DOPTO = 13, 14, 15, 16  # velocity aid sigmas (m/s), period and validity (ns)
P_GATE, P_AGE, P_RPOS = 17, 18, 19  # position chi-square gate (0 off), aiding age (ns), sigma floor (m)
P_S0 = 20  # 9: restart sigmas of attitude (E, N, U rad), velocity (m/s), position (m, E N U)
P_VEL = 29  # 1: use the velocity aid
P_STILL = 32  # STILL_PRM: the standstill detector's parameters
PRM_SIZE = P_STILL + STILL_PRM

# cos^2 L sin^2 lon above this: the grid frame's north (u x y_e) is too short to be defined
_GRID_SINGULAR = 0.99


@njit(cache=True)
def grid_dcms(st: np.ndarray, CeG: np.ndarray, Cen: np.ndarray) -> tuple[float, float, float]:
    """C_e^G and C_e^n at the ECEF position of ``st``; returns (lat, lon, h)."""
    lat, lon, h = geodetic(st[S_SINS], st[S_SINS + 1], st[S_SINS + 2])
    grid_frame(lat, lon, CeG)
    enu_frame(lat, lon, Cen)
    return lat, lon, h


@njit(cache=True)
def feedback(st: np.ndarray, x: np.ndarray) -> None:
    """Closed loop: the estimate into the navigation state of the frame in use and the
    bias compensations."""
    sins = st[S_SINS : S_SINS + 20]
    if st[S_FRAME] == FRAME_GEOGRAPHIC:
        core_feedback(sins, st[S_BG : S_BG + 3], st[S_BA : S_BA + 3], x)
        return
    CeG = np.empty((3, 3))
    Cen = np.empty((3, 3))
    grid_dcms(st, CeG, Cen)
    # C_b^e true = C_G^e (I + [phi_G x]) C_e^G C_b^e = (I + [C_G^e phi_G x]) C_b^e
    pe = CeG.T @ x[PHI : PHI + 3]
    rotate_attitude(sins, 6, pe[0], pe[1], pe[2])
    dve = CeG.T @ x[DV : DV + 3]
    for i in range(3):
        sins[3 + i] -= dve[i]
        sins[16 + i] -= dve[i]
        sins[i] -= x[DR + i]
        st[S_BG + i] += x[EPS + i]
        st[S_BA + i] += x[NABLA + i]


@njit(cache=True)
def nav_dcm_velocity(st: np.ndarray, C: np.ndarray, v: np.ndarray) -> None:
    """C_b^nav and the velocity in the frame in use (g: ENU; G: grid)."""
    quat_dcm(st, S_SINS + 6, C)
    if st[S_FRAME] == FRAME_GEOGRAPHIC:
        v[:] = st[S_SINS + 3 : S_SINS + 6]
        return
    CeG = np.empty((3, 3))
    Cen = np.empty((3, 3))
    grid_dcms(st, CeG, Cen)
    C[:, :] = CeG @ C.copy()
    v[:] = CeG @ st[S_SINS + 3 : S_SINS + 6]


@njit(cache=True)
def output(st: np.ndarray, P: np.ndarray, t: float, r, q) -> None:
    """One epoch, geographic whatever the frame (ICD 2.2); byte 44's frame bits."""
    if st[S_FRAME] == FRAME_GEOGRAPHIC:
        sat = write_output(st, S_SINS, P, t, r, q)
    else:
        CeG = np.empty((3, 3))
        Cen = np.empty((3, 3))
        lat, lon, h = grid_dcms(st, CeG, Cen)
        Cbe = np.empty((3, 3))
        quat_dcm(st, S_SINS + 6, Cbe)
        C = Cen @ Cbe
        r.t_ns = np.int64(t)
        r.lat, r.lon, r.h = lat, lon, h
        ve = Cen @ np.ascontiguousarray(st[S_SINS + 3 : S_SINS + 6])
        for i in range(3):
            r.vel_n[i] = ve[i]
        write_attitude(C, r)
        q.t_ns = np.int64(t)
        M = Cen @ CeG.T  # G to ENU
        sat = write_sigmas(q, C, Cen @ P[DR : DR + 3, DR : DR + 3] @ Cen.T, M @ P[DV : DV + 3, DV : DV + 3] @ M.T,
                           M @ P[PHI : PHI + 3, PHI : PHI + 3] @ M.T)
    r.frame = np.uint8(st[S_FRAME])
    r.mode = np.uint8(st[S_MODE])
    r.valid = np.uint8(1 if st[S_PHASE] == 2.0 and not sat else 0)  # a sigma beyond full scale: not valid


@njit(cache=True)
def latitude(st: np.ndarray) -> float:
    if st[S_FRAME] == FRAME_GEOGRAPHIC:
        return st[S_SINS]
    return geodetic(st[S_SINS], st[S_SINS + 1], st[S_SINS + 2])[0]


@njit(cache=True)
def output_mode(st: np.ndarray, prm: np.ndarray, t: float) -> float:
    if st[S_PHASE] != 2.0:
        return float(MODE_ALIGNING)
    pos = t - st[S_LAST_BDS] <= prm[P_AGE]
    vel = t - st[S_LAST_VEL] <= prm[P_AGE]
    if pos and vel:
        return float(MODE_MULTI_SENSOR)
    if pos:
        return float(MODE_BDS)
    if vel:
        return float(MODE_DOPPLER)
    return float(MODE_INERTIAL)
