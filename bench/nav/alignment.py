"""Analytic coarse alignment of a stationary strapdown IMU.

At rest the accelerometers see the reaction to gravity, ``f_n = [0, 0, g]``, and the
gyros the Earth's rotation, ``omega_ie_n = [0, Omega cos(lat), Omega sin(lat)]``. Two
non-parallel vectors known in both frames fix the attitude (TRIAD); the angle between
them gives the latitude. Good to a fraction of a degree in heading with a navigation-
grade unit and a few minutes of data; the fine alignment is the estimator's job.
"""

from __future__ import annotations

import numpy as np

from bench.nav.earth import OMEGA_IE

__all__ = ["coarse_align", "latitude_from_static"]


def _triad(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    t1 = a / np.linalg.norm(a)
    t2 = np.cross(a, b)
    t2 /= np.linalg.norm(t2)
    return np.column_stack([t1, t2, np.cross(t1, t2)])


def coarse_align(f_b: np.ndarray, omega_ib_b: np.ndarray, lat: float) -> np.ndarray:
    """C_bn (3, 3) from mean specific force (m/s^2) and mean angular rate (rad/s) at rest.

    Parameters
    ----------
    f_b, omega_ib_b:
        (3,) averages over the static period, body frame RFU.
    lat:
        Latitude, rad.
    """
    f_b = np.asarray(f_b, dtype=float)
    w_b = np.asarray(omega_ib_b, dtype=float)
    f_n = np.array([0.0, 0.0, np.linalg.norm(f_b)])
    w_n = np.array([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    C = _triad(f_n, w_n) @ _triad(f_b, w_b).T
    u, _, vt = np.linalg.svd(C)  # nearest rotation
    return u @ vt


def latitude_from_static(f_b: np.ndarray, omega_ib_b: np.ndarray) -> float:
    """Latitude (rad) from the angle between gravity and the Earth rate sensed at rest."""
    f_b = np.asarray(f_b, dtype=float)
    w_b = np.asarray(omega_ib_b, dtype=float)
    s = float(np.dot(f_b, w_b) / (np.linalg.norm(f_b) * np.linalg.norm(w_b)))
    return float(np.arcsin(np.clip(s, -1.0, 1.0)))
