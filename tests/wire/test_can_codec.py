"""CAN codecs: round trips over the full ranges, cantools as the independent decoder, strictness."""

from __future__ import annotations

import math

import cantools
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import CodecError
from bench.frames import CanBatch
from bench.wire.bits import INT64_MAX_US
from bench.wire.can import CanEncoder, codec, codec_for_id
from bench.wire.dbc import dbc_path, load_specs

NAMES = sorted(load_specs())
DB = cantools.database.load_file(str(dbc_path()), strict=True)
_TO_SI = {"deg": math.pi / 180.0, "arcmin": math.pi / 180.0 / 60.0}


def _raw_strategy(name):
    c = codec(name)
    fields = [s.field for s in c.spec.signals if s is not c.crc_signal]
    return st.fixed_dictionaries({f.name: st.integers(f.raw_min, f.raw_max) for f in fields})


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=80, deadline=None)
@given(data=st.data())
def test_raw_round_trip_full_field_range(name, data):
    """Every field over its whole range, 64-bit times and negative values included; cantools agrees."""
    c = codec(name)
    raw = data.draw(_raw_strategy(name))
    payload = c.encode_raw({k: np.array([v], dtype=np.uint64 if v > 2**63 - 1 else np.int64) for k, v in raw.items()})
    back = c.decode_raw(payload)
    for k, v in raw.items():
        assert int(back[k][0]) == v, k
    ref = DB.decode_message(c.frame_id, payload[0].tobytes(), decode_choices=False, scaling=False)
    for k, v in raw.items():
        assert ref[k] == v, k
    assert ref[c.crc_signal.name] == int(back[c.crc_signal.name][0])


def _si_strategy(name):
    """SI values drawn as raw integers in the allowed range (so the round trip is exact)."""
    c = codec(name)
    out = {}
    for q in c.quantities:
        sigs = [c.spec.signal(s) for s in q.signals]
        if q.kind in ("time_us", "time_ms"):
            unit = 1000 if q.kind == "time_us" else 1_000_000
            hi = min(c.raw_bounds(sigs[0].name)[1], INT64_MAX_US if unit == 1000 else INT64_MAX_US // 1000)
            out[q.name] = st.integers(0, hi).map(lambda r, u=unit: r * u)
        elif q.kind == "int_wrap":
            out[q.name] = st.integers(0, 2**62)
        elif q.kind in ("int", "bits"):
            if q.kind == "bits":
                out[q.name] = st.integers(0, (1 << len(sigs)) - 1)
            else:
                out[q.name] = st.integers(*c.raw_bounds(sigs[0].name))
        else:
            parts = [
                st.integers(*c.raw_bounds(s.name)).map(lambda r, s=s: r * s.scale * _TO_SI.get(s.unit, 1.0))
                for s in sigs
            ]
            out[q.name] = st.tuples(*parts).map(list) if len(parts) > 1 else parts[0]
    return st.fixed_dictionaries(out)


def _close(c, q, got, want):
    sigs = [c.spec.signal(s) for s in q.signals]
    lsb = np.array([s.scale * _TO_SI.get(s.unit, 1.0) for s in sigs])
    if q.kind == "angle_wrap":
        d = (np.asarray(got) - np.asarray(want) + math.pi) % (2 * math.pi) - math.pi
        return np.all(np.abs(d) <= lsb * 0.5 + 1e-12)
    return np.all(np.abs(np.asarray(got) - np.asarray(want)) <= lsb * 0.5 * (1 + 1e-9))


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=80, deadline=None)
@given(data=st.data())
def test_si_round_trip(name, data):
    c = codec(name)
    values = data.draw(_si_strategy(name))
    payload = c.encode_one(**values)
    back = c.decode_one(payload, fd=c.fd)
    for q in c.quantities:
        if q.kind == "int_wrap":
            assert back[q.name] == values[q.name] % 65536
        elif q.kind in ("int", "bits", "time_us", "time_ms"):
            assert back[q.name] == values[q.name], q.name
        else:
            assert _close(c, q, back[q.name], values[q.name]), (q.name, back[q.name], values[q.name])
    # cantools reads the same physical values (in the DBC's units)
    ref = DB.decode_message(c.frame_id, payload, decode_choices=False)
    for q in c.quantities:
        if q.kind in ("float", "angle_wrap"):
            for i, sname in enumerate(q.signals):
                s = c.spec.signal(sname)
                want = back[q.name][i] if len(q.signals) > 1 else back[q.name]
                assert ref[sname] * _TO_SI.get(s.unit, 1.0) == pytest.approx(want, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("name", ["NAV_SOLUTION", "ODOMETER", "DOPPLER", "DRIVER_INPUT"])
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_arbitrary_floats_round_to_the_nearest_step(name, data):
    c = codec(name)
    values = data.draw(_si_strategy(name))
    for q in c.quantities:
        if q.kind == "float":
            sigs = [c.spec.signal(s) for s in q.signals]
            lsb = np.array([s.scale * _TO_SI.get(s.unit, 1.0) for s in sigs])
            jitter = data.draw(st.lists(st.floats(-0.49, 0.49), min_size=len(sigs), max_size=len(sigs)))
            v = np.asarray(values[q.name], float) + np.array(jitter) * lsb
            lo = np.array([c.raw_bounds(s.name)[0] * s.scale * _TO_SI.get(s.unit, 1.0) for s in sigs])
            hi = np.array([c.raw_bounds(s.name)[1] * s.scale * _TO_SI.get(s.unit, 1.0) for s in sigs])
            v = np.clip(v, lo, hi)
            values[q.name] = list(v) if len(sigs) > 1 else float(v[0])
    back = c.decode_one(c.encode_one(**values))
    for q in c.quantities:
        if q.kind == "float":
            assert _close(c, q, back[q.name], values[q.name]), q.name


def test_cantools_decodes_every_frame_the_bench_sends_to_the_values_meant():
    """A second of every bench message from the batch encoders, each frame through cantools."""
    rng = np.random.default_rng(7)
    enc = CanEncoder()
    t10 = np.arange(1, 101) * 10_000_000
    t20 = np.arange(1, 51) * 20_000_000
    meant = {
        "BENCH_TIME": (t10, {"time_ns": t10, "lockstep": rng.integers(0, 2, 100)}),
        "BENCH_EPOCH": (t10[:1], {"epoch_utc_ns": np.array([1_748_736_000_123_000_000])}),
        "BENCH_CMD": (t10[:3], {"command": np.array([1, 2, 3])}),
        "ODOMETER": (
            t10,
            {
                "pulse_count": np.cumsum(rng.integers(0, 900, 100)),
                "speed": rng.uniform(-30, 300, 100),
                "reverse": rng.integers(0, 2, 100),
                "valid": rng.integers(0, 2, 100),
            },
        ),
        "DRIVER_INPUT": (
            t20,
            {
                "left_lever": rng.integers(0, 3, 50),
                "right_lever": rng.integers(0, 3, 50),
                "steering": rng.uniform(-9, 9, 50),
                "brake": rng.integers(0, 2, 50),
            },
        ),
        "DOPPLER": (
            t20,
            {
                "speed": rng.uniform(-50, 200, 50),
                "quality": rng.integers(0, 256, 50),
                "valid": rng.integers(0, 2, 50),
                "low_signal": rng.integers(0, 2, 50),
            },
        ),
    }
    frames = CanBatch.concat([enc.encode(n, t, **v) for n, (t, v) in meant.items()]).sorted()
    seen = {n: 0 for n in meant}
    for f in frames.frames():
        c = codec_for_id(f.can_id)
        ref = DB.decode_message(f.can_id, f.data, decode_choices=False)
        _, values = meant[c.name]
        i = seen[c.name]
        seen[c.name] += 1
        assert ref["AliveCounter"] == i % 16
        for q in c.quantities:
            if q.name == "alive":
                continue
            s = c.spec.signal(q.signals[0])
            want = values[q.name][i]
            if q.kind == "time_us":
                assert ref[s.name] == want // 1000
            elif q.kind == "time_ms":
                assert ref[s.name] == want // 1_000_000
            elif q.kind == "int_wrap":
                assert ref[s.name] == want % 65536
            elif q.kind == "int":
                assert ref[s.name] == want
            else:
                assert ref[s.name] * _TO_SI.get(s.unit, 1.0) == pytest.approx(
                    want, abs=s.scale * 0.5 * _TO_SI.get(s.unit, 1.0) * (1 + 1e-9)
                )
        assert DB.get_message_by_frame_id(f.can_id).length == len(f.data)
    assert seen == {n: len(t) for n, (t, _) in meant.items()}


def test_nav_frames_decode_in_cantools_units():
    c = codec("NAV_SOLUTION")
    p = c.encode_one(
        t_ns=123_456_789_000,
        lat=math.radians(34.2460),
        lon=math.radians(-108.9),
        h=380.5,
        vel_n=[1.5, -2.25, 0.125],
        heading=math.radians(359.99999999),
        pitch=math.radians(-3.5),
        roll=math.radians(89.9),
        frame=1,
        mode=5,
        valid=1,
        epoch=255,
    )
    ref = DB.decode_message(0x300, p, decode_choices=False)
    assert ref["TimeOfValidity"] == 123_456_789
    assert ref["Latitude"] == pytest.approx(34.2460, abs=1e-7)
    assert ref["Longitude"] == pytest.approx(-108.9, abs=1e-7)
    assert ref["Heading"] == 0.0  # 359.99999999 deg rounds to 360 and wraps
    assert (ref["VelEast"], ref["VelNorth"], ref["VelUp"]) == (1.5, -2.25, 0.125)
    assert (ref["NavFrame"], ref["Mode"], ref["SolutionValid"], ref["EpochCounter"]) == (1, 5, 1, 255)
    q = codec("NAV_QUALITY")
    p = q.encode_one(
        t_ns=5_000,
        sigma_pos=[1, 2, 3],
        sigma_vel=[0.1, 0.2, 0.3],
        sigma_att=[math.radians(1 / 60), 0, math.radians(0.5 / 60)],
        fault_detected=0b1010,
        excluded=0b0001,
        odo_fault_class=3,
        epoch=9,
    )
    ref = DB.decode_message(0x301, p, decode_choices=False)
    assert ref["SigmaHeading"] == pytest.approx(1.0) and ref["SigmaRoll"] == pytest.approx(0.5)
    assert (ref["FaultOdometer"], ref["FaultDoppler"], ref["FaultBds"], ref["FaultImu"]) == (0, 1, 0, 1)
    assert (ref["ExcludedOdometer"], ref["OdoFaultClass"], ref["EpochCounter"]) == (1, 3, 9)


def test_times_round_half_up_to_the_microsecond():
    c = codec("BENCH_TIME")
    for t_ns, us in [(1499, 1), (1500, 2), (999_999_500, 1_000_000), (0, 0), (499, 0)]:
        assert DB.decode_message(0x10, c.encode_one(time_ns=t_ns, lockstep=0, alive=0))["BenchTime"] == us


def test_range_errors_name_the_field():
    odo = codec("ODOMETER")
    with pytest.raises(CodecError, match=r"ODOMETER\.Speed \(speed\): 400 m/s outside \[-327\.68, 327\.67\]") as e:
        odo.encode_one(pulse_count=1, speed=400.0, reverse=0, valid=1, alive=0)
    assert e.value.kind == "range"
    with pytest.raises(CodecError, match=r"ODOMETER\.Speed.*not finite"):
        odo.encode_one(pulse_count=1, speed=float("nan"), reverse=0, valid=1, alive=0)
    with pytest.raises(CodecError, match=r"ODOMETER\.AliveCounter \(alive\): 16 outside \[0, 15\]"):
        odo.encode_one(pulse_count=1, speed=1.0, reverse=0, valid=1, alive=16)
    with pytest.raises(CodecError, match=r"DRIVER_INPUT\.LeftLever \(left_lever\): 3 outside \[0, 2\]"):
        codec("DRIVER_INPUT").encode_one(left_lever=3, right_lever=0, steering=0.0, brake=0, alive=0)
    with pytest.raises(CodecError, match=r"NAV_SOLUTION\.Latitude \(lat\)"):
        codec("NAV_SOLUTION").encode_one(
            t_ns=0,
            lat=1.6,
            lon=0.0,
            h=0.0,
            vel_n=[0, 0, 0],
            heading=0.0,
            pitch=0.0,
            roll=0.0,
            frame=0,
            mode=0,
            valid=0,
            epoch=0,
        )
    with pytest.raises(CodecError, match=r"BENCH_TIME\.BenchTime \(time_ns\)"):
        codec("BENCH_TIME").encode_one(time_ns=-1000, lockstep=0, alive=0)
    with pytest.raises(CodecError, match=r"BENCH_TIME\.BenchTime \(time_ns\)"):
        codec("BENCH_TIME").encode_one(time_ns=2**48 * 1000, lockstep=0, alive=0)
    with pytest.raises(CodecError, match=r"BENCH_CMD\.Command \(command\): 0 outside \[1, 3\]"):
        codec("BENCH_CMD").encode_one(command=0, alive=0)
    with pytest.raises(CodecError, match=r"missing low_signal"):
        codec("DOPPLER").encode_one(speed=1.0, quality=0, valid=1, alive=0)


def _fixed_crc(c, data: bytearray) -> bytes:
    row = np.frombuffer(bytes(data), np.uint8)[None].copy()
    c.refresh_crc(row)
    return row[0].tobytes()


def test_strict_decoding_kinds():
    odo = codec("ODOMETER")
    good = odo.encode_one(pulse_count=7, speed=3.21, reverse=0, valid=1, alive=5)
    assert odo.decode_one(good, expect_counter=5)["speed"] == pytest.approx(3.21)
    cases = []
    flipped = bytearray(good)
    flipped[2] ^= 0x01
    cases.append((bytes(flipped), "crc"))
    reserved = bytearray(good)
    reserved[5] = 0x01  # byte 5 is zero in the ICD
    cases.append((_fixed_crc(odo, reserved), "format"))
    nibble = bytearray(good)
    nibble[6] |= 0x80  # high nibble of the alive byte must be zero
    cases.append((_fixed_crc(odo, nibble), "format"))
    cases.append((good[:7], "length"))
    for data, kind in cases:
        with pytest.raises(CodecError) as e:
            odo.decode_one(data)
        assert e.value.kind == kind, data
    with pytest.raises(CodecError) as e:
        odo.decode_one(good, expect_counter=6)
    assert e.value.kind == "counter"
    with pytest.raises(CodecError) as e:
        odo.decode_one(good, fd=True)
    assert e.value.kind == "length"
    drv = codec("DRIVER_INPUT")
    lever = bytearray(drv.encode_one(left_lever=2, right_lever=1, steering=0.1, brake=1, alive=0))
    lever[0] = 3
    with pytest.raises(CodecError) as e:
        drv.decode_one(_fixed_crc(drv, lever))
    assert e.value.kind == "range"
    assert codec_for_id(0x555) is None


def test_batch_status_counts_each_kind():
    odo = codec("ODOMETER")
    enc = CanEncoder()
    b = enc.encode("ODOMETER", np.arange(6) * 10_000_000, pulse_count=np.arange(6), speed=1.0, reverse=0, valid=1)
    b.data[1, 7] ^= 0xFF  # crc
    b.data[2, 5] = 1  # reserved
    odo.refresh_crc(b.data[2:3])
    b.length[3] = 6  # dlc
    b.fd[4] = True  # FD flag on a classic message
    values, status = odo.decode(b)
    assert [("ok", "crc", "format", "length", "length", "ok")[i] for i in range(6)] == [
        ("ok", "length", "crc", "format", "range")[s] for s in status
    ]
    assert values["pulse_count"][5] == 5


def test_pulse_count_rolls_over_and_heading_wraps():
    odo = codec("ODOMETER")
    assert (
        odo.decode_one(odo.encode_one(pulse_count=65536 + 12, speed=0.0, reverse=1, valid=1, alive=0))["pulse_count"]
        == 12
    )
    nav = codec("NAV_SOLUTION")
    base = dict(
        t_ns=0, lat=0.0, lon=0.0, h=0.0, vel_n=[0, 0, 0], pitch=0.0, roll=0.0, frame=0, mode=0, valid=1, epoch=0
    )
    for heading in (-0.5, 2 * math.pi + 0.25, 7 * math.pi):
        got = nav.decode_one(nav.encode_one(heading=heading, **base))["heading"]
        assert 0.0 <= got < 2 * math.pi
        assert got == pytest.approx(heading % (2 * math.pi), abs=1e-9)
