"""WGS-84 Earth model: radii of curvature, normal gravity, Earth and transport rates,
and conversions between geodetic, ECEF and local ENU coordinates.

All functions are vectorised: scalars or arrays of shape (N,) in, arrays out. Latitude and
longitude in radians, heights in metres above the ellipsoid, vectors in the ENU frame.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "A",
    "F",
    "E2",
    "B",
    "OMEGA_IE",
    "GM",
    "radii",
    "gravity",
    "gravity_n",
    "earth_rate_n",
    "transport_rate_n",
    "geodetic_to_ecef",
    "ecef_to_geodetic",
    "C_en",
    "ecef_to_enu",
    "enu_to_ecef",
    "position_rates",
    "POLAR_LATITUDE",
]

#: Semi-major axis, m.
A = 6378137.0
#: Flattening.
F = 1.0 / 298.257223563
#: First eccentricity squared.
E2 = F * (2.0 - F)
#: Semi-minor axis, m.
B = A * (1.0 - F)
#: Earth rotation rate, rad/s.
OMEGA_IE = 7.292115e-5
#: Latitude (rad) beyond which the bench's truth and scoring work in ECEF and a
#: wander-azimuth frame rather than in latitude, longitude and ENU heading (singular at
#: the poles): a drive, or a recorded truth, that passes it is "polar".
POLAR_LATITUDE = float(np.radians(89.0))
#: Earth's gravitational constant including the atmosphere, m^3/s^2.
GM = 3.986004418e14

# Somigliana normal gravity on the ellipsoid.
_GAMMA_E = 9.7803253359
_K_SOMIGLIANA = 0.00193185265241
_M = OMEGA_IE**2 * A**2 * B / GM


def radii(lat: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Meridian and prime-vertical radii of curvature.

    Returns
    -------
    (R_M, R_N):
        Radii in metres, shaped like ``lat``.
    """
    s2 = np.sin(lat) ** 2
    w2 = 1.0 - E2 * s2
    w = np.sqrt(w2)
    R_N = A / w
    R_M = R_N * (1.0 - E2) / w2
    return R_M, R_N


def gravity(lat: np.ndarray | float, h: np.ndarray | float) -> np.ndarray:
    """Magnitude of normal gravity (gravitation plus centrifugal), m/s^2.

    Somigliana's formula on the ellipsoid with the second-order free-air reduction in
    height (NIMA TR8350.2, eq. 4-1 and 4-3).
    """
    s2 = np.sin(lat) ** 2
    g0 = _GAMMA_E * (1.0 + _K_SOMIGLIANA * s2) / np.sqrt(1.0 - E2 * s2)
    return g0 * (1.0 - 2.0 / A * (1.0 + F + _M - 2.0 * F * s2) * h + 3.0 * np.asarray(h) ** 2 / A**2)


def gravity_n(lat: np.ndarray | float, h: np.ndarray | float) -> np.ndarray:
    """Normal gravity vector in ENU, shape (..., 3): ``[0, 0, -gravity]``."""
    g = np.asarray(gravity(lat, h), dtype=float)
    out = np.zeros((*g.shape, 3))
    out[..., 2] = -g
    return out


def earth_rate_n(lat: np.ndarray | float) -> np.ndarray:
    """Earth rate omega_ie_n in ENU, shape (..., 3)."""
    lat = np.asarray(lat, dtype=float)
    out = np.zeros((*lat.shape, 3))
    out[..., 1] = OMEGA_IE * np.cos(lat)
    out[..., 2] = OMEGA_IE * np.sin(lat)
    return out


def transport_rate_n(lat: np.ndarray | float, h: np.ndarray | float, vel_n: np.ndarray) -> np.ndarray:
    """Transport rate omega_en_n in ENU, shape (..., 3), from velocity ``vel_n`` (..., 3)."""
    R_M, R_N = radii(lat)
    ve = vel_n[..., 0]
    vn = vel_n[..., 1]
    out = np.empty(np.shape(vel_n))
    out[..., 0] = -vn / (R_M + h)
    out[..., 1] = ve / (R_N + h)
    out[..., 2] = ve * np.tan(lat) / (R_N + h)
    return out


def position_rates(lat: np.ndarray, h: np.ndarray, vel_n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time derivatives of latitude, longitude (rad/s) and height (m/s) from ``vel_n``."""
    R_M, R_N = radii(lat)
    return (
        vel_n[..., 1] / (R_M + h),
        vel_n[..., 0] / ((R_N + h) * np.cos(lat)),
        vel_n[..., 2],
    )


def geodetic_to_ecef(lat: np.ndarray | float, lon: np.ndarray | float, h: np.ndarray | float) -> np.ndarray:
    """ECEF position, shape (..., 3), m."""
    _, R_N = radii(lat)
    clat = np.cos(lat)
    out = np.empty((*np.shape(lat), 3))
    out[..., 0] = (R_N + h) * clat * np.cos(lon)
    out[..., 1] = (R_N + h) * clat * np.sin(lon)
    out[..., 2] = (R_N * (1.0 - E2) + h) * np.sin(lat)
    return out


def ecef_to_geodetic(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geodetic latitude, longitude (rad) and height (m) of ECEF positions (..., 3).

    Bowring's start and Newton refinement; sub-micrometre on and near the Earth.
    """
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    # Bowring's initial estimate through the parametric latitude.
    beta = np.arctan2(z * A, p * B)
    ep2 = E2 / (1.0 - E2)
    lat = np.arctan2(z + ep2 * B * np.sin(beta) ** 3, p - E2 * A * np.cos(beta) ** 3)
    for _ in range(2):
        _, R_N = radii(lat)
        s, c = np.sin(lat), np.cos(lat)
        h = p * c + z * s - A * np.sqrt(1.0 - E2 * s * s)
        lat = np.arctan2(z, p * (1.0 - E2 * R_N / (R_N + h)))
    _, R_N = radii(lat)
    s, c = np.sin(lat), np.cos(lat)
    h = p * c + z * s - A * np.sqrt(1.0 - E2 * s * s)
    return lat, lon, h


def C_en(lat: np.ndarray | float, lon: np.ndarray | float) -> np.ndarray:
    """Rotation from ECEF to ENU at (lat, lon), shape (..., 3, 3): ``v_n = C_en @ v_e``."""
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    out = np.empty((*np.shape(lat), 3, 3))
    out[..., 0, 0] = -so
    out[..., 0, 1] = co
    out[..., 0, 2] = 0.0
    out[..., 1, 0] = -sl * co
    out[..., 1, 1] = -sl * so
    out[..., 1, 2] = cl
    out[..., 2, 0] = cl * co
    out[..., 2, 1] = cl * so
    out[..., 2, 2] = sl
    return out


def ecef_to_enu(xyz: np.ndarray, lat0: float, lon0: float, h0: float) -> np.ndarray:
    """Local ENU coordinates (..., 3) of ECEF points relative to the origin (lat0, lon0, h0)."""
    origin = geodetic_to_ecef(lat0, lon0, h0)
    return (np.asarray(xyz) - origin) @ C_en(lat0, lon0).T


def enu_to_ecef(enu: np.ndarray, lat0: float, lon0: float, h0: float) -> np.ndarray:
    """ECEF points (..., 3) of local ENU coordinates relative to the origin (lat0, lon0, h0)."""
    origin = geodetic_to_ecef(lat0, lon0, h0)
    return np.asarray(enu) @ C_en(lat0, lon0) + origin
