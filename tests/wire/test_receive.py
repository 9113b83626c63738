"""Receivers: the bench's NAV_* receiver counts and keeps every bad frame, never raises."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.frames import CanBatch, CanFrame
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from bench.wire.can import CanEncoder, codec
from bench.wire.receive import BenchTrafficDecoder, NavReceiver


def _nav(n: int, t0: int = 0, epoch0: int = 0):
    rng = np.random.default_rng(n + t0)
    sol = np.zeros(n, NAV_SOLUTION_DTYPE)
    sol["t_ns"] = t0 + np.arange(1, n + 1) * 10_000_000
    sol["rx_ns"] = sol["t_ns"] + 2_000_000
    sol["lat"] = math.radians(34.246) + rng.normal(0, 1e-6, n)
    sol["lon"] = math.radians(108.9096) + rng.normal(0, 1e-6, n)
    sol["h"] = 380.0 + rng.normal(0, 1, n)
    sol["vel_n"] = rng.normal(0, 5, (n, 3))
    sol["heading"] = rng.uniform(0, 2 * math.pi, n)
    sol["pitch"] = rng.normal(0, 0.05, n)
    sol["roll"] = rng.normal(0, 0.05, n)
    sol["frame"], sol["mode"], sol["valid"] = 0, 5, 1
    sol["epoch"] = (epoch0 + np.arange(n)) % 256
    q = np.zeros(n, NAV_QUALITY_DTYPE)
    q["t_ns"], q["rx_ns"], q["epoch"] = sol["t_ns"], sol["rx_ns"], sol["epoch"]
    q["sigma_pos"] = rng.uniform(0.1, 50, (n, 3))
    q["sigma_vel"] = rng.uniform(0.01, 1, (n, 3))
    q["sigma_att"] = rng.uniform(1e-5, 1e-3, (n, 3))
    q["fault_detected"] = rng.integers(0, 16, n)
    q["excluded"] = rng.integers(0, 16, n)
    q["odo_fault_class"] = rng.integers(0, 4, n)
    return sol, q


def _frames(sol, q, enc=None):
    enc = enc or CanEncoder()
    return CanBatch.concat(
        [
            enc.encode_records("NAV_SOLUTION", sol),
            enc.encode_records("NAV_QUALITY", q),
            enc.encode("DUT_READY", sol["rx_ns"] + 1000, time_ns=sol["t_ns"]),
        ]
    ).sorted()


def test_round_trip_of_dut_output_records():
    sol, q = _nav(300, epoch0=200)  # epoch counter wraps 255 -> 0
    rx = NavReceiver()
    out = rx.feed(_frames(sol, q))
    assert rx.tally.as_dict() == {}
    np.testing.assert_array_equal(out.solutions["t_ns"], sol["t_ns"])
    np.testing.assert_array_equal(out.solutions["rx_ns"], sol["rx_ns"])  # arrival = frame time on the bus
    np.testing.assert_array_equal(out.solutions["epoch"], sol["epoch"])
    lsb = math.radians(1e-7)
    assert np.max(np.abs(out.solutions["lat"] - sol["lat"])) <= lsb / 2 * 1.001
    assert np.max(np.abs(out.solutions["vel_n"] - sol["vel_n"])) <= 0.5e-4 * 1.001
    dpsi = (out.solutions["heading"] - sol["heading"] + math.pi) % (2 * math.pi) - math.pi
    assert np.max(np.abs(dpsi)) <= lsb / 2 * 1.001
    assert np.max(np.abs(out.qualities["sigma_att"] - q["sigma_att"])) <= math.radians(0.01 / 60) / 2 * 1.001
    np.testing.assert_array_equal(out.qualities["fault_detected"], q["fault_detected"])
    np.testing.assert_array_equal(out.qualities["odo_fault_class"], q["odo_fault_class"])
    np.testing.assert_array_equal(out.ready_ns, sol["t_ns"])


def test_every_bad_frame_is_counted_by_kind_and_kept():
    sol, q = _nav(40)
    frames = _frames(sol, q).frames()
    bad = []
    i_sol = [i for i, f in enumerate(frames) if f.can_id == 0x300]
    i_q = [i for i, f in enumerate(frames) if f.can_id == 0x301]
    f = frames[i_sol[3]]
    frames[i_sol[3]] = CanFrame(f.t_ns, f.can_id, f.data[:20] + bytes([f.data[20] ^ 1]) + f.data[21:], True)  # crc
    f = frames[i_sol[10]]
    frames[i_sol[10]] = CanFrame(f.t_ns, f.can_id, f.data[:32], True)  # length
    f = frames[i_q[20]]
    frames[i_q[20]] = CanFrame(f.t_ns, f.can_id, f.data, False)  # classic frame where FD is due: length
    bad.append(CanFrame(sol["rx_ns"][5], 0x123, bytes(8)))  # unknown id
    bad.append(CanFrame(sol["rx_ns"][6], 0x010, bytes(8)))  # a bench message from the DUT side
    del frames[i_sol[30]]  # epoch 30 missing: counter skip, 1 lost; its quality has no solution: pairing
    rx = NavReceiver()
    out = rx.feed(CanBatch.from_frames(frames + bad).sorted())
    assert "pairing" not in rx.tally.as_dict()  # the qualities may still get their solutions
    rx.finish()  # the end of the run: they never came
    # the rejected frames are gone: NAV_SOLUTION epochs 3, 10, 30 and NAV_QUALITY epoch 20 count as lost
    assert rx.tally.as_dict() == {"crc": 1, "length": 2, "unknown_id": 2, "counter": 4, "lost": 4, "pairing": 3}
    kinds = sorted(b.kind for b in rx.tally.bad)
    assert kinds.count("crc") == 1 and kinds.count("unknown_id") == 2 and kinds.count("pairing") == 3
    crc_frame = next(b for b in rx.tally.bad if b.kind == "crc")
    assert crc_frame.stream == "can:NAV_SOLUTION" and len(crc_frame.data) == 48
    assert len(out.solutions) == 37 and len(out.qualities) == 39


def test_duplicates_are_dropped_and_counted():
    sol, q = _nav(5)
    frames = _frames(sol, q)
    doubled = CanBatch.concat([frames, frames.take(np.flatnonzero(frames.can_id == 0x300)[:2])]).sorted()
    rx = NavReceiver()
    out = rx.feed(doubled)
    assert rx.tally.as_dict() == {"duplicate": 2}
    assert len(out.solutions) == 5


def test_bench_traffic_decoder_on_the_dut_side():
    enc = CanEncoder()
    t = np.arange(1, 21) * 10_000_000
    batch = CanBatch.concat(
        [
            enc.encode("BENCH_TIME", t, time_ns=t, lockstep=1),
            enc.encode("ODOMETER", t, pulse_count=np.arange(20) * 7, speed=np.linspace(0, 5, 20), reverse=0, valid=1),
        ]
    ).sorted()
    dec = BenchTrafficDecoder()
    out = dec.feed(batch)
    assert dec.tally.as_dict() == {}
    np.testing.assert_array_equal(out["BENCH_TIME"]["time_ns"], t)
    assert out["BENCH_TIME"]["lockstep"].tolist() == [1] * 20
    np.testing.assert_allclose(out["ODOMETER"]["speed"], np.linspace(0, 5, 20), atol=0.005)
    with pytest.raises(KeyError):
        out["DOPPLER"]
    # frozen bench time with the counter running: stale
    frozen = enc.encode("BENCH_TIME", t[:3] + 1_000_000_000, time_ns=np.full(3, t[-1]), lockstep=1)
    dec.feed(frozen)
    assert dec.tally.as_dict() == {"stale": 3}


def test_codec_encode_records_uses_the_record_fields():
    sol, _ = _nav(3)
    frames = CanEncoder().encode_records("NAV_SOLUTION", sol, at_ns=sol["t_ns"])
    np.testing.assert_array_equal(frames.t_ns, sol["t_ns"])
    vals, status = codec("NAV_SOLUTION").decode(frames)
    assert not status.any()
    np.testing.assert_array_equal(vals["epoch"], sol["epoch"])
