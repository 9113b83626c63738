"""The fault matrix (issue 33, item 2): the IMU interval is never assumed (what every row
checks: tests/fault_matrix/test_inputs.py).

Before issue 33 an IMU log encoded at its native 100 Hz and replayed with the default
10 ms step made all four reference estimators take 5 ms as the IMU interval (no step held
two frames, so the shared rest alignment could not measure it and fell back to 5 ms):
each frame was integrated as 5 ms, the filter estimated a 1 g accelerometer bias and
drifted, and the run ended ``complete``, exit 0. Nothing warned.

Each row is a real run: a parked vehicle synthesised by ``bench synth`` at the IMU rate
of the row, its IMU samples encoded to the ICD byte stream (the log a user brings), then
``bench replay --imu-log`` into an estimator, and the solution judged against the truth
(parked at the surveyed point): position held, velocity zero, level attitude.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bench.record.mcap_io import RecordingReader
from bench.wire.imu import encode_frames
from tests.fault_matrix.matrix import bench

LAT, LON, H = 34.246, 108.909, 380.0
HEADING = 30.0
PARKED = f"""
[scenario]
id = "REST"
title = "parked"
start_utc = "2026-03-01T08:00:00Z"

[initial]
latitude = {LAT}
longitude = {LON}
height = "{H} m"
heading = "{HEADING} deg"

[imu]
grade = "navigation"
rate = "{{rate}}"

[[segment]]
kind = "static"
duration = "{{duration}}"
"""
CONFIG = f"""
initial_position = [{LAT}, {LON}, {H}]
coarse_alignment = "10 s"
alignment = "40 s"
"""
NAV_FROM_S = 45.0  # the fine alignment ends at 40 s


def _synth(folder: Path, rate: str, duration: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "parked.toml").write_text(PARKED.format(rate=rate, duration=duration))
    out = folder / "synth.mcap"
    bench("synth", str(folder / "parked.toml"), "-o", str(out), "-q", cwd=folder, expect=0)
    return out


def _samples(rec: Path) -> np.ndarray:
    return RecordingReader(rec).read_columnar("/imu")


def _encode(imu: np.ndarray, path: Path) -> Path:
    """The samples as the ICD byte stream of the imu line (a logger's file)."""
    frames = encode_frames(imu["t_ns"], imu["dtheta"], imu["dvel"], imu["status"], imu["temperature"],
                           np.arange(len(imu)) % 256)
    path.write_bytes(frames.tobytes())
    return path


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("imu_interval")
    (d / "cfg.toml").write_text(CONFIG)
    (d / "empty_faults.toml").write_text("fault = []  # no faults: re-encode the samples\n")
    return d


@pytest.fixture(scope="module")
def log100(folder) -> Path:
    """90 s parked, 100 Hz, as an ICD IMU byte log."""
    return _encode(_samples(_synth(folder / "s100", "100 Hz", "90 s")), folder / "imu100.bin")


def _solution(rec: Path) -> np.ndarray:
    return RecordingReader(rec).read_columnar("/dut/nav_solution")


def _assert_parked(rec: Path, until_s: float) -> None:
    """After the alignment the solution holds the surveyed point at rest, level (the
    navigation grade's accelerometer biases tilt it by hundredths of a degree)."""
    s = _solution(rec)
    t = s["t_ns"] * 1e-9
    nav = s[t >= NAV_FROM_S]
    assert len(nav) and t[-1] >= until_s - 0.1, f"the solution ends at {t[-1]:.2f} s"
    assert np.all(nav["valid"] == 1)
    r = 6.378e6
    north = (nav["lat"] - math.radians(LAT)) * r
    east = (nav["lon"] - math.radians(LON)) * r * math.cos(math.radians(LAT))
    horiz = float(np.max(np.hypot(north, east)))
    vert = float(np.max(np.abs(nav["h"] - H)))
    speed = float(np.max(np.linalg.norm(nav["vel_n"], axis=1)))
    tilt = float(np.degrees(np.max(np.abs(np.concatenate([nav["pitch"], nav["roll"]])))))
    hdg = float(np.degrees(np.max(np.abs(np.angle(np.exp(1j * (nav["heading"] - math.radians(HEADING))))))))
    figures = f"horizontal {horiz:.3f} m, vertical {vert:.3f} m, speed {speed:.4f} m/s, tilt {tilt:.4f} deg, " \
              f"heading error {hdg:.3f} deg"
    assert horiz < 0.5 and vert < 0.5 and speed < 0.02, figures
    assert tilt < 0.05 and hdg < 0.5, figures


# ------------------------------------------------------------------ Why: 100 Hz at 10 ms steps
@pytest.mark.parametrize("estimator", ["seed000", "seed001", "seed002", "seed003"])
def test_a_100_hz_log_at_the_default_10_ms_step_aligns_and_holds_the_parked_vehicle(folder, log100, estimator):
    out = folder / f"why_{estimator}.mcap"
    bench("replay", "--imu-log", str(log100), "--estimator", estimator, "--dut-config", str(folder / "cfg.toml"),
          "-o", str(out), "-q", "--force", cwd=folder, expect=0)
    _assert_parked(out, 90.0)


# ------------------------------------------------------------------ the declared rate
def test_a_log_at_another_rate_than_declared_is_refused_before_the_run_naming_both(folder, log100):
    out = folder / "refused.mcap"
    r = bench("replay", "--imu-log", str(log100), "--estimator", "seed000", "--dut-config",
              str(folder / "cfg.toml"), "--imu-rate", "200 Hz", "-o", str(out), "-q", cwd=folder, expect=2)
    assert "--imu-rate" in r.err and "100 Hz" in r.err and "200 Hz" in r.err and "imu100.bin" in r.err, r.err
    assert not out.exists()
    # the reference case declares 200 Hz: a 100 Hz log replayed into it is refused, the case named
    case = Path(__file__).parents[2] / "test_cases" / "S000_sins_doppler.toml"
    r = bench("replay", "--imu-log", str(log100), "--case", str(case), "-o", str(out), "-q", cwd=folder, expect=2)
    assert "S000_sins_doppler.toml" in r.err and "sensors.imu.rate" in r.err, r.err
    assert "100 Hz" in r.err and "200 Hz" in r.err, r.err
    assert not out.exists()
    # declared right: it runs
    bench("replay", "--imu-log", str(log100), "--estimator", "seed000", "--dut-config", str(folder / "cfg.toml"),
          "--imu-rate", "100 Hz", "-o", str(out), "-q", cwd=folder, expect=0)


def test_a_recording_replayed_into_a_case_of_another_rate_is_refused(folder):
    rec = _synth(folder / "s100r", "100 Hz", "20 s")
    case = Path(__file__).parents[2] / "test_cases" / "S000_sins_doppler.toml"
    out = folder / "refused_rec.mcap"
    r = bench("replay", str(rec), "--faults", str(folder / "empty_faults.toml"), "--case", str(case), "-o", str(out),
              "-q", cwd=folder, expect=2)
    assert "S000_sins_doppler.toml" in r.err and "100 Hz" in r.err and "200 Hz" in r.err, r.err
    assert not out.exists()


# ------------------------------------------------------------------ 1 kHz at 1 s steps
def test_a_1_khz_recording_at_1_s_steps_aligns_and_holds(folder):
    rec = _synth(folder / "s1k", "1000 Hz", "60 s")
    out = folder / "r1k.mcap"
    bench("replay", str(rec), "--faults", str(folder / "empty_faults.toml"), "--estimator", "seed000",
          "--dut-config", str(folder / "cfg.toml"), "--step", "1000", "-o", str(out), "-q", "--force",
          cwd=folder, expect=0)
    _assert_parked(out, 60.0)


# ------------------------------------------------------------------ a rate change mid-log
def test_a_log_whose_rate_changes_mid_log_is_refused_naming_the_time_and_both_rates(folder, log100):
    imu = _samples(folder / "s100" / "synth.mcap")
    half = len(imu) // 2
    slow = imu[half:][1::2].copy()  # 50 Hz from the middle on: pairs of 10 ms frames summed into 20 ms ones
    slow["dtheta"] += imu[half:][0::2]["dtheta"][: len(slow)]
    slow["dvel"] += imu[half:][0::2]["dvel"][: len(slow)]
    log = _encode(np.concatenate([imu[:half], slow]), folder / "imu_100_then_50.bin")
    out = folder / "change.mcap"
    r = bench("replay", "--imu-log", str(log), "--estimator", "seed000", "--dut-config", str(folder / "cfg.toml"),
              "-o", str(out), "-q", cwd=folder, expect=2)
    assert "imu_100_then_50.bin" in r.err and "changes rate" in r.err, r.err
    assert "100 Hz" in r.err and "50 Hz" in r.err and "45" in r.err, r.err
    assert not out.exists()


# ------------------------------------------------------------------ the real laser-gyro log
PSINS = Path(__file__).parents[1] / "data" / "psins_lasergyro_10min.imu"


def _psins_to_icd(path: Path, out: Path) -> tuple[float, float, float, float]:
    """The PSINS SIMU text log (tests/data/README.md: 0.1 arcsec and 125 ug*s counts, RFU,
    the interval and g in its second parameter line) as the ICD byte stream at its own
    100 Hz; returns (lat, lon, h) and the level attitude (pitch, roll, deg) of the whole
    log's mean specific force, an independent levelling (numpy only)."""
    a = np.loadtxt(path, comments="%")
    pos, sf, data = a[1], a[2], a[3:]
    dt, g = pos[4] * 1e-3, pos[5]
    n = len(data)
    t = np.round(np.arange(1, n + 1) * dt * 1e9).astype(np.int64)
    dth = data[:, :3] * sf[:3] * math.radians(1 / 3600)
    dv = data[:, 3:] * sf[3:] * 1e-6 * g
    frames = encode_frames(t, dth, dv, np.zeros(n, np.int64), np.full(n, 25.0), np.arange(n) % 256)
    out.write_bytes(frames.tobytes())
    f = dv.sum(axis=0)
    return (float(pos[0]), float(pos[1]), float(pos[2]), math.degrees(math.atan2(f[1], math.hypot(f[0], f[2]))),
            math.degrees(math.atan2(-f[0], f[2])))


def test_the_real_100_hz_laser_gyro_log_at_the_default_step_aligns_and_holds(folder):
    """The issue's own log (10 min of it): before, 5 ms taken for its 10 ms interval and a
    drift of kilometres; now the heading of the log's header (PSINS yaw -90.6 deg, counted
    to the west: 90.6 deg), the levelling of its mean specific force, the point held."""
    lat, lon, h, pitch, roll = _psins_to_icd(PSINS, folder / "psins.bin")
    (folder / "dut_config.toml").write_text(f"initial_position = [{lat}, {lon}, {h}]\n")
    out = folder / "psins.mcap"
    bench("replay", "--imu-log", str(folder / "psins.bin"), "--estimator", "seed000",
          "--dut-config", str(folder / "dut_config.toml"), "-o", str(out), "-q", "--force", cwd=folder, expect=0)
    s = _solution(out)
    t = s["t_ns"] * 1e-9
    assert t[-1] >= 599.9
    nav = s[t >= 305.0]  # the seed000 default alignment is 300 s
    r = 6.378e6
    north = (nav["lat"] - math.radians(lat)) * r
    east = (nav["lon"] - math.radians(lon)) * r * math.cos(math.radians(lat))
    horiz = float(np.max(np.hypot(north, east)))
    speed = float(np.max(np.linalg.norm(nav["vel_n"], axis=1)))
    hdg = np.degrees(nav["heading"])
    dp = float(np.max(np.abs(np.degrees(nav["pitch"]) - pitch)))
    dr = float(np.max(np.abs(np.degrees(nav["roll"]) - roll)))
    figures = (f"horizontal {horiz:.2f} m, speed {speed:.4f} m/s, heading {hdg.min():.3f}..{hdg.max():.3f} deg, "
               f"pitch off {dp * 60:.1f}', roll off {dr * 60:.1f}'")
    assert horiz < 20.0 and speed < 0.1, figures
    assert np.all(np.abs(hdg - 90.6) < 0.5), figures
    assert dp < 0.25 and dr < 0.25, figures  # a rocking vehicle: the filter's level follows it


# ------------------------------------------------------------------ a synthetic case at 100 Hz
CASE_100 = f"""
[case]
id = "IMU100"
title = "parked, 100 Hz IMU, the default 10 ms step"
requirements = ["R"]

[scenario]
script = "parked.toml"

[sensors]
imu = {{ grade = "navigation", rate = "100 Hz" }}

[dut]
kind = "in_process"
name = "seed000"
config = {{ initial_position = [{LAT}, {LON}, {H}], coarse_alignment = "10 s", alignment = "40 s" }}

[run]
seeds = [1]

[scoring]
convergence = "{NAV_FROM_S:g} s"

[[criterion]]
id = "H"
requirement = "R"
metric = "accuracy.horizontal.max"
window = "converged"
at_most = "0.5 m"

[[criterion]]
id = "V"
requirement = "R"
metric = "accuracy.vertical.max"
window = "converged"
at_most = "0.5 m"
"""


def test_a_case_whose_imu_runs_at_100_hz_passes_at_the_default_step(folder):
    """``bench run`` of a case with ``imu = { rate = "100 Hz" }`` (a step holds one frame):
    before, 5 ms per frame and a FAIL by metres; now the parked point within centimetres."""
    d = folder / "case100"
    d.mkdir()
    (d / "parked.toml").write_text(PARKED.format(rate="100 Hz", duration="90 s"))
    (d / "case.toml").write_text(CASE_100)
    r = bench("run", str(d / "case.toml"), "-o", str(d / "out"), "-q", cwd=d, expect=0)
    assert "PASS     IMU100" in r.out, r.out
