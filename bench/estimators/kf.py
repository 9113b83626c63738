"""The Kalman filter core of the reference estimators (compiled, closed loop).

The filters are error-state filters with closed-loop feedback: after every measurement
update the estimate is fed back into the mechanization and the sensor compensations and
the state reset to zero, so the time update propagates the covariance only. Updates use
the Joseph form and linear solves, never an explicit inverse::

    S = H P H' + R                  innovation covariance (m, m)
    K' = solve(S, H P)              gain, transposed (m, n)
    x = K z
    P = (I - K H) P (I - K H)' + K R K'

The innovation ``z - H x`` (here ``z``, the prior being zero) and ``S`` are returned, so a
caller can test them (normalised innovation squared against a chi-square quantile) before
it accepts the update; :func:`nis` gives that statistic.

Shapes: n states, m measurements; every array float64 and C-contiguous.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["time_update", "joseph_update", "nis", "KalmanFilter"]


@njit(cache=True)
def time_update(P: np.ndarray, Phi: np.ndarray, Qd: np.ndarray) -> None:
    """``P <- Phi P Phi' + Qd``, kept symmetric. ``P``, ``Phi``, ``Qd``: (n, n)."""
    P[:, :] = Phi @ P @ Phi.T + Qd
    n = P.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            s = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = s
            P[j, i] = s


@njit(cache=True)
def innovation_covariance(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``S = H P H' + R`` (m, m)."""
    return H @ P @ H.T + R


@njit(cache=True)
def joseph_update(x: np.ndarray, P: np.ndarray, z: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Measurement update of a zero prior: ``x`` (n,) gets ``K z``, ``P`` (n, n) the
    Joseph-form posterior. ``z`` (m,), ``H`` (m, n), ``R`` (m, m). Returns ``S`` (m, m)."""
    HP = H @ P
    S = HP @ H.T + R
    Kt = np.linalg.solve(S, HP)  # (m, n): K' = S^-1 H P, S symmetric
    K = Kt.T.copy()
    x[:] = K @ z
    n = P.shape[0]
    IKH = -K @ H
    for i in range(n):
        IKH[i, i] += 1.0
    P[:, :] = IKH @ P @ IKH.T + K @ R @ Kt
    for i in range(n):
        for j in range(i + 1, n):
            s = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = s
            P[j, i] = s
    return S


@njit(cache=True)
def nis(z: np.ndarray, S: np.ndarray) -> float:
    """Normalised innovation squared ``z' S^-1 z`` (by a solve)."""
    return float(z @ np.linalg.solve(S, z))


class KalmanFilter:
    """A plain error-state Kalman filter over the compiled core, for tests, tools and
    estimators written in Python.

    Parameters
    ----------
    P0:
        (n, n) initial covariance.
    """

    def __init__(self, P0: np.ndarray):
        self.P = np.array(P0, dtype=float, order="C")
        self.x = np.zeros(len(self.P))
        #: innovation and its covariance of the last update
        self.innovation = np.zeros(0)
        self.S = np.zeros((0, 0))

    def predict(self, Phi: np.ndarray, Qd: np.ndarray) -> None:
        """Time update (the state is zero after feedback, so only P moves)."""
        self.x = np.ascontiguousarray(Phi, dtype=float) @ self.x
        time_update(self.P, np.ascontiguousarray(Phi, dtype=float), np.ascontiguousarray(Qd, dtype=float))

    def update(self, z: np.ndarray, H: np.ndarray, R: np.ndarray) -> float:
        """Batch measurement update; returns the normalised innovation squared."""
        H = np.ascontiguousarray(H, dtype=float)
        innov = np.ascontiguousarray(z, dtype=float) - H @ self.x
        dx = np.zeros_like(self.x)
        self.S = joseph_update(dx, self.P, innov, H, np.ascontiguousarray(R, dtype=float))
        self.x = self.x + dx
        self.innovation = innov
        return nis(innov, self.S)

    def update_sequential(self, z: np.ndarray, H: np.ndarray, r: np.ndarray) -> np.ndarray:
        """One scalar update per row (uncorrelated measurement noise ``r``, (m,) variances);
        returns each row's normalised innovation squared."""
        out = np.zeros(len(z))
        for i in range(len(z)):
            out[i] = self.update(np.asarray(z)[i : i + 1], np.asarray(H)[i : i + 1], np.array([[r[i]]]))
        return out

    def feedback(self) -> np.ndarray:
        """The estimate, handed to the caller for correction, and the state reset to zero."""
        x, self.x = self.x, np.zeros_like(self.x)
        return x
