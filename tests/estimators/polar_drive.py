"""A drive over the North Pole for the seed-003 estimator tests: a level vehicle on a great
circle through the pole at constant speed. The IMU's increments are the great circle's
(Earth rate, the circle's rate, gravity, Coriolis); the truth is the bench's ECEF
mechanization run on exactly those increments (so an error-free estimator reproduces it);
1 Hz position fixes and 50 Hz Doppler speeds from the truth, without errors unless the
test adds them."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.dut.estimator import DutInputs
from bench.nav import earth
from bench.nav.ecef import dcm_quat, ecef_position, enu_frame, geodetic, step_e
from bench.nav.rotation import quat_to_dcm
from bench.wire.imu import IMU_SAMPLE_DTYPE
from bench.wire.nmea import GNSS_FIX_DTYPE

RATE = 200
T = 1.0 / RATE
EPOCH_UTC = 1_700_000_000_000_000_000


@dataclass
class PolarDrive:
    t: np.ndarray  # (N,) ns, end of each IMU interval
    imu: np.ndarray  # IMU_SAMPLE_DTYPE
    lat: np.ndarray  # (N,) truth after each interval, rad
    lon: np.ndarray
    h: np.ndarray
    v_e: np.ndarray  # (N, 3) ECEF velocity
    C_be: np.ndarray  # (N, 3, 3)

    def inputs(self, t0_ns: int, t1_ns: int, speed: float) -> DutInputs:
        """The step (t0, t1]: its IMU frames, a fix on each whole second, Doppler at 50 Hz."""
        sel = (self.t > t0_ns) & (self.t <= t1_ns)
        imu = self.imu[sel]
        fixes = np.zeros(0, GNSS_FIX_DTYPE)
        d_t = np.arange((t0_ns // 20_000_000 + 1) * 20_000_000, t1_ns + 1, 20_000_000, dtype=np.int64)
        sec = [t for t in self.t[sel] if t % 1_000_000_000 == 0]
        if sec:
            k = np.searchsorted(self.t, sec)
            fixes = np.zeros(len(k), GNSS_FIX_DTYPE)
            fixes["t_ns"] = sec
            fixes["lat"], fixes["lon"], fixes["h"] = self.lat[k], self.lon[k], self.h[k]
            fixes["sigma_lat"] = fixes["sigma_lon"] = fixes["sigma_alt"] = 1.0
            fixes["quality"] = 1
        can = {"DOPPLER": {"rx_ns": d_t, "speed": np.full(len(d_t), speed), "valid": np.ones(len(d_t), np.uint8),
                           "quality": np.full(len(d_t), 200, np.uint8), "low_signal": np.zeros(len(d_t), np.uint8)}}
        return DutInputs(t_ns=t1_ns, imu=imu, gnss=fixes, can=can, epoch_utc_ns=EPOCH_UTC)


def over_the_pole(lat0_deg: float, lon0_deg: float, h: float, speed: float, seconds: float) -> PolarDrive:
    """Drive north from (lat0, lon0) at ``speed`` over the pole for ``seconds``."""
    n = round(seconds * RATE)
    lat0, lon0 = math.radians(lat0_deg), math.radians(lon0_deg)
    se = np.zeros(20)
    ecef_position(lat0, lon0, h, se[0:3])
    Cen = np.zeros((3, 3))
    enu_frame(lat0, lon0, Cen)
    se[3:6] = Cen.T @ np.array([0.0, speed, 0.0])
    dcm_quat(Cen.T, se, 6)  # body RFU = ENU at heading 0, level
    plane = np.cross(se[0:3], se[3:6])
    plane /= np.linalg.norm(plane)
    wie = np.array([0.0, 0.0, earth.OMEGA_IE])
    imu = np.zeros(n, IMU_SAMPLE_DTYPE)
    out = PolarDrive(t=np.arange(1, n + 1, dtype=np.int64) * 5_000_000, imu=imu, lat=np.zeros(n), lon=np.zeros(n),
                     h=np.zeros(n), v_e=np.zeros((n, 3)), C_be=np.zeros((n, 3, 3)))
    imu["t_ns"] = out.t
    imu["rx_ns"] = out.t
    for k in range(n):
        lat, lon, hh = geodetic(se[0], se[1], se[2])
        Cbe = quat_to_dcm(se[6:10])
        w_eb = plane * speed / np.linalg.norm(se[0:3])
        u = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
        a_e = np.cross(w_eb, se[3:6]) + 2.0 * np.cross(wie, se[3:6])
        imu["dtheta"][k] = Cbe.T @ (wie + w_eb) * T
        imu["dvel"][k] = Cbe.T @ (a_e + float(earth.gravity(lat, hh)) * u) * T
        step_e(se, imu["dtheta"][k], imu["dvel"][k], T)
        out.lat[k], out.lon[k], out.h[k] = geodetic(se[0], se[1], se[2])
        out.v_e[k] = se[3:6]
        out.C_be[k] = quat_to_dcm(se[6:10])
    return out
