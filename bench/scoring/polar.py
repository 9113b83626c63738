"""Truth interpolation and navigation errors near a pole, where latitude, longitude and ENU
heading are singular.

A recorded truth whose latitude passes :data:`bench.nav.earth.POLAR_LATITUDE` is "polar"
(:func:`is_polar`). :mod:`bench.scoring.align` then interpolates it and measures the
DUT's errors here, through the Earth-fixed frame only:

* position: cubic Hermite on the ECEF position with the ECEF velocity as derivative;
* velocity: cubic Hermite on the ECEF velocity, whose derivative comes from the recorded
  specific force: ``dv_e/dt = C_ne (C_bn f_b - 2 omega_ie_n x vel_n + g_n)``;
* attitude: ``C_be = C_ne C_bn`` on SO(3) (as :func:`bench.scoring.align._so3_hermite`)
  with the body rate relative to the Earth ``omega_eb_b = omega_ib_b - C_bn^T omega_ie_n``;
  the interpolated position's ENU frame gives back ``vel_n``, ``q_bn`` and the Euler angles.

Errors compare like with like: the DUT reports velocity and attitude in the ENU frame at
its own position, which near the pole may turn by a large angle about the vertical
within metres. Its velocity and attitude are taken into the truth's ENU frame through
ECEF (``C_en(truth) C_ne(DUT)``) before the differences are formed, so a DUT whose output
is right scores zero at and around the pole, whatever its position error. Away from the
poles that transport is the identity up to the position error's angle (micro-radians),
which the ordinary scoring leaves out; polar truths are the only ones scored this way,
so every other verdict is bit for bit as before.
"""

from __future__ import annotations

import numpy as np

from bench.nav import earth
from bench.nav.rotation import dcm_to_quat, quat_to_dcm

__all__ = ["is_polar", "polar_truth", "between_frames"]


def is_polar(lat: np.ndarray) -> bool:
    """True when latitudes (rad) pass the polar limit."""
    return bool(len(lat) and np.max(np.abs(lat)) > earth.POLAR_LATITUDE)


def _C_ne(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    return np.swapaxes(earth.C_en(lat, lon), -1, -2)


def _mv(C: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("nij,nj->ni", C, v)


def polar_truth(truth: np.ndarray) -> dict[str, np.ndarray]:
    """ECEF samples of a truth record array: position ``x`` (N, 3), velocity ``v`` and its
    rate ``a`` (N, 3), attitude ``q_be`` (N, 4) and the body rate ``w_eb_b`` (N, 3)."""
    lat, lon, h = truth["lat"], truth["lon"], truth["h"]
    C_ne = _C_ne(lat, lon)
    C_bn = quat_to_dcm(truth["q_bn"])
    vel = truth["vel_n"]
    w_ie = earth.earth_rate_n(lat)
    a_n = _mv(C_bn, truth["f_b"]) - 2.0 * np.cross(w_ie, vel)
    a_n[:, 2] -= earth.gravity(lat, h)
    return {
        "x": earth.geodetic_to_ecef(lat, lon, h),
        "v": _mv(C_ne, vel),
        "a": _mv(C_ne, a_n),
        "q_be": dcm_to_quat(C_ne @ C_bn),
        "w_eb_b": truth["omega_ib_b"] - np.einsum("nji,nj->ni", C_bn, w_ie),
    }


def between_frames(
    to_lat: np.ndarray,
    to_lon: np.ndarray,
    from_lat: np.ndarray,
    from_lon: np.ndarray,
    vel_n: np.ndarray,
    C_bn: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """ENU velocities (M, 3) and attitudes C_bn (M, 3, 3) given in the ENU frame at
    ``(from_lat, from_lon)`` taken into the ENU frame at ``(to_lat, to_lon)`` through ECEF
    (the same Earth-fixed vector and body attitude, other components)."""
    R = earth.C_en(to_lat, to_lon) @ _C_ne(from_lat, from_lon)
    return _mv(R, vel_n), R @ C_bn

