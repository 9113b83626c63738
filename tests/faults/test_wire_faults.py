"""Wire faults: registration, determinism, and a DUT-side decoder counting every kind correctly.

Each fault kind runs in its own window on a stream where a receiver can see it; the
decoders of :mod:`bench.wire` (the DUT's side of the wire) then count what they see,
and the counts must be exactly what the rules of docs/wire.md predict from the number
of frames each window acted on (taken from the injector's event records).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.faults.schedule import parse_schedule, registered_kinds
from bench.faults.wire import WIRE_EVENT_DTYPE, WIRE_EVENTS_TOPIC, WIRE_KINDS, WireFaultInjector, wire_windows
from bench.frames import CanBatch, SerialBatch
from bench.wire import imu
from bench.wire.can import CanEncoder
from bench.wire.imu_stream import ImuStreamDecoder
from bench.wire.nmea import GNSS_FIX_DTYPE, encode_epochs
from bench.wire.nmea_stream import NmeaStreamDecoder
from bench.wire.receive import BenchTrafficDecoder

MS = 1_000_000
T_END = 4_000 * MS


def _w(kind, start_ms, end_ms, target, **params):
    return {
        "kind": kind,
        "layer": "wire",
        "target": target,
        "start": f"{start_ms} ms",
        "end": f"{end_ms} ms",
        "params": params,
    }


def _can_traffic(t_end=T_END):
    rng = np.random.default_rng(1)
    enc = CanEncoder()
    t10 = np.arange(10 * MS, t_end + 1, 10 * MS)
    t20 = np.arange(20 * MS, t_end + 1, 20 * MS)
    return CanBatch.concat(
        [
            enc.encode("BENCH_TIME", t10, time_ns=t10, lockstep=0),
            enc.encode(
                "ODOMETER",
                t10 + 1000,
                pulse_count=np.arange(t10.size) * 5,
                speed=8 + rng.normal(0, 0.2, t10.size),
                reverse=0,
                valid=1,
            ),
            enc.encode(
                "DOPPLER", t20 + 2000, speed=8 + rng.normal(0, 0.05, t20.size), quality=200, valid=1, low_signal=0
            ),
        ]
    ).sorted()


def _imu_traffic(t_end=T_END):
    rng = np.random.default_rng(2)
    t = np.arange(5 * MS, t_end + 1, 5 * MS)
    return imu.encode_batch(
        t, rng.normal(0, 1e-4, (t.size, 3)), rng.normal(0, 1e-2, (t.size, 3)), 0x3F, 25.0, np.arange(t.size) % 256
    )


def _run_can(inj, traffic, step_ms, t_end=T_END):
    outs, evs = [], []
    for k in range(0, max(t_end, int(traffic.t_ns.max())), step_ms * MS):
        sel = (traffic.t_ns > k) & (traffic.t_ns <= k + step_ms * MS)
        o, e = inj.can(traffic.take(sel), until_ns=k + step_ms * MS)
        outs.append(o)
        evs.append(e)
    outs.append(inj.flush_can())
    return CanBatch.concat(outs), np.concatenate(evs)


def _run_serial(inj, stream, traffic, step_ms, t_end=T_END):
    outs, evs = [], []
    for k in range(0, max(t_end, int(traffic.t_ns.max())), step_ms * MS):
        sel = (traffic.t_ns > k) & (traffic.t_ns <= k + step_ms * MS)
        o, e = inj.serial(stream, traffic.take(sel), until_ns=k + step_ms * MS)
        outs.append(o)
        evs.append(e)
    outs.append(inj.flush_serial(stream))
    return SerialBatch.concat(outs), np.concatenate(evs)


def _k(events, schedule, kind):
    ids = [w.id for w in schedule if w.kind == kind]
    return int(np.isin(events["fault_id"], ids).sum())


# ---------------------------------------------------------------------------- registry
def test_every_kind_is_registered_on_the_wire_layer():
    wire = {k.kind for k in registered_kinds() if k.layer == "wire"}
    assert wire == set(WIRE_KINDS)
    assert WIRE_EVENTS_TOPIC.dtype == WIRE_EVENT_DTYPE and "t_ns" in WIRE_EVENT_DTYPE.names


@pytest.mark.parametrize(
    ("table", "match"),
    [
        (_w("wrong_dlc", 0, 10, "serial:imu"), "applies to can:"),
        (_w("bad_checksum", 0, 10, "can:ODOMETER"), "applies to serial:gnss"),
        (_w("freeze", 0, 10, "serial:gnss"), "applies to"),
        (_w("silence", 0, 10, "can:ODOMETER"), "applies to can, serial"),
        (_w("baud_mismatch", 0, 10, "serial:imu"), "missing parameter"),
        (_w("delay", 0, 10, "can:ODOMETER", delay="5 m"), "delay"),
    ],
)
def test_schedule_errors(table, match):
    with pytest.raises(ConfigError, match=match):
        wire_windows(parse_schedule([table], file="case.toml"))


@pytest.mark.parametrize(
    ("table", "match"),
    [
        (_w("drop", 0, 10, "can:ODOMETR"), "no message 'ODOMETR'"),
        (_w("offset", 0, 10, "can:ODOMETER", signal="sped", value=1.0), "signal must be one of"),
        (_w("offset", 0, 10, "serial:imu", signal="dtheta", value=1.0), r"dtheta\[0..2\]"),
        (_w("wrong_dlc", 0, 10, "can:DOPPLER", dlc=9), "dlc must be"),
        (_w("drop", 0, 10, "can:DOPPLER", probability=1.5), "probability"),
        (_w("counter_skip", 0, 10, "serial:imu", skip=0), "skip must be at least 1"),
    ],
)
def test_window_checks(table, match):
    with pytest.raises(ConfigError, match=match):
        WireFaultInjector(parse_schedule([table]))


# ---------------------------------------------------------------------------- determinism
def test_result_does_not_depend_on_how_the_run_is_cut():
    sched = parse_schedule(
        [
            _w("drop", 100, 900, "can:*", probability=0.3),
            _w("delay", 1000, 1500, "can:ODOMETER", delay="3 ms", jitter="25 ms"),
            _w("duplicate", 1600, 1700, "can:DOPPLER", copies=2, gap="1 ms"),
            _w("corrupt_crc", 1800, 1900, "can:*"),
            _w("counter_skip", 2000, 2100, "can:BENCH_TIME", skip=3),
        ]
    )
    traffic = _can_traffic(2_500 * MS)
    results = [_run_can(WireFaultInjector(sched, seed=9), traffic, step, 2_500 * MS) for step in (10, 70, 2500)]
    for out, ev in results[1:]:
        np.testing.assert_array_equal(out.t_ns, results[0][0].t_ns)
        np.testing.assert_array_equal(out.can_id, results[0][0].can_id)
        np.testing.assert_array_equal(out.data, results[0][0].data)
        np.testing.assert_array_equal(
            np.sort(ev, order=["t_ns", "fault_id", "can_id"]),
            np.sort(results[0][1], order=["t_ns", "fault_id", "can_id"]),
        )
    other, _ = _run_can(WireFaultInjector(sched, seed=10), traffic, 10, 2_500 * MS)
    assert len(other) != len(results[0][0]) or not np.array_equal(other.t_ns, results[0][0].t_ns)
    assert np.all(np.diff(results[0][0].t_ns) >= 0)


def test_no_windows_no_change():
    traffic = _can_traffic(500 * MS)
    out, ev = _run_can(WireFaultInjector(parse_schedule([])), traffic, 50, 500 * MS)
    assert ev.size == 0 and np.array_equal(out.data, traffic.data) and np.array_equal(out.t_ns, traffic.t_ns)


# ---------------------------------------------------------------------------- every kind, counted
def test_can_decoder_counts_every_can_fault_kind():
    sched = parse_schedule(
        [
            _w("drop", 100, 130, "can:ODOMETER"),
            _w("delay", 300, 350, "can:BENCH_TIME", delay="4 ms"),
            _w("delay", 400, 600, "can:BENCH_TIME", jitter="8 ms"),
            _w("duplicate", 700, 740, "can:ODOMETER"),
            _w("freeze", 900, 1000, "can:DOPPLER"),
            _w("offset", 1100, 1150, "can:ODOMETER", signal="speed", value=1.5),
            _w("scale", 1200, 1300, "can:DOPPLER", signal="speed", factor=1.1),
            _w("corrupt_crc", 1400, 1430, "can:ODOMETER"),
            _w("counter_stale", 1600, 1650, "can:ODOMETER"),
            _w("counter_skip", 1800, 1830, "can:DOPPLER", skip=2),
            _w("wrong_dlc", 2000, 2040, "can:ODOMETER", dlc=6),
            _w("silence", 2200, 2250, "can"),
        ]
    )
    traffic = _can_traffic()
    inj = WireFaultInjector(sched, seed=3)
    out, ev = _run_can(inj, traffic, 25)
    dec = BenchTrafficDecoder(late_ns=3 * MS, stale=("BENCH_TIME", "DOPPLER"))
    got = dec.feed(out)
    k = {kind: _k(ev, sched, kind) for kind in WIRE_KINDS}
    assert k["drop"] == 3 and k["silence"] == 5 + 5 + 3 and k["freeze"] == 5
    jitter_id = next(w.id for w in sched if w.kind == "delay" and w.params["jitter"])
    late_jitter = int(np.sum(ev["value"][ev["fault_id"] == jitter_id] > 3 * MS))
    assert 0 < late_jitter < 20
    expected = {
        "skip": 1 + 1 + k["counter_skip"] + 1 + 3,  # drop, crc, skip, dlc, silence (one per message)
        "lost": k["drop"] + k["corrupt_crc"] + 2 * k["counter_skip"] + k["wrong_dlc"] + k["silence"],
        "late": 5 + late_jitter,
        "duplicate": k["duplicate"],
        "stale": k["freeze"],
        "crc": k["corrupt_crc"],
        "repeat": k["counter_stale"],
        "length": k["wrong_dlc"],
    }
    assert dec.tally.as_dict() == expected
    # offset and scale: valid frames, wrong values
    odo, ref = got["ODOMETER"], BenchTrafficDecoder().feed(traffic)["ODOMETER"]
    w_on = (odo["rx_ns"] >= 1100 * MS) & (odo["rx_ns"] < 1150 * MS)
    r_on = (ref["rx_ns"] >= 1100 * MS) & (ref["rx_ns"] < 1150 * MS)
    np.testing.assert_allclose(odo["speed"][w_on], ref["speed"][r_on] + 1.5, atol=0.006)
    dop, dref = got["DOPPLER"], BenchTrafficDecoder().feed(traffic)["DOPPLER"]
    w_on = (dop["rx_ns"] >= 1200 * MS) & (dop["rx_ns"] < 1300 * MS)
    r_on = (dref["rx_ns"] >= 1200 * MS) & (dref["rx_ns"] < 1300 * MS)
    np.testing.assert_allclose(dop["speed"][w_on], dref["speed"][r_on] * 1.1, atol=1e-4)


def test_imu_decoder_counts_every_serial_fault_kind():
    sched = parse_schedule(
        [
            _w("drop", 100, 115, "serial:imu"),
            _w("delay", 300, 330, "serial:imu", delay="4 ms"),
            _w("duplicate", 500, 520, "serial:imu"),
            _w("freeze", 700, 730, "serial:imu"),
            _w("offset", 900, 950, "serial:imu", signal="dvel[2]", value=0.02),
            _w("scale", 1000, 1050, "serial:imu", signal="dtheta[0]", factor=2.0),
            _w("corrupt_crc", 1100, 1115, "serial:imu"),
            _w("counter_stale", 1300, 1320, "serial:imu"),
            _w("counter_skip", 1500, 1515, "serial:imu", skip=3),
            _w("garbage", 1700, 1760, "serial:imu", length=40, every="20 ms"),
            _w("truncate", 1900, 1915, "serial:imu"),
            _w("silence", 2100, 2150, "serial:imu"),
            _w("baud_mismatch", 2300, 2320, "serial:imu", baud=230_400),
            _w("baud_mismatch", 2500, 2600, "serial:imu", baud=465_000),  # within UART tolerance: harmless
        ]
    )
    traffic = _imu_traffic()
    out, ev = _run_serial(WireFaultInjector(sched, seed=4), "imu", traffic, 20)
    k = {kind: _k(ev, sched, kind) for kind in WIRE_KINDS}
    baud_ids = [w.id for w in sched if w.kind == "baud_mismatch"]
    k_bad_baud = int(np.sum(ev["fault_id"] == baud_ids[0]))
    dec = ImuStreamDecoder(late_ns=3 * MS, stale=True)
    samples = [dec.feed(c.data, c.t_ns) for c in out.chunks()]
    dec.flush()
    samples = np.concatenate(samples)
    counts = dec.tally.as_dict()
    bad_baud_runs = sum(counts.pop(kind, 0) for kind in ("length", "format", "range"))
    expected_sync = k["garbage"]  # one per burst; the garbled window adds its own runs
    extra_sync = counts.pop("sync") - expected_sync
    extra_crc = counts.pop("crc") - k["corrupt_crc"]
    extra_trunc = counts.pop("truncated") - k["truncate"]
    assert min(extra_sync, extra_crc, extra_trunc) >= 0
    assert 1 <= extra_sync + extra_crc + extra_trunc + bad_baud_runs <= 2 * k_bad_baud  # the garbled bytes
    assert counts == {
        "skip": 1 + 1 + k["counter_skip"] + 1 + 1 + 1,  # drop, crc, skip, truncate, silence, baud
        "lost": k["drop"] + k["corrupt_crc"] + 3 * k["counter_skip"] + k["truncate"] + k["silence"] + k_bad_baud,
        "late": k["delay"],
        "duplicate": k["duplicate"],
        "stale": k["freeze"],
        "repeat": k["counter_stale"],
    }
    assert k["garbage"] == 3 and k["delay"] == 6
    clean = ImuStreamDecoder().feed(traffic.tobytes())
    i_on = (samples["t_ns"] >= 900 * MS) & (samples["t_ns"] < 950 * MS)
    c_on = (clean["t_ns"] >= 900 * MS) & (clean["t_ns"] < 950 * MS)
    np.testing.assert_allclose(samples["dvel"][i_on, 2], clean["dvel"][c_on, 2] + 0.02, atol=1e-8)
    i_on = (samples["t_ns"] >= 1000 * MS) & (samples["t_ns"] < 1050 * MS)
    c_on = (clean["t_ns"] >= 1000 * MS) & (clean["t_ns"] < 1050 * MS)
    np.testing.assert_allclose(samples["dtheta"][i_on, 0], clean["dtheta"][c_on, 0] * 2.0, atol=1e-9)


def _fixes(n):
    f = np.zeros(n, GNSS_FIX_DTYPE)
    f["t_ns"] = np.arange(n) * 200 * MS  # 5 Hz
    f["utc_ns"] = 1_748_736_000 * 10**9 + f["t_ns"]
    f["lat"], f["lon"], f["h"] = math.radians(34.2), math.radians(108.9), 380.0
    f["vel_n"] = (3.0, 4.0, 0.0)
    f["sigma_lat"], f["sigma_lon"], f["sigma_alt"] = 1.0, 1.0, 2.0
    f["sats"], f["hdop"], f["quality"] = 12, 0.9, 1
    return f


def _gnss_run(schedule_tables, seed=5):
    fixes = _fixes(20)  # 5 Hz; the sentences of epoch i leave at 200 i + 50 ms
    traffic = encode_epochs(fixes, at_ns=fixes["t_ns"] + 50 * MS)
    sched = parse_schedule(schedule_tables)
    out, ev = _run_serial(WireFaultInjector(sched, seed=seed), "gnss", traffic, 50)
    dec = NmeaStreamDecoder(epoch_utc_ns=int(fixes["utc_ns"][0]), late_ns=60 * MS)
    got = [dec.feed(c.data, c.t_ns) for c in out.chunks()]
    got.append(dec.flush())
    k = {kind: _k(ev, sched, kind) for kind in WIRE_KINDS}
    return fixes, np.concatenate(got), dec.tally.as_dict(), k


def test_nmea_decoder_counts_every_gnss_fault_kind():
    fixes, got, counts, k = _gnss_run(
        [
            _w("drop", 240, 260, "serial:gnss", probability=0.6),  # epoch 1
            _w("delay", 640, 660, "serial:gnss", delay="30 ms"),  # epoch 3
            _w("duplicate", 1040, 1060, "serial:gnss"),  # epoch 5: every sentence twice
            _w("garbage", 1150, 1360, "serial:gnss", length=30, every="200 ms"),  # bursts before epochs 6 and 7
            _w("truncate", 1640, 1660, "serial:gnss"),  # epoch 8: every sentence cut
            _w("bad_checksum", 2040, 2060, "serial:gnss"),  # epoch 10
            _w("silence", 2440, 2460, "serial:gnss"),  # epoch 12: nothing sent, nothing to count
        ]
    )
    assert 0 < k["drop"] < 5 and k["duplicate"] == 5 and k["garbage"] == 2 and k["truncate"] == 5
    assert counts == {
        "missing": k["drop"],  # the epoch's other sentences came; epochs cut or garbled whole are not seen
        "late": 1,  # epoch 3: 50 + 30 ms after its time, tolerance 60 ms
        "duplicate": k["duplicate"],
        "sync": k["garbage"],
        "truncated": k["truncate"],
        "checksum": k["bad_checksum"],
    }
    seen = set(got["t_ns"].tolist())
    lost = {8, 10, 12}
    assert seen == {int(t) for i, t in enumerate(fixes["t_ns"]) if i not in lost}


def test_nmea_baud_mismatch_garbles_the_epoch():
    fixes, got, counts, k = _gnss_run([_w("baud_mismatch", 1440, 1460, "serial:gnss", baud=57_600)])
    assert k["baud_mismatch"] == 5
    assert int(fixes["t_ns"][7]) not in set(got["t_ns"].tolist()) and len(got) == 19
    assert sum(counts.values()) >= 1 and "late" not in counts
    fixes, got, counts, k = _gnss_run([_w("baud_mismatch", 1440, 1460, "serial:gnss", baud=117_000)])  # +1.6 %
    assert len(got) == 20 and counts == {}


def test_freeze_holds_the_last_frame_before_the_window_whatever_the_batches():
    traffic = _imu_traffic(1_000 * MS)
    sched = parse_schedule([_w("freeze", 500, 520, "serial:imu")])
    clean = ImuStreamDecoder().feed(traffic.tobytes())
    before = clean[np.searchsorted(clean["t_ns"], 500 * MS) - 1]  # the frame at 495 ms
    for step in (5, 20, 100, 1000):  # the window starts on a batch boundary or inside one
        out, ev = _run_serial(WireFaultInjector(sched), "imu", traffic, step, 1_000 * MS)
        got = ImuStreamDecoder().feed(out.tobytes())
        on = (got["t_ns"] >= 500 * MS) & (got["t_ns"] < 520 * MS)
        assert on.sum() == 4 and len(ev) == 4
        np.testing.assert_array_equal(got["dtheta"][on], np.repeat(before["dtheta"][None], 4, axis=0))
        np.testing.assert_array_equal(got["t_ns"], clean["t_ns"])  # time and counter run on


def test_offset_on_every_message_acts_where_the_signal_is():
    traffic = _can_traffic(300 * MS)
    sched = parse_schedule([_w("offset", 100, 200, "can:*", signal="speed", value=-0.5)])
    out, ev = _run_can(WireFaultInjector(sched), traffic, 50, 300 * MS)
    assert set(ev["can_id"].tolist()) == {0x120, 0x130}  # ODOMETER and DOPPLER carry a speed, BENCH_TIME not
    got, ref = BenchTrafficDecoder().feed(out), BenchTrafficDecoder().feed(traffic)
    for name in ("ODOMETER", "DOPPLER"):
        on = (ref[name]["rx_ns"] >= 100 * MS) & (ref[name]["rx_ns"] < 200 * MS)
        np.testing.assert_allclose(got[name]["speed"][on], ref[name]["speed"][on] - 0.5, atol=0.006)
        np.testing.assert_array_equal(got[name]["speed"][~on], ref[name]["speed"][~on])
    np.testing.assert_array_equal(got["BENCH_TIME"]["time_ns"], ref["BENCH_TIME"]["time_ns"])
    with pytest.raises(ConfigError, match="signal must be one of"):
        WireFaultInjector(parse_schedule([_w("scale", 0, 10, "can:*", signal="altitude", factor=2.0)]))
