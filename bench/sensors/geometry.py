"""Where a sensor sits on the vehicle: lever arms and mounting angles, applied to truth.

A point fixed to the body at lever arm ``l_b`` (body frame RFU, from the IMU) moves
relative to the Earth with ``v_n = vel_n + C_bn (omega_eb_b x l_b)``, where
``omega_eb_b = omega_ib_b - C_bn^T omega_ie_n`` is the body rate relative to the Earth.
Its position is the IMU's plus ``C_bn l_b``, added in ECEF so that it is exact.

A sensor axis mounted with yaw ``a_psi`` (clockwise seen from above, towards the right)
and pitch ``a_theta`` (nose up) relative to the body has, in the body frame, the forward
direction ``[sin a_psi cos a_theta, cos a_psi cos a_theta, sin a_theta]`` (seed 002,
eq. 9): the sensor frame is rotated from the body by ``C_sb = Rz(-a_psi) Rx(a_theta)``.
"""

from __future__ import annotations

import numpy as np

from bench.nav import earth
from bench.nav.rotation import euler_rates_to_omega_nb_b, euler_to_dcm
from bench.scenario.trajectory import Trajectory, Truth, level_rates

__all__ = [
    "mounting_dcm",
    "forward_axis",
    "omega_eb_b",
    "velocity_n_at",
    "position_at",
    "body_velocity",
]


def mounting_dcm(yaw: float, pitch: float) -> np.ndarray:
    """``C_sb`` (3, 3): sensor frame to body frame for mounting yaw and pitch (rad)."""
    return euler_to_dcm(yaw, pitch, 0.0)


def forward_axis(yaw: float, pitch: float) -> np.ndarray:
    """The sensor's forward axis in the body frame, (3,)."""
    return mounting_dcm(yaw, pitch)[:, 1]


def _mtv(C: np.ndarray, v: np.ndarray) -> np.ndarray:
    """C^T v for (N, 3, 3) and (N, 3)."""
    return np.einsum("nji,nj->ni", C, v)


def omega_eb_b(truth: Truth) -> np.ndarray:
    """Body rate relative to the Earth, in b, (N, 3) rad/s."""
    return truth.omega_ib_b - _mtv(truth.C_bn, earth.earth_rate_n(truth.lat))


def velocity_n_at(truth: Truth, lever_b: np.ndarray) -> np.ndarray:
    """Earth-relative velocity of the point at ``lever_b`` (3,), in ENU, (N, 3)."""
    if not np.any(lever_b):
        return truth.vel_n.copy()
    return truth.vel_n + np.einsum("nij,nj->ni", truth.C_bn, np.cross(omega_eb_b(truth), lever_b))


def position_at(truth: Truth, lever_b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geodetic latitude, longitude (rad) and height (m) of the point at ``lever_b``, (N,) each."""
    if not np.any(lever_b):
        return truth.lat.copy(), truth.lon.copy(), truth.h.copy()
    l_n = truth.C_bn @ np.asarray(lever_b, dtype=float)
    xyz = earth.geodetic_to_ecef(truth.lat, truth.lon, truth.h)
    l_e = np.einsum("nji,nj->ni", earth.C_en(truth.lat, truth.lon), l_n)  # C_ne = C_en^T
    return earth.ecef_to_geodetic(xyz + l_e)


def body_velocity(traj: Trajectory, t_ns: np.ndarray, lever_b: np.ndarray) -> np.ndarray:
    """Earth-relative velocity of the point at ``lever_b`` in the body frame, (N, 3), straight
    from the kinematics (half the cost of :func:`~bench.scenario.trajectory.truth_at`):
    ``C_bn^T vel_n + (omega_nb_b + C_bn^T omega_en_n) x l_b``."""
    k = traj.kinematics(np.asarray(t_ns) * 1e-9)
    psi, theta, gamma = k.euler[:, 0], k.euler[:, 1], k.euler[:, 2]
    C = euler_to_dcm(psi, theta, gamma)
    v_b = _mtv(C, k.vel_n)
    if np.any(lever_b):
        psi_dot, w_en, _ = level_rates(k)  # the wander-azimuth form near a pole (no tan(lat))
        w_nb = euler_rates_to_omega_nb_b(psi, theta, gamma, psi_dot, k.euler_rate[:, 1], k.euler_rate[:, 2])
        w_eb = w_nb + _mtv(C, w_en)
        v_b = v_b + np.cross(w_eb, lever_b)
    return v_b
