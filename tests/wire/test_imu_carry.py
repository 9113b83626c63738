"""IMU increments on the wire keep their sum: the rounding remainder is carried from frame to
frame (as an IMU's pulse counter keeps it), so a low-noise IMU does not drift by the wire's
rounding; window by window through the bench's traffic encoder as in one piece."""

from __future__ import annotations

import numpy as np

from bench.faults.schedule import FaultSchedule
from bench.run.traffic import TrafficEncoder
from bench.sensors.imu.model import IMU_DTYPE
from bench.wire import imu

N = 100_000  # 500 s at 200 Hz
RATE_LSB = np.array([365.3, -72.25, 12.4999])  # increments per frame, in LSB: no noise to dither them


def _records() -> np.ndarray:
    rec = np.zeros(N, IMU_DTYPE)
    rec["t_ns"] = (np.arange(N, dtype=np.int64) + 1) * 5_000_000
    rec["dtheta"] = RATE_LSB * imu.DTHETA_LSB
    rec["dvel"] = RATE_LSB[::-1] * 10 * imu.DVEL_LSB
    rec["temperature"] = 25.0
    return rec


def test_carried_rounding_keeps_the_sum_within_one_lsb_where_rounding_each_frame_drifts():
    v = np.tile(RATE_LSB * imu.DTHETA_LSB, (N, 1))
    sent, rest = imu.carry_quantize(v, imu.DTHETA_LSB, np.zeros(3))
    counts = sent / imu.DTHETA_LSB
    assert np.allclose(counts, np.rint(counts), atol=1e-6)  # whole LSBs
    assert np.all(np.abs(counts - RATE_LSB) <= 1.0 + 1e-9)  # each frame within one LSB of its increment
    drift = np.cumsum(counts, axis=0) - np.cumsum(np.tile(RATE_LSB, (N, 1)), axis=0)
    assert np.abs(drift).max() <= 0.501  # float sums of 1e5 terms
    assert np.allclose(rest, -drift[-1], atol=1e-6)
    # what rounding each frame on its own does: 0.3, 0.25 and 0.4999 LSB per frame, all the same way
    own = np.cumsum(np.rint(np.tile(RATE_LSB, (N, 1))), axis=0)[-1] - RATE_LSB * N
    assert np.all(np.abs(own) > 0.2 * N)


def test_the_carry_runs_across_calls_as_in_one_piece():
    rng = np.random.default_rng(7)
    v = (RATE_LSB + rng.normal(0.0, 0.2, (5000, 3))) * imu.DTHETA_LSB
    whole, _ = imu.carry_quantize(v, imu.DTHETA_LSB, np.zeros(3))
    carry, parts, cuts = np.zeros(3), [], np.sort(rng.choice(np.arange(1, 5000), 40, replace=False))
    for piece in np.split(v, cuts):
        sent, carry = imu.carry_quantize(piece, imu.DTHETA_LSB, carry)
        parts.append(sent)
    assert np.array_equal(np.rint(np.concatenate(parts) / imu.DTHETA_LSB), np.rint(whole / imu.DTHETA_LSB))
    empty, kept = imu.carry_quantize(np.zeros((0, 3)), imu.DTHETA_LSB, carry)
    assert len(empty) == 0 and np.array_equal(kept, carry)


def test_frames_of_the_traffic_encoder_sum_to_the_increments_within_one_lsb():
    rec = _records()
    enc = TrafficEncoder([], epoch_ns=0, lockstep=True, schedule=FaultSchedule(), seed=0, topics={"imu": "/imu"})
    chunks = []
    step = 1_000_000_000  # windows of one second
    for t0 in range(0, int(rec["t_ns"][-1]), step):
        sel = rec[(rec["t_ns"] > t0) & (rec["t_ns"] <= t0 + step)]
        chunks.append(enc.window({"/imu": sel}, t0, t0 + step).imu.buf)
    wire, status = imu.decode_frames(np.concatenate(chunks))
    assert len(wire) == N and not status.any()
    th = wire["dtheta"] / imu.DTHETA_LSB
    dv = wire["dvel"] / imu.DVEL_LSB
    assert np.abs(np.cumsum(th, axis=0) - np.cumsum(rec["dtheta"] / imu.DTHETA_LSB, axis=0)).max() <= 0.501
    assert np.abs(np.cumsum(dv, axis=0) - np.cumsum(rec["dvel"] / imu.DVEL_LSB, axis=0)).max() <= 0.501
