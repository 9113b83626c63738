"""An independent strapdown integrator for the exported i2Nav files (tests only).

Written from first principles in the conventions of the exported files -- body
forward-right-down, navigation north-east-down, WGS-84 geodetic position, ZYX Euler angles
(roll, pitch, yaw) -- and using nothing of the bench's navigation code: it checks the
file format and the frame conversions, not the bench against itself.

Per IMU interval (increments dtheta, dv over dt): the attitude is advanced by the rotation
vector with the two-sample coning correction, the navigation frame by the Earth and
transport rates at the interval's middle; the specific-force velocity increment gets the
rotation and two-sample sculling corrections; gravity is the normal gravity of the
WGS-84 ellipsoid (Somigliana) reduced to height with the second-order free-air formula;
position is integrated with the mean velocity of the interval.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

A = 6378137.0
F = 1.0 / 298.257223563
E2 = F * (2.0 - F)
OMEGA = 7.292115e-5
GM = 3.986004418e14
GAMMA_E = 9.7803253359
GAMMA_P = 9.8321849378


@njit(cache=True)
def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


@njit(cache=True)
def _rot(phi):
    """Rotation matrix of the rotation vector phi (Rodrigues)."""
    a = math.sqrt(phi[0] ** 2 + phi[1] ** 2 + phi[2] ** 2)
    K = _skew(phi)
    if a < 1e-12:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + math.sin(a) / a * K + (1.0 - math.cos(a)) / (a * a) * K @ K


@njit(cache=True)
def _gravity(lat, h):
    b = A * (1.0 - F)
    k = (b * GAMMA_P) / (A * GAMMA_E) - 1.0
    m = OMEGA**2 * A * A * b / GM
    s2 = math.sin(lat) ** 2
    g0 = GAMMA_E * (1.0 + k * s2) / math.sqrt(1.0 - E2 * s2)
    return g0 * (1.0 - 2.0 / A * (1.0 + F + m - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))


@njit(cache=True)
def _radii(lat):
    s2 = math.sin(lat) ** 2
    rn = A / math.sqrt(1.0 - E2 * s2)
    rm = A * (1.0 - E2) / (1.0 - E2 * s2) ** 1.5
    return rm, rn


@njit(cache=True)
def _rates(lat, h, v):
    rm, rn = _radii(lat)
    wie = np.array([OMEGA * math.cos(lat), 0.0, -OMEGA * math.sin(lat)])
    wen = np.array([v[1] / (rn + h), -v[0] / (rm + h), -v[1] * math.tan(lat) / (rn + h)])
    return wie, wen


@njit(cache=True)
def integrate(t, dth, dvl, lat0, lon0, h0, v0, C0):
    """Positions (N, 3: lat, lon rad, h m) after each IMU line, from the state at the
    start of the first interval (``t`` the line times, s)."""
    n = len(t)
    out = np.empty((n, 3))
    lat, lon, h = lat0, lon0, h0
    v = v0.copy()
    C = C0.copy()
    pth = np.zeros(3)
    pdv = np.zeros(3)
    t_prev = t[0] - (t[1] - t[0])
    lat_p, h_p, v_p = lat, h, v.copy()
    for k in range(n):
        dt = t[k] - t_prev
        t_prev = t[k]
        th = dth[k]
        dv = dvl[k]
        # middle of the interval, extrapolated from the last one
        lat_m = 1.5 * lat - 0.5 * lat_p
        h_m = 1.5 * h - 0.5 * h_p
        v_m = 1.5 * v - 0.5 * v_p
        wie, wen = _rates(lat_m, h_m, v_m)
        zeta = (wie + wen) * dt
        # velocity
        scul = 0.5 * np.cross(th, dv) + (np.cross(pth, dv) + np.cross(pdv, th)) / 12.0
        dvf = (np.eye(3) - 0.5 * _skew(zeta)) @ C @ (dv + scul)
        g = np.array([0.0, 0.0, _gravity(lat_m, h_m)])
        dvg = (g - np.cross(2.0 * wie + wen, v_m)) * dt
        lat_p, h_p, v_p = lat, h, v.copy()
        v_new = v + dvf + dvg
        # attitude
        phi = th + np.cross(pth, th) / 12.0
        C = _rot(-zeta) @ C @ _rot(phi)
        # position
        vm = 0.5 * (v + v_new)
        h_new = h - vm[2] * dt
        hm = 0.5 * (h + h_new)
        rm, _ = _radii(lat)
        lat_new = lat + vm[0] / (rm + hm) * dt
        _, rn2 = _radii(0.5 * (lat + lat_new))
        lon = lon + vm[1] / ((rn2 + hm) * math.cos(0.5 * (lat + lat_new))) * dt
        lat, h, v = lat_new, h_new, v_new
        pth, pdv = th, dv
        out[k, 0], out[k, 1], out[k, 2] = lat, lon, h
    return out


def euler_to_dcm(roll, pitch, yaw):
    """C_b^n (FRD body to NED) of ZYX Euler angles (rad)."""
    cr, sr, cp, sp, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), \
        math.sin(yaw)
    return np.array([
        [cp * cy, -cr * sy + sr * sp * cy, sr * sy + cr * sp * cy],
        [cp * sy, cr * cy + sr * sp * sy, -sr * cy + cr * sp * sy],
        [-sp, sr * cp, cr * cp],
    ])


def north_east_down_error(lat, lon, h, lat_t, lon_t, h_t):
    """Position error (..., 3) in metres, north, east, down, of (lat, lon, h) against truth."""
    rm, rn = (np.vectorize(lambda x: _radii(x)[0])(lat_t), np.vectorize(lambda x: _radii(x)[1])(lat_t))
    return np.stack([(lat - lat_t) * (rm + h_t), (lon - lon_t) * (rn + h_t) * np.cos(lat_t), -(h - h_t)], axis=-1)
