"""IMU serial frame: round trips over full ranges, strict errors, resynchronisation on garbage."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from bench.errors import CodecError
from bench.wire import imu
from bench.wire.bits import INT64_MAX_US
from bench.wire.crc import crc16_ccitt_false
from bench.wire.imu_stream import ImuStreamDecoder

I32 = st.integers(-(2**31), 2**31 - 1)
SAMPLE = st.fixed_dictionaries(
    {
        "t_us": st.integers(0, INT64_MAX_US),
        "dtheta": st.tuples(I32, I32, I32),
        "dvel": st.tuples(I32, I32, I32),
        "status": st.integers(0, 255),
        "temperature": st.integers(-(2**15), 2**15 - 1),
        "counter": st.integers(0, 255),
    }
)


def _frames(samples):
    return imu.encode_frames(
        np.array([s["t_us"] * 1000 for s in samples], np.int64),
        np.array([s["dtheta"] for s in samples]) * imu.DTHETA_LSB,
        np.array([s["dvel"] for s in samples]) * imu.DVEL_LSB,
        [s["status"] for s in samples],
        np.array([s["temperature"] for s in samples]) * imu.TEMP_LSB,
        [s["counter"] for s in samples],
    )


@settings(max_examples=200, deadline=None)
@given(st.lists(SAMPLE, min_size=1, max_size=20))
def test_round_trip_full_ranges(samples):
    frames = _frames(samples)
    assert frames.shape == (len(samples), 42)
    out, status = imu.decode_frames(frames)
    assert not status.any()
    rec = frames.view(imu.FRAME_DTYPE).reshape(-1)
    for i, s in enumerate(samples):
        assert int(rec["time_us"][i]) == s["t_us"]
        assert out["t_ns"][i] == s["t_us"] * 1000
        assert tuple(rec["dtheta"][i]) == s["dtheta"] and tuple(rec["dvel"][i]) == s["dvel"]
        assert int(rec["temperature"][i]) == s["temperature"]
        assert (out["status"][i], out["counter"][i]) == (s["status"], s["counter"])
        np.testing.assert_allclose(out["dtheta"][i], np.array(s["dtheta"]) * imu.DTHETA_LSB, rtol=1e-15)
        one = imu.decode_one(frames[i].tobytes())
        assert one["t_ns"] == s["t_us"] * 1000
        # independent layout check: bytes by hand
        f = frames[i].tobytes()
        assert f[:3] == b"\xaa\x55\x24" and f[3] == s["counter"]
        assert int.from_bytes(f[4:12], "little") == s["t_us"]
        assert int.from_bytes(f[12:16], "little", signed=True) == s["dtheta"][0]
        assert int.from_bytes(f[32:36], "little", signed=True) == s["dvel"][2]
        assert int.from_bytes(f[38:40], "little", signed=True) == s["temperature"]
        assert int.from_bytes(f[40:42], "little") == crc16_ccitt_false(f[2:40])


def test_encode_range_errors():
    ok = dict(t_ns=1000, dtheta=[0.0, 0, 0], dvel=[0.0, 0, 0], status=0x3F, temperature=20.0, counter=0)
    imu.encode_one(**ok)
    for key, bad, match in [
        ("dtheta", [2.2, 0, 0], "dtheta"),
        ("dvel", [0, -21.5, 0], "dvel"),
        ("temperature", 400.0, "temperature"),
        ("status", 256, "status"),
        ("counter", -1, "counter"),
        ("t_ns", -1000, "before bench time zero"),
        ("dtheta", [float("nan"), 0, 0], "not finite"),
    ]:
        with pytest.raises(CodecError, match=match) as e:
            imu.encode_one(**{**ok, key: bad})
        assert e.value.kind == "range"


def _with_crc(frame: bytearray) -> bytes:
    frame[40:42] = crc16_ccitt_false(bytes(frame[2:40])).to_bytes(2, "little")
    return bytes(frame)


def test_strict_decoding_kinds():
    good = bytearray(imu.encode_one(5_000_000, [1e-6, 2e-6, 3e-6], [1e-3, 0, -1e-3], 0x3F, 21.5, 9))
    assert imu.decode_one(bytes(good))["counter"] == 9
    cases = [(bytes(good[:41]), "length")]
    b = bytearray(good)
    b[0] = 0xAB
    cases.append((bytes(b), "sync"))
    b = bytearray(good)
    b[2] = 35
    cases.append((_with_crc(b), "length"))
    b = bytearray(good)
    b[20] ^= 4
    cases.append((bytes(b), "crc"))
    b = bytearray(good)
    b[37] = 1  # status bits 8..15 are reserved
    cases.append((_with_crc(b), "format"))
    b = bytearray(good)
    b[4:12] = (INT64_MAX_US + 1).to_bytes(8, "little")
    cases.append((_with_crc(b), "range"))
    for data, kind in cases:
        with pytest.raises(CodecError) as e:
            imu.decode_one(data)
        assert e.value.kind == kind


def _stream(n, seed=0):
    rng = np.random.default_rng(seed)
    t = (np.arange(n) + 1) * 5_000_000
    return imu.encode_frames(
        t, rng.normal(0, 1e-4, (n, 3)), rng.normal(0, 1e-2, (n, 3)), 0x3F, 30.0, np.arange(n) % 256
    )


JUNK = st.one_of(
    st.binary(min_size=0, max_size=90),  # garbage, sync bytes included
    st.tuples(st.integers(0, 39), st.integers(1, 41)).map(lambda a: ("cut", *a)),  # a truncated frame
    st.binary(min_size=1, max_size=6).map(lambda b: b"\xaa\x55" + b),  # a false start
)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(JUNK, min_size=40, max_size=40), st.lists(st.integers(1, 97), min_size=1, max_size=200))
def test_resynchronises_without_losing_any_intact_frame(junk, cuts):
    """Random garbage, false starts and truncated frames between 40 intact frames, read in
    random pieces: every intact frame comes out, in order, and nothing else."""
    frames = _stream(40, seed=len(cuts))
    parts = []
    for i in range(40):
        j = junk[i]
        if isinstance(j, tuple):
            whole = frames[j[1]].tobytes()
            j = whole[: j[2]]
            # a cut frame whose missing tail equals the head of the frame after it (its CRC's
            # last byte is 0xAA, the next sync byte) is byte for byte an intact frame: any
            # receiver takes it, and the frame after it is then lost; not a resync failure
            assume(j + frames[i].tobytes()[: len(whole) - len(j)] != whole)
        parts += [j, frames[i].tobytes()]
    data = b"".join(parts)
    dec = ImuStreamDecoder()
    got = []
    pos, k = 0, 0
    while pos < len(data):
        step = cuts[k % len(cuts)]
        got.append(dec.feed(data[pos : pos + step], rx_ns=pos))
        pos += step
        k += 1
    dec.flush()
    out = np.concatenate(got)
    assert out["counter"].tolist() == list(range(40))
    np.testing.assert_array_equal(out["t_ns"], (np.arange(40) + 1) * 5_000_000)
    bad_runs = sum(dec.tally[k] for k in ("sync", "length", "truncated", "crc", "format", "range"))
    assert bad_runs >= sum(1 for p in parts[0::2] if p)


def test_each_bad_run_is_one_event_of_its_kind():
    frames = _stream(12)
    rng = np.random.default_rng(3)
    noise = rng.integers(0, 255, 25).astype(np.uint8)
    noise[noise >= 0xAA] += 1  # no 0xAA: plain line noise
    corrupt = frames[6].copy()
    corrupt[41] ^= 0x5A
    wrong_len = bytearray(frames[8].tobytes())
    wrong_len[2] = 30
    data = b"".join(
        [
            frames[0].tobytes(),
            noise.tobytes(),
            frames[1].tobytes(),  # 1 sync
            frames[2].tobytes()[:20],
            frames[3].tobytes(),  # 1 truncated
            frames[4].tobytes()[:3],
            frames[5].tobytes()[:30],
            frames[5].tobytes(),  # 2 truncated
            corrupt.tobytes(),
            frames[7].tobytes(),  # 1 crc (frame 6 lost)
            bytes(wrong_len),
            frames[9].tobytes(),  # 1 length (frame 8 lost)
            frames[10].tobytes(),
            frames[10].tobytes(),
            frames[11].tobytes(),  # 1 duplicate
        ]
    )
    for step in (1, 2, 13, 41, 42, 43, len(data)):  # the counts do not depend on how the bytes arrive
        dec = ImuStreamDecoder()
        for k in range(0, len(data), step):
            dec.feed(data[k : k + step])
        dec.flush()
        assert dec.tally.as_dict() == {
            "sync": 1,
            "truncated": 3,
            "crc": 1,
            "length": 1,
            "duplicate": 1,
            "skip": 4,
            "lost": 4,
        }, step
        kept = {b.kind for b in dec.tally.bad}
        assert kept == {"sync", "truncated", "crc", "length", "duplicate", "skip"}
        noise_kept = [b.data for b in dec.tally.bad if b.kind == "sync"]
        assert b"".join(noise_kept) == noise.tobytes()


def test_sequence_labels_and_late_frames():
    frames = _stream(10)
    stale = frames[4].copy()
    stale[12:40] = frames[3][12:40]
    imu.refresh_crc(stale[None])
    repeat = frames[6].copy()
    imu.set_counters(repeat[None], [5])
    late = frames[8].copy()
    seq = [frames[0], frames[1], frames[3], stale, frames[5], repeat, frames[7], late, frames[9]]
    dec = ImuStreamDecoder(late_ns=2_000_000, stale=True)
    rx = [int(f.view(imu.FRAME_DTYPE)["time_us"][0]) * 1000 + 1000 for f in seq]
    rx[7] += 5_000_000
    for f, r in zip(seq, rx, strict=True):
        dec.feed(f.tobytes(), r)
    # 1 -> 3 skips one; frame 6 repeats counter 5, so 7 follows 5: a second skip (E2E semantics)
    assert dec.tally.as_dict() == {"skip": 2, "lost": 2, "stale": 1, "repeat": 1, "late": 1}


def test_a_stream_split_anywhere_decodes_the_same():
    frames = _stream(30).tobytes()
    whole = ImuStreamDecoder().feed(frames)
    for size in (1, 2, 41, 43, 100):
        dec = ImuStreamDecoder()
        parts = [dec.feed(frames[k : k + size]) for k in range(0, len(frames), size)]
        np.testing.assert_array_equal(np.concatenate(parts)["t_ns"], whole["t_ns"])
        assert dec.tally.as_dict() == {}
