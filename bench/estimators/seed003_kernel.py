"""Compiled step of the seed-003 estimator: SINS / position / velocity integration in the
geographic frame g or the polar grid frame G, and the switch between them (numba).

One call per scheduler step runs, for every IMU frame of the step: the bias
compensation; the mechanization of the frame in use (g: :func:`bench.nav.strapdown._step`,
latitude, longitude, height, ENU velocity, C_b^n; G: :func:`bench.nav.ecef.step_e`, ECEF
position, velocity and C_b^e, whose projections on G, ``C_e^G``, are seed 003's grid-frame
navigation parameters); the commands and the automatic switch; the covariance time update
(g: :func:`bench.estimators.ins_model.ins_error_matrix`, seed eq. 9-13; G:
:func:`bench.estimators.grid_model.grid_error_matrix`, eq. 18-22); the fine alignment's
zero-velocity updates at rest, then the position fixes (g: ENU metres; G: ECEF, eq. 24) and
the velocity aid (the Doppler forward speed with the non-holonomic constraint, in the body
frame), with closed-loop feedback; and the output epochs, geographic whatever the frame
(ICD 2.2).

A switch converts the navigation parameters (eq. 23, 26-27) and, with ``P_CONV`` = 1, the
filter's covariance (eq. 28-38, :mod:`bench.estimators.frame_switch`); with 0 it restarts
the attitude, velocity and position covariance in the new frame from the configured
initial sigmas (the paper's comparison), with 2 it keeps the matrix as it is.

The 15 states: attitude error (0-2, in the frame in use), velocity error (3-5, idem),
position error (6-8: metres E, N, U in g; ECEF metres in G), gyro (9-11) and accelerometer
(12-14) biases in the body frame; computed minus true (:mod:`bench.estimators.ins_model`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.estimators.frame_switch import covariance_to_geographic, covariance_to_grid
from bench.estimators.grid_model import grid_error_matrix
from bench.estimators.ins_model import (
    DR,
    DV,
    EPS,
    NABLA,
    PHI,
    discretize,
    ins_error_matrix,
)
from bench.estimators.kf import time_update
from bench.estimators.seed003_meas import position_update, velocity_update
from bench.estimators.seed003_state import (
    _GRID_SINGULAR,
    FRAME_GEOGRAPHIC,
    FRAME_GRID,
    N_STATES,
    P_AUTO,
    P_CONV,
    P_DOPTO,
    P_GLIM,
    P_HYST,
    P_NA,
    P_NG,
    P_OUT,
    P_QA,
    P_QG,
    P_RP0,
    P_S0,
    P_STILL,
    P_SWLAT,
    P_TU,
    P_VEL,
    P_VELPER,
    P_ZUPT,
    S_ALIGN_END,
    S_BA,
    S_BG,
    S_CCONSUMED,
    S_CONSUMED,
    S_DOK,
    S_DT,
    S_DV,
    S_FN,
    S_FRAME,
    S_MANUAL,
    S_MODE,
    S_NEXT_OUT,
    S_NEXT_VEL,
    S_NREFUSED,
    S_NSWITCH,
    S_P0,
    S_PHASE,
    S_SINS,
    S_STILL,
    S_TLAST,
    S_TNOM,
    S_TSINCE,
    S_TSWITCH,
    S_W,
    feedback,
    grid_dcms,
    latitude,
    nav_dcm_velocity,
    output,
    output_mode,
)
from bench.estimators.sins_core import (
    STILL_PRM,
    STILL_SIZE,
    quat_dcm,
    standstill,
    standstill_feed,
    zero_velocity_update,
    zupt_update,
)
from bench.nav.ecef import enu_frame, from_geographic, geodetic, grid_frame, step_e, to_geographic
from bench.nav.strapdown import _step

__all__ = ["run_step", "switch_frame", "restart_covariance"]

@njit(cache=True)
def _time_update(st: np.ndarray, P: np.ndarray, prm: np.ndarray, T: float) -> None:
    n = N_STATES
    F = np.zeros((n, n))
    Qc = np.zeros((n, n))
    C = np.zeros((3, 3))
    v = np.zeros(3)
    nav_dcm_velocity(st, C, v)
    if st[S_FRAME] == FRAME_GEOGRAPHIC:
        f_n = st[S_FN : S_FN + 3] / T
        ins_error_matrix(F, st[S_SINS], st[S_SINS + 2], v, f_n, C)
    else:
        CeG = np.empty((3, 3))
        Cen = np.empty((3, 3))
        lat, _, h = grid_dcms(st, CeG, Cen)
        f_G = CeG @ (st[S_FN : S_FN + 3] / T)
        grid_error_matrix(F, lat, h, CeG, v, f_G, C)
    for i in range(3):
        Qc[PHI + i, PHI + i] = prm[P_NG] ** 2
        Qc[DV + i, DV + i] = prm[P_NA] ** 2
        Qc[EPS + i, EPS + i] = prm[P_QG] ** 2
        Qc[NABLA + i, NABLA + i] = prm[P_QA] ** 2
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
def restart_covariance(st: np.ndarray, P: np.ndarray, prm: np.ndarray) -> None:
    """The attitude, velocity and position blocks of ``P`` (and their cross terms) set to
    the configured initial sigmas in the frame in use; the bias block kept."""
    for i in range(9):
        for j in range(N_STATES):
            P[i, j] = 0.0
            P[j, i] = 0.0
    for i in range(6):
        P[i, i] = prm[P_S0 + i] ** 2
    if st[S_FRAME] == FRAME_GEOGRAPHIC:
        for i in range(3):
            P[DR + i, DR + i] = prm[P_S0 + 6 + i] ** 2
        return
    CeG = np.empty((3, 3))
    Cen = np.empty((3, 3))
    grid_dcms(st, CeG, Cen)
    D = np.zeros((3, 3))
    for i in range(3):
        D[i, i] = prm[P_S0 + 6 + i] ** 2
    Pe = Cen.T @ D @ Cen
    P[DR : DR + 3, DR : DR + 3] = Pe


@njit(cache=True)
def switch_frame(st: np.ndarray, P: np.ndarray, prm: np.ndarray, to_grid: bool, t: float) -> bool:
    """Switch the navigation frame: the navigation parameters converted (eq. 23, 26-27),
    the covariance converted (eq. 36-38), restarted or kept as ``P_CONV`` says. Returns
    False (and counts a refusal) where the target frame is singular: the grid frame where
    ``cos^2 L sin^2 lon`` > 0.99, the geographic one beyond ``P_GLIM``."""
    _catch_up(st, P, prm)
    sins = st[S_SINS : S_SINS + 20]
    tmp = sins.copy()
    Cx = np.empty((3, 3))
    if to_grid:
        lat, lon, h = sins[0], sins[1], sins[2]
        if (math.cos(lat) * math.sin(lon)) ** 2 > _GRID_SINGULAR:
            st[S_NREFUSED] += 1.0
            return False
        Cen = np.empty((3, 3))
        enu_frame(lat, lon, Cen)
        grid_frame(lat, lon, Cx)
        vG = Cx @ (Cen.T @ np.ascontiguousarray(sins[3:6]))  # C_gG v_g = C_eG C_ne v_n
        if prm[P_CONV] == 1.0 and not covariance_to_grid(P, lat, lon, h, vG):
            st[S_NREFUSED] += 1.0
            return False
        from_geographic(tmp, sins)
        st[S_FRAME] = FRAME_GRID
    else:
        lat, lon, h = geodetic(sins[0], sins[1], sins[2])
        if abs(lat) > prm[P_GLIM]:
            st[S_NREFUSED] += 1.0
            return False
        grid_frame(lat, lon, Cx)
        vG = Cx @ np.ascontiguousarray(sins[3:6])
        if prm[P_CONV] == 1.0 and not covariance_to_geographic(P, lat, lon, h, vG):
            st[S_NREFUSED] += 1.0
            return False
        to_geographic(tmp, sins)
        st[S_FRAME] = FRAME_GEOGRAPHIC
    if prm[P_CONV] == 0.0:
        restart_covariance(st, P, prm)
    st[S_NSWITCH] += 1.0
    st[S_TSWITCH] = t
    return True


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
    c_t: np.ndarray,
    c_code: np.ndarray,
    fixes: np.ndarray,
    sol: np.ndarray,
    qual: np.ndarray,
) -> int:
    """Process one step's IMU frames (``dth``, ``dvel`` (N, 3), ``t_imu`` (N,) ns), Doppler
    samples (arrival ns, speed m/s, valid; (M,)), commands (arrival ns, BENCH_CMD code;
    (K,)) and pending fixes (``fixes`` (F, FIX_COLS), by measurement time), writing the
    output epochs into ``sol``/``qual`` (length >= N). Returns the number of epochs;
    ``st[S_CONSUMED]``, ``st[S_CCONSUMED]``: the fixes and commands used up."""
    n_out = 0
    j = 0
    jc = 0
    jf = 0
    th = np.zeros(3)
    dv = np.zeros(3)
    C = np.zeros((3, 3))
    sins = st[S_SINS : S_SINS + 20]
    for k in range(t_imu.shape[0]):
        t = float(t_imu[k])
        while j < d_t.shape[0] and d_t[j] <= t:
            st[S_DV] = d_v[j]
            st[S_DOK] = 1.0 if d_ok[j] else 0.0
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
            st[S_W + i] = th[i] / T
        if st[S_FRAME] == FRAME_GEOGRAPHIC:
            _step(sins, th, dv, T)
        else:
            step_e(sins, th, dv, T)
        quat_dcm(st, S_SINS + 6, C)
        if st[S_FRAME] == FRAME_GEOGRAPHIC:
            standstill_feed(st[S_STILL : S_STILL + STILL_SIZE], C, th, dv, T, t, prm[P_STILL : P_STILL + STILL_PRM])
        else:  # the detector's horizontal is ENU's: no standstill in the grid frame
            st[S_STILL + 6] = -1.0
        for i in range(3):
            st[S_FN + i] += C[i, 0] * dv[0] + C[i, 1] * dv[1] + C[i, 2] * dv[2]
        st[S_TSINCE] += T
        nav = st[S_PHASE] == 2.0
        # commands: at the first IMU frame at or after their arrival
        while jc < c_t.shape[0] and c_t[jc] <= t:
            code = c_code[jc]
            jc += 1
            if not nav:
                continue
            if code == 1 or code == 2:
                st[S_MANUAL] = 1.0
                want = FRAME_GRID if code == 1 else FRAME_GEOGRAPHIC
                if st[S_FRAME] != want:
                    switch_frame(st, P, prm, want == FRAME_GRID, t)
            elif code == 3:
                _catch_up(st, P, prm)
                restart_covariance(st, P, prm)
        if nav and st[S_MANUAL] == 0.0 and prm[P_AUTO] > 0.0:
            lat = abs(latitude(st))
            if st[S_FRAME] == FRAME_GEOGRAPHIC and lat >= prm[P_SWLAT]:
                switch_frame(st, P, prm, True, t)
            elif st[S_FRAME] == FRAME_GRID and lat < prm[P_SWLAT] - prm[P_HYST]:
                switch_frame(st, P, prm, False, t)
        if st[S_TSINCE] >= prm[P_TU] - 1e-6:
            _time_update(st, P, prm, st[S_TSINCE])
            if not nav:
                x = zupt_update(sins, P, st[S_P0 : S_P0 + 3], prm[P_ZUPT], prm[P_RP0])
                feedback(st, x)
            elif standstill(st[S_STILL : S_STILL + STILL_SIZE], sins, t, prm[P_STILL : P_STILL + STILL_PRM]) \
                    and not (st[S_DOK] > 0.0 and t - st[S_DT] <= prm[P_DOPTO] and abs(st[S_DV]) > prm[P_STILL + 4]):
                x = zero_velocity_update(sins, P, prm[P_STILL + 5])  # standing (the Doppler, if any, reads ~0)
                feedback(st, x)
        if not nav and t >= st[S_ALIGN_END]:
            _catch_up(st, P, prm)
            x = zupt_update(sins, P, st[S_P0 : S_P0 + 3], prm[P_ZUPT], prm[P_RP0])
            feedback(st, x)
            st[S_PHASE] = 2.0
            st[S_NEXT_VEL] = t + prm[P_VELPER]
            nav = True
        while jf < fixes.shape[0] and fixes[jf, 0] <= t:  # (at rest the alignment has its own)
            if nav:
                _catch_up(st, P, prm)
                position_update(st, P, prm, fixes[jf], t)
            jf += 1
        if nav and t >= st[S_NEXT_VEL]:
            st[S_NEXT_VEL] += prm[P_VELPER]
            if prm[P_VEL] > 0.0 and st[S_DOK] > 0.0 and t - st[S_DT] <= prm[P_DOPTO]:
                _catch_up(st, P, prm)
                velocity_update(st, P, prm, t)
        st[S_MODE] = output_mode(st, prm, t)
        if t >= st[S_NEXT_OUT] and t % prm[P_OUT] == 0.0:
            output(st, P, t, sol[n_out], qual[n_out])
            n_out += 1
            st[S_NEXT_OUT] = t + prm[P_OUT]
    while j < d_t.shape[0]:  # samples after the step's last IMU frame (or a step without one)
        st[S_DV] = d_v[j]
        st[S_DOK] = 1.0 if d_ok[j] else 0.0
        st[S_DT] = float(d_t[j])
        j += 1
    st[S_CONSUMED] = jf
    st[S_CCONSUMED] = jc
    return n_out
