"""The seed-003 estimator's aiding updates, compiled: the position fix (g: ENU metres; G:
the ECEF difference of seed eq. 24 with R rotated from ENU) and the body-frame velocity aid
(the Doppler forward speed with the non-holonomic constraint), either frame, closed-loop
feedback into the state (:mod:`bench.estimators.seed003_state`). Joseph-form updates with
solves (:func:`bench.estimators.kf.joseph_update`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from bench.estimators.ins_model import DR, DV, PHI, position_difference
from bench.estimators.kf import innovation_covariance, joseph_update, nis
from bench.estimators.seed003_state import (
    FRAME_GEOGRAPHIC,
    N_STATES,
    P_GATE,
    P_RDOP,
    P_RNHC,
    P_RPOS,
    S_DV,
    S_FRAME,
    S_LAST_BDS,
    S_LAST_VEL,
    S_NBDS,
    S_NIS,
    S_NREJ,
    S_NVEL,
    S_SINS,
    feedback,
    nav_dcm_velocity,
)
from bench.nav.ecef import ecef_position, enu_frame

__all__ = ["position_update", "velocity_update"]


@njit(cache=True)
def position_update(st: np.ndarray, P: np.ndarray, prm: np.ndarray, fix: np.ndarray, t: float) -> None:
    """A position fix (measured at ``fix[0]`` ns) against the INS carried back to that
    time along its velocity; sigmas from the fix (GST) with a floor, chi-square gated."""
    if fix[9] <= 0.0:
        return
    back = (t - fix[0]) * 1e-9
    n = N_STATES
    z = np.zeros(3)
    H = np.zeros((3, n))
    R = np.zeros((3, 3))
    sig = np.array([max(fix[7], prm[P_RPOS]), max(fix[6], prm[P_RPOS]), max(fix[8], prm[P_RPOS])])
    sins = st[S_SINS : S_SINS + 20]
    if st[S_FRAME] == FRAME_GEOGRAPHIC:
        position_difference(sins[0], sins[1], sins[2], fix[1], fix[2], fix[3], z)
        for i in range(3):
            z[i] -= sins[3 + i] * back
            R[i, i] = sig[i] ** 2
    else:
        rf = np.zeros(3)
        ecef_position(fix[1], fix[2], fix[3], rf)
        for i in range(3):
            z[i] = sins[i] - sins[3 + i] * back - rf[i]
        Cen = np.empty((3, 3))
        enu_frame(fix[1], fix[2], Cen)
        D = np.zeros((3, 3))
        for i in range(3):
            D[i, i] = sig[i] ** 2
        R[:, :] = Cen.T @ D @ Cen  # seed eq. 24: the ECEF difference, its noise rotated from ENU
    for i in range(3):
        H[i, DR + i] = 1.0
    S = innovation_covariance(P, H, R)
    d2 = nis(z, S)
    st[S_NIS] = d2
    if prm[P_GATE] > 0.0 and d2 > prm[P_GATE]:
        st[S_NREJ] += 1.0
        return
    x = np.zeros(n)
    joseph_update(x, P, z, H, R)
    feedback(st, x)
    st[S_NBDS] += 1.0
    st[S_LAST_BDS] = t


@njit(cache=True)
def velocity_update(st: np.ndarray, P: np.ndarray, prm: np.ndarray, t: float) -> None:
    """The velocity aid in the body frame: (right, forward, up) = (0, Doppler speed, 0),
    the same in either frame (``v_b = C_b^nav' v_nav``)."""
    n = N_STATES
    C = np.zeros((3, 3))
    v = np.zeros(3)
    nav_dcm_velocity(st, C, v)
    vb = C.T @ v
    # v_b computed = C'(I + [phi x])(v + dv): H_phi = -C' [v x], H_dv = C'
    sk = np.zeros((3, 3))
    sk[0, 1], sk[0, 2], sk[1, 0], sk[1, 2], sk[2, 0], sk[2, 1] = -v[2], v[1], v[2], -v[0], -v[1], v[0]
    Mphi = -(C.T @ sk)
    z = np.zeros(3)
    H = np.zeros((3, n))
    R = np.zeros((3, 3))
    for i in range(3):
        z[i] = vb[i] - (st[S_DV] if i == 1 else 0.0)
        for j in range(3):
            H[i, DV + j] = C[j, i]
            H[i, PHI + j] = Mphi[i, j]
        R[i, i] = (prm[P_RDOP] if i == 1 else prm[P_RNHC]) ** 2
    x = np.zeros(n)
    joseph_update(x, P, z, H, R)
    feedback(st, x)
    st[S_NVEL] += 1.0
    st[S_LAST_VEL] = t
