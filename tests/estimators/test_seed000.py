"""The seed-000 estimator's handling of its inputs and configuration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.dut.estimator import DutInputs, create_estimator
from bench.errors import ConfigError
from bench.estimators.seed000 import Seed000
from tests.estimators.test_alignment import LAT, LON, H, _static_imu

POS = [math.degrees(LAT), math.degrees(LON), H]


def _doppler(t0_ns: int, t1_ns: int, valid: bool) -> dict[str, np.ndarray]:
    t = np.arange(t0_ns + 20_000_000, t1_ns + 1, 20_000_000, dtype=np.int64)
    n = len(t)
    return {
        "rx_ns": t,
        "speed": np.zeros(n),
        "quality": np.full(n, 200, np.uint8),
        "valid": np.full(n, int(valid), np.uint8),
        "low_signal": np.zeros(n, np.uint8),
    }


def _run(est: Seed000, seconds: float, invalid: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    imu = _static_imu(3, seconds)
    sols, quals = [], []
    for k in range(0, len(imu), 20):  # 100 ms steps
        part = imu[k : k + 20]
        t1 = int(part["t_ns"][-1])
        t0 = t1 - 100_000_000
        ok = not (invalid[0] * 1e9 <= t1 < invalid[1] * 1e9)
        out = est.step(DutInputs(t1, part, np.zeros(0), {"DOPPLER": _doppler(t0, t1, ok)}))
        sols.append(out.solutions)
        quals.append(out.qualities)
    return np.concatenate(sols), np.concatenate(quals)


def test_doppler_invalid_suspends_the_dead_reckoning_and_it_restarts_after():
    est = create_estimator("seed000", {"initial_position": POS, "alignment": "60 s"})
    sol, qual = _run(est, 120.0, (80.0, 90.0))
    t = sol["t_ns"] * 1e-9
    assert np.all(sol["mode"][t < 60.0] == 0) and np.all(sol["valid"][t < 60.0] == 0)
    before = (t > 61.0) & (t < 79.9)  # steps ending in [80 s, 90 s) carry invalid samples
    during = (t > 80.0) & (t < 89.9)
    after = t > 90.1
    assert np.all(sol["mode"][before] == 2) and np.all(sol["mode"][after] == 2)
    assert np.all(sol["mode"][during] == 1)  # inertial only
    assert np.all(qual["excluded"][during] & 2) and not np.any(qual["excluded"][before | after] & 2)
    # navigation stays sane at rest throughout
    assert np.all(np.abs(sol["vel_n"][t > 60.0]) < 0.05)
    assert np.all(np.abs(sol["lat"][t > 60.0] - LAT) * 6.4e6 < 2.0)
    # the sigmas are reported and finite
    assert np.all(np.isfinite(qual["sigma_pos"])) and np.all(qual["sigma_att"][t > 60.0] > 0)


def test_configuration_errors_name_the_key():
    with pytest.raises(ConfigError) as e:
        create_estimator("seed000", {"initial_position": POS, "gyro_bais": "0.01 deg/h"})
    assert "gyro_bais" in str(e.value)
    with pytest.raises(ConfigError) as e:
        create_estimator("seed000", {"initial_position": POS, "mode": "position_only"})
    assert e.value.key == "dut.config.mode"
    with pytest.raises(ConfigError) as e:
        create_estimator("seed000", {})
    assert e.value.key == "dut.config.initial_position"
    for bad in (["34 N", 108.9, 380.0], [134.0, 108.9, 380.0], [34.2, float("nan"), 380.0]):
        with pytest.raises(ConfigError) as e:
            create_estimator("seed000", {"initial_position": bad})
        assert e.value.key == "dut.config.initial_position"
    with pytest.raises(ConfigError) as e:
        create_estimator("seed000", {"initial_position": POS, "gyro_noise": "3 m"})
    assert e.value.key == "dut.config.gyro_noise"
    with pytest.raises(ConfigError) as e:
        create_estimator("seed000", {"initial_position": POS, "alignment": "5 s"})
    assert e.value.key == "dut.config.coarse_alignment"


def test_output_epochs_are_on_the_output_grid_without_gaps():
    est = create_estimator("seed000", {"initial_position": POS, "alignment": "30 s", "output_rate": "50 Hz"})
    sol, qual = _run(est, 40.0, (0.0, 0.0))
    assert np.all(np.diff(sol["t_ns"]) == 20_000_000)
    assert sol["t_ns"][0] == 0 or sol["t_ns"][0] == 20_000_000
    assert np.array_equal(sol["t_ns"], qual["t_ns"])


def test_doppler_samples_of_a_step_without_imu_frames_are_kept():
    # the IMU frames and the radar's samples arrive in alternate steps: the radar is
    # never lost (mode stays Doppler-aided) although no step has both
    est = create_estimator("seed000", {"initial_position": POS, "alignment": "30 s"})
    imu = _static_imu(4, 60.0)
    modes = []
    for k in range(0, len(imu), 2):
        part = imu[k : k + 2]
        t1 = int(part["t_ns"][-1])
        modes.append(est.step(DutInputs(t1, part, np.zeros(0), {})).solutions)
        est.step(DutInputs(t1 + 1, imu[:0], np.zeros(0), {"DOPPLER": _doppler(t1 - 20_000_000, t1 + 1, True)}))
    sol = np.concatenate(modes)
    t = sol["t_ns"] * 1e-9
    assert np.all(sol["mode"][t > 31.0] == 2)
