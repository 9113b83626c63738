"""Fine alignment at rest: the heading converges to the limit the gyros allow.

At rest a Kalman fine alignment cannot tell the east gyro bias from a heading error: it
converges to the gyrocompassing limit ``-eps_E / (Omega cos lat)`` (heading clockwise from
north; a positive east bias turns the computed north towards the west). With the seed-000
IMU (0.01 deg/h on every axis, fixed) at the S000 start (34.246 N, heading 30 deg) that is
-3.78 arcmin. The gyro noise (0.001 deg/sqrt(h)) over 300 s scatters each run about it by
about 1 arcmin (ARW / sqrt(T) / (Omega cos lat)), so over 20 seeds: the mean lands within
25 % of the limit, and the scatter is what the filter's own covariance says it is.
"""

from __future__ import annotations

import math

import numpy as np

from bench.dut.estimator import DutInputs
from bench.estimators.seed000 import Seed000
from bench.nav.earth import OMEGA_IE, gravity
from bench.nav.rotation import euler_to_dcm, wrap_pi
from bench.sensors.imu.errors import ImuErrorModel
from bench.sensors.imu.grade import load_grade
from bench.sensors.imu.ideal import ImuBlock
from bench.wire.imu import IMU_SAMPLE_DTYPE

LAT, LON, H = math.radians(34.24605), math.radians(108.90965), 380.0
PSI = math.radians(30.0)
RATE = 200.0
AM = math.degrees(1.0) * 60.0


def _static_imu(seed: int, seconds: float) -> np.ndarray:
    """Wire-quantized increments of the seed-000 IMU at rest at the S000 start."""
    n = int(seconds * RATE)
    T = 1.0 / RATE
    C = euler_to_dcm(PSI, 0.0, 0.0)
    w_b = C.T @ np.array([0.0, OMEGA_IE * math.cos(LAT), OMEGA_IE * math.sin(LAT)])
    f_b = C.T @ np.array([0.0, 0.0, float(gravity(LAT, H))])
    t = (np.arange(1, n + 1) * round(T * 1e9)).astype(np.int64)
    ideal = ImuBlock(t, np.tile(w_b * T, (n, 1)), np.tile(f_b * T, (n, 1)), np.full(n, 0x3F, np.uint8))
    meas = ImuErrorModel(load_grade("seed000"), seed, RATE).apply(ideal)
    rec = np.zeros(n, IMU_SAMPLE_DTYPE)
    rec["t_ns"] = t
    rec["dtheta"] = np.round(meas.dtheta / 1e-9) * 1e-9  # ICD LSBs
    rec["dvel"] = np.round(meas.dvel / 1e-8) * 1e-8
    return rec


def _align(seed: int, seconds: float = 300.0, push: float = 0.0) -> tuple[float, float, float, float]:
    """(heading error, pitch error, roll error, heading sigma) at the end of the alignment;
    ``push`` (rad) is added to the x gyro's angle over the first 10 s (the coarse period)."""
    est = Seed000()
    est.configure({"initial_position": [math.degrees(LAT), math.degrees(LON), H], "alignment": f"{seconds} s"})
    imu = _static_imu(seed, seconds + 1.0)
    first = imu["t_ns"] <= 10_000_000_000
    imu["dtheta"][first, 0] += push / np.count_nonzero(first)
    step = int(RATE)  # 1 s steps
    last = None
    for k in range(0, len(imu), step):
        part = imu[k : k + step]
        out = est.step(DutInputs(int(part["t_ns"][-1]), part, np.zeros(0), {}))
        sol = out.solutions
        at = np.flatnonzero(sol["t_ns"] == round(seconds * 1e9))
        if len(at):
            last = (sol[at[0]], out.qualities[at[0]])
    assert last is not None
    s, q = last
    return (
        float(wrap_pi(s["heading"] - PSI)),
        float(s["pitch"]),
        float(s["roll"]),
        float(q["sigma_att"][0]),
    )


def test_fine_alignment_reaches_the_gyrocompassing_limit_over_20_seeds():
    eps = load_grade("seed000").gyro.bias
    eps_e = (euler_to_dcm(PSI, 0.0, 0.0) @ eps)[0]
    limit = -eps_e / (OMEGA_IE * math.cos(LAT))
    assert abs(limit * AM - (-3.78)) < 0.01
    errs = np.array([_align(seed) for seed in range(1, 21)])
    heading = errs[:, 0]
    assert abs(heading.mean() - limit) <= 0.25 * abs(limit), heading * AM
    # the scatter about the limit against the filter's noise share of its heading sigma:
    # total sigma^2 = (bias prior / (Omega cos lat))^2 + noise^2
    prior = math.radians(0.01) / 3600.0 / (OMEGA_IE * math.cos(LAT))
    noise = np.sqrt(np.mean(errs[:, 3] ** 2) - prior**2)
    scatter = np.sqrt(np.mean((heading - limit) ** 2))
    assert 0.5 * noise <= scatter <= 1.6 * noise, (scatter * AM, noise * AM)
    # level: the tilt that balances the accelerometer biases (100 ug -> ~0.34 arcmin a
    # unit axis), nothing like the coarse alignment's errors
    assert np.all(np.abs(errs[:, 1:3]) * AM < 0.6)
    # the filter knows it cannot do better: its heading sigma is at least the limit's size
    # (the bias prior 0.01 deg/h gives 2.77 arcmin) and no more than the coarse start
    assert np.all((errs[:, 3] * AM > 2.5) & (errs[:, 3] * AM < 4.0)), errs[:, 3] * AM


def test_a_shorter_alignment_is_further_from_the_limit():
    # the estimator really converges in time: 30 s of fine alignment leaves a larger
    # heading sigma than 300 s
    short = _align(1, 40.0)
    full = _align(1, 300.0)
    assert short[3] > full[3] * 1.2


def test_the_coarse_period_noise_does_not_pull_the_fine_heading():
    # At rest the fine alignment sees heading error plus east gyro bias as one sum. The
    # coarse alignment's heading error holds the same bias (it gyrocompasses too), so the
    # fine alignment's prior correlates the two (core_covariance); treated as independent,
    # the fine alignment split the sum by the prior's ratio and kept about 12 % of the
    # coarse period's noise: S000's seed 7, a 2.9-sigma x-gyro draw over its first 10 s,
    # ended 5.5 arcmin off where the limit is 3.8. The same seed's IMU with 3 urad more
    # on the x gyro over the first 10 s (a coarse heading about 20 arcmin further off)
    # must end the alignment where it ends without it.
    plain = _align(7)
    pushed = _align(7, push=3e-6)
    assert abs(pushed[0] - plain[0]) * AM < 0.8, (plain[0] * AM, pushed[0] * AM)
