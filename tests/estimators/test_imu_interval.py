"""The IMU interval measured from the frames' own times, whatever the rate and the step
(issue 33 item 2): the shared rest alignment, seed003's moving start, and the bench's
stream-rate check (bench.run.imu_rate)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.dut.estimator import DutInputs, create_estimator
from bench.errors import ConfigError
from bench.estimators.rest_alignment import RestAlignment
from bench.frames import SerialBatch
from bench.run.imu_rate import BLOCK_GAPS, measure_stream, require_rate
from bench.wire.imu import IMU_SAMPLE_DTYPE, encode_frames


def _frames(t_ns) -> np.ndarray:
    imu = np.zeros(len(t_ns), IMU_SAMPLE_DTYPE)
    imu["t_ns"] = t_ns
    return imu


def _steps(imu: np.ndarray, step_ns: int):
    """The frames cut at lockstep step times, as the bench hands them over."""
    t = 0
    while t < imu["t_ns"][-1]:
        t += step_ns
        yield t, imu[(imu["t_ns"] > t - step_ns) & (imu["t_ns"] <= t)]


@pytest.mark.parametrize(("rate", "step_ms"), [(100, 10), (1000, 1000), (1, 10), (200, 10), (50, 7), (400, 3)])
def test_the_rest_alignment_measures_the_interval_at_any_rate_and_step(rate, step_ms):
    rest = RestAlignment()
    interval = 1_000_000_000 // rate
    for _, part in _steps(_frames(np.arange(1, 12 * rate + 1) * interval), step_ms * 1_000_000):
        rest.add(part)
    assert rest.nominal_step_s() == pytest.approx(1.0 / rate, rel=1e-12)


def test_lost_frames_do_not_move_the_measured_interval():
    t = np.arange(1, 2001) * 5_000_000
    t = np.delete(t, np.arange(3, 2000, 7))  # one frame in seven lost on the wire
    rest = RestAlignment()
    for _, part in _steps(_frames(t), 10_000_000):
        rest.add(part)
    assert rest.nominal_step_s() == pytest.approx(0.005)


def test_a_coarse_period_of_one_frame_says_so_instead_of_guessing():
    rest = RestAlignment()
    rest.add(_frames([1_000_000_000]))  # 1 Hz, the first frame
    with pytest.raises(ConfigError) as e:
        rest.nominal_step_s()
    assert e.value.key == "dut.config.coarse_alignment" and "cannot be measured" in str(e.value)
    with pytest.raises(ConfigError):
        RestAlignment().nominal_step_s()


def test_seed003_moving_start_takes_the_interval_of_two_frames_when_each_step_holds_one():
    """100 Hz at 10 ms steps: the first frame is held until the second gives the interval,
    then the drive at constant velocity is integrated over 10 ms frames (not 5 ms)."""
    est = create_estimator("seed003", {"initial_position": [30.0, 110.0, 50.0], "start": "moving",
                                       "initial_velocity": [0.0, 10.0, 0.0]})
    rate = 100
    n = 10 * rate
    imu = _frames(np.arange(1, n + 1) * (1_000_000_000 // rate))
    lat = math.radians(30.0)
    g = 9.7932  # the level specific force holds the vehicle (a small vertical drift at most)
    imu["dvel"][:, 2] = g / rate
    w_ie = 7.292115e-5
    imu["dtheta"][:, 1] = w_ie * math.cos(lat) / rate
    imu["dtheta"][:, 2] = w_ie * math.sin(lat) / rate
    outs = [est.step(DutInputs(t, part, np.zeros(0), {})).solutions for t, part in _steps(imu, 10_000_000)]
    assert len(outs[0]) == 0  # the first step's frame is held: one frame has no interval
    sol = np.concatenate(outs)
    assert sol["t_ns"][0] == imu["t_ns"][0]  # ... and answered for with the second step
    north = (sol["lat"][-1] - lat) * 6.378e6
    assert north == pytest.approx(100.0, abs=1.0)  # 10 s at 10 m/s north (5 ms frames: 50 m)


def test_the_stream_rate_is_measured_from_the_frames_bytes_and_refused_when_not_declared():
    t = np.arange(1, 1001) * 10_000_000
    frames = encode_frames(t, np.zeros((1000, 3)), np.zeros((1000, 3)), 0, 25.0, np.arange(1000) % 256)
    batch = SerialBatch.from_fixed(t, frames)
    rate = measure_stream(batch, source="imu.bin")
    assert rate is not None and rate.rate_hz == pytest.approx(100.0) and rate.frames == 1000
    require_rate(rate, 100.0, file=None, key="--imu-rate")
    require_rate(rate, 101.5, file=None, key="--imu-rate")  # within 2 %: an IMU's clock
    with pytest.raises(ConfigError) as e:
        require_rate(rate, 200.0, file="case.toml", key="sensors.imu.rate")
    assert "100 Hz" in str(e.value) and "200 Hz" in str(e.value) and "imu.bin" in str(e.value)
    assert e.value.file == "case.toml" and e.value.key == "sensors.imu.rate"
    assert measure_stream(t[:1], source="x") is None  # one frame: nothing to measure


def test_a_rate_change_is_refused_but_lost_frames_and_jitter_are_not():
    rng = np.random.default_rng(3)
    t = np.arange(1, 20001) * 5_000_000 + rng.integers(-200_000, 200_000, 20000)  # 200 Hz, 0.2 ms jitter
    lossy = np.delete(t, rng.choice(20000, 4000, replace=False))  # 20 % lost
    assert measure_stream(lossy, source="x").rate_hz == pytest.approx(200.0, rel=1e-3)
    change = np.concatenate([t[:10000], t[10000] + np.arange(0, 5000) * 10_000_000])  # 200 Hz, then 100 Hz
    with pytest.raises(ConfigError) as e:
        measure_stream(change, source="imu.bin")
    msg = str(e.value)
    assert "changes rate" in msg and "median interval 5.0" in msg and "100 Hz (10 ms)" in msg
    assert e.value.file == "imu.bin"
    # a change inside a block is found at that block (within BLOCK_GAPS frames)
    at = float(msg.split("from bench time ")[1].split(" s")[0])
    assert abs(at - t[10000] * 1e-9) <= BLOCK_GAPS * 0.005 + 1e-9


def test_seed001_keeps_2_s_of_ins_history_at_1_khz():
    """The history a delayed BDS fix is placed in: 400 states are 2 s at 200 Hz, 0.4 s at
    1 kHz; it is sized by the measured interval."""
    # the coarse period ends by half the alignment at the latest, then the history is sized
    est = create_estimator("seed001", {"initial_position": [30.0, 110.0, 50.0], "coarse_alignment": "2 s",
                                        "alignment": "4 s"})
    imu = _frames(np.arange(1, 3001) * 1_000_000)
    imu["dvel"][:, 2] = 9.79e-3  # at rest, level, heading north: gravity and the Earth's rate
    imu["dtheta"][:, 1] = 7.292115e-5 * math.cos(math.radians(30.0)) * 1e-3
    imu["dtheta"][:, 2] = 7.292115e-5 * math.sin(math.radians(30.0)) * 1e-3
    for t, part in _steps(imu, 1_000_000_000):
        est.step(DutInputs(t, part, np.zeros(0), {}))
    assert est.hist.shape[0] >= 2000


def test_frames_lost_on_the_wire_are_no_rate_change_when_the_counters_say_so():
    """60 % of the frames of a stretch dropped on the wire: the counters skip, the rate holds;
    the same stream re-counted (a logger at half the rate) is a rate change."""
    n = 6000
    t = np.arange(1, n + 1) * 5_000_000
    counter = np.arange(n) % 256
    rng = np.random.default_rng(1)
    lost = np.zeros(n, bool)
    lost[2000:4000] = rng.random(2000) < 0.6
    keep = ~lost
    frames = encode_frames(t[keep], np.zeros((keep.sum(), 3)), np.zeros((keep.sum(), 3)), 0, 25.0, counter[keep])
    rate = measure_stream(SerialBatch.from_fixed(t[keep], frames), source="imu.bin")
    assert rate is not None and rate.rate_hz == pytest.approx(200.0)
    half = np.concatenate([t[:2000], t[2000::2]])
    frames = encode_frames(half, np.zeros((len(half), 3)), np.zeros((len(half), 3)), 0, 25.0,
                           np.arange(len(half)) % 256)
    with pytest.raises(ConfigError, match="changes rate"):
        measure_stream(SerialBatch.from_fixed(half, frames), source="imu.bin")
