"""A short synthetic drive for the seed-001 estimator tests: truth from the bench's own
mechanization on designed increments (so an error-free IMU closes exactly), the IMU with
biases and noise, a 100 Hz odometer and 1 Hz BDS fixes at the antenna, each optional
error chosen by the test."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.dut.estimator import DutInputs
from bench.estimators.ins_model import radii, rates
from bench.nav.rotation import quat_to_dcm
from bench.nav.strapdown import NavState, Strapdown, _gravity
from bench.wire.imu import IMU_SAMPLE_DTYPE
from bench.wire.nmea import GNSS_FIX_DTYPE

LAT, LON, H = math.radians(29.72), math.radians(106.63), 320.0
POS = [29.72, 106.63, 320.0]
RATE = 200
T = 1.0 / RATE
EPOCH_UTC = 1_700_000_000_000_000_000


@dataclass
class Drive:
    t: np.ndarray  # (N,) ns, end of each IMU interval
    imu: np.ndarray  # IMU_SAMPLE_DTYPE
    pos: np.ndarray  # (N, 3) lat, lon, h
    vel: np.ndarray  # (N, 3) ENU
    C: np.ndarray  # (N, 3, 3) C_bn


def _profile(t: float, rest: float) -> tuple[float, float]:
    """(forward acceleration m/s^2, yaw rate rad/s, positive = heading clockwise)."""
    s = t - rest
    if s < 0:
        return 0.0, 0.0
    if s < 10:
        return 1.0, 0.0
    k = int(s // 20) % 4  # 20 s blocks: straight, right turn, straight, left turn with speed changes
    u = s % 20
    if k == 1 and 5 <= u < 15:
        return 0.0, math.radians(9.0)
    if k == 3 and 5 <= u < 15:
        return 0.0, -math.radians(9.0)
    if k == 2 and u < 5:
        return 0.6, 0.0
    if k == 0 and 10 <= u < 15 and s > 20:
        return -0.6, 0.0
    return 0.0, 0.0


def make_drive(seconds: float, seed: int, rest: float = 60.0, heading: float = math.radians(60.0),
               gyro_bias: float = 0.01, accel_bias: float = 100.0) -> Drive:
    """``gyro_bias`` deg/h, ``accel_bias`` ug: the constant biases (random signs)."""
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    sd = Strapdown(NavState.from_euler(LAT, LON, H, np.zeros(3), np.array([heading, 0.0, 0.0])))
    out_t = (np.arange(1, n + 1) * round(T * 1e9)).astype(np.int64)
    pos, vel, Cs = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3))
    dth, dvl = np.zeros((n, 3)), np.zeros((n, 3))
    speed, hdg = 0.0, heading
    rt = np.zeros((2, 3))
    for k in range(n):
        s = sd.state
        a, r = _profile(k * T, rest)
        C = quat_to_dcm(s.q_bn)
        hdg += r * T
        speed_new = speed + a * T
        v_new = speed_new * np.array([math.sin(hdg), math.cos(hdg), 0.0])
        rates(s.lat, s.h, s.vel_n[0], s.vel_n[1], rt)
        w_in = rt[0] + rt[1]
        f_n = (v_new - s.vel_n) / T + np.cross(2 * rt[0] + rt[1], s.vel_n) + np.array([0, 0, _gravity(s.lat, s.h)])
        w_b = np.array([0.0, 0.0, -r]) + C.T @ w_in
        dth[k] = w_b * T
        dvl[k] = C.T @ f_n * T
        sd.step(dth[k], dvl[k], T)
        s = sd.state
        pos[k] = s.lat, s.lon, s.h
        vel[k] = s.vel_n
        Cs[k] = quat_to_dcm(s.q_bn)
        speed = speed_new
    bg = np.radians(gyro_bias / 3600.0) * rng.choice([-1.0, 1.0], 3)
    ba = accel_bias * 1e-6 * 9.8 * rng.choice([-1.0, 1.0], 3)
    arw = math.radians(0.001) / 60.0 * math.sqrt(T)  # rad per sample
    vrw = 10e-6 * 9.8 * math.sqrt(T)
    imu = np.zeros(n, IMU_SAMPLE_DTYPE)
    imu["t_ns"] = out_t
    imu["dtheta"] = dth + bg * T + rng.normal(0.0, arw, (n, 3))
    imu["dvel"] = dvl + ba * T + rng.normal(0.0, vrw, (n, 3))
    return Drive(out_t, imu, pos, vel, Cs)


def fixes(drive: Drive, seed: int, *, lever=(0.5, 1.2, 1.8), sigma=(0.5, 0.5, 0.8), tag_ns: int = 0,
          outage: tuple[float, float] | None = None, markov=(0.0, 0.0, 0.0), tau: float = 45.0) -> np.ndarray:
    """1 Hz fixes at the antenna (lever arm, body RFU), white noise ``sigma`` plus a Markov
    part, stamped ``tag_ns`` after the true measurement time; no fix in ``outage`` (s)."""
    rng = np.random.default_rng(seed + 1000)
    idx = np.nonzero(drive.t % 1_000_000_000 == 0)[0]
    out = np.zeros(len(idx), GNSS_FIX_DTYPE)
    m = np.zeros(3)
    sig = np.array(sigma)
    mk = np.array(markov)
    for j, k in enumerate(idx):
        lat, lon, h = drive.pos[k]
        m = m * math.exp(-1.0 / tau) + mk * math.sqrt(1 - math.exp(-2.0 / tau)) * rng.normal(size=3)
        e = drive.C[k] @ np.asarray(lever) + m + sig * rng.normal(size=3)
        rmh, rnh = radii(lat, h)
        w = drive.imu["dtheta"][k] / T
        v = drive.vel[k] + drive.C[k] @ np.cross(w, np.asarray(lever)) + 0.03 * rng.normal(size=3)
        r = out[j]
        r["t_ns"] = drive.t[k] + tag_ns
        r["utc_ns"] = EPOCH_UTC + r["t_ns"]
        r["lat"], r["lon"], r["h"] = lat + e[1] / rmh, lon + e[0] / (rnh * math.cos(lat)), h + e[2]
        r["vel_n"] = v[0], v[1], math.nan
        r["sigma_lat"], r["sigma_lon"], r["sigma_alt"] = math.hypot(sig[1], mk[1]), math.hypot(sig[0], mk[0]), \
            math.hypot(sig[2], mk[2])
        r["quality"] = 1
        if outage and outage[0] <= drive.t[k] * 1e-9 < outage[1]:
            for f in ("lat", "lon", "h", "sigma_lat", "sigma_lon", "sigma_alt"):
                r[f] = math.nan
            r["quality"] = 0
    return out


def run(est, drive: Drive, gnss: np.ndarray, *, odometer: bool = True, latency_ns: int = 80_000_000,
        scale: float = 0.002) -> tuple[np.ndarray, np.ndarray]:
    """Step ``est`` in 10 ms steps; fixes delivered ``latency_ns`` after their true time."""
    sols, quals = [], []
    arrive = gnss["t_ns"] - 0 + latency_ns
    fwd = np.einsum("nij,ni->nj", drive.C, drive.vel)[:, 1]
    g = 0
    for k in range(0, len(drive.t), 2):
        t = int(drive.t[k + 1])
        can = {}
        if odometer:
            sp = np.round(fwd[k + 1] * (1 + scale) / 0.01) * 0.01
            can["ODOMETER"] = {"rx_ns": np.array([t], np.int64), "speed": np.array([sp]),
                               "valid": np.array([1], np.uint8), "reverse": np.array([0], np.uint8),
                               "pulse_count": np.array([0], np.uint16)}
        g1 = int(np.searchsorted(arrive, t, side="right"))
        out = est.step(DutInputs(t, drive.imu[k : k + 2], gnss[g:g1], can, EPOCH_UTC))
        g = g1
        sols.append(out.solutions)
        quals.append(out.qualities)
    return np.concatenate(sols), np.concatenate(quals)


def errors(drive: Drive, sol: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t s, (N, 3) ENU position error m) of the output epochs."""
    idx = np.searchsorted(drive.t, sol["t_ns"])
    lat, lon, h = drive.pos[idx].T
    rmh, rnh = radii(LAT, H)
    e = np.column_stack([(sol["lon"] - lon) * rnh * np.cos(lat), (sol["lat"] - lat) * rmh, sol["h"] - h])
    return sol["t_ns"] * 1e-9, e
