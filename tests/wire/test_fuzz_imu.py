"""The IMU frame stream decoder under hostile input: it follows the resynchronisation rule
of docs/wire.md (checked against a plain reference implementation of the rule), accounts
for every byte, survives any garbage, and gives the same frames, events and stamps
however the bytes are split into reads."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from bench.frames import SerialBatch
from bench.wire import imu
from bench.wire.bits import INT64_MAX_US
from bench.wire.imu_stream import RUN_KINDS, ImuStreamDecoder

N = 40
_rng = np.random.default_rng(7)
FRAMES = imu.encode_frames(
    (np.arange(N) + 1) * 5_000_000, _rng.normal(0, 1e-4, (N, 3)), _rng.normal(0, 1e-2, (N, 3)), 0x3F, 30.0, np.arange(N)
)
FB = [f.tobytes() for f in FRAMES]
TAIL = imu.encode_frames(
    (np.arange(8) + 1000) * 5_000_000, np.full((8, 3), 1e-5), np.full((8, 3), 1e-3), 0x3F, 25.0, np.arange(8) + 100
).tobytes()


def _with_crc(frame: bytearray) -> bytes:
    rows = np.frombuffer(bytes(frame), np.uint8).reshape(1, 42).copy()
    return imu.refresh_crc(rows)[0].tobytes()


def _field_fault(args) -> bytes:
    """A frame whose CRC holds but a field does not: reserved status bits, or a time past int64 ns."""
    i, which = args
    f = bytearray(FB[i])
    if which:
        f[37] = 0x80
    else:
        f[4:12] = (INT64_MAX_US + 1).to_bytes(8, "little")
    return _with_crc(f)


def _flip(args) -> bytes:
    i, pos, bit = args
    f = bytearray(FB[i])
    f[pos] ^= 1 << bit
    return bytes(f)


PIECE = st.one_of(
    st.integers(0, N - 1).map(lambda i: FB[i]),
    st.lists(st.sampled_from([0xAA, 0x55, 0x24, 0x00, 0xFF, 0x13]), max_size=12).map(bytes),
    st.binary(max_size=50),
    st.tuples(st.integers(0, N - 1), st.integers(1, 41)).map(lambda a: FB[a[0]][: a[1]]),  # a cut frame
    st.tuples(st.integers(0, N - 1), st.integers(0, 41), st.integers(0, 7)).map(_flip),
    st.tuples(st.integers(0, N - 1), st.booleans()).map(_field_fault),
    st.binary(max_size=5).map(lambda b: b"\xaa\x55" + b),  # a false start
)
STREAM = st.lists(PIECE, max_size=20).map(b"".join)
CUTS = st.lists(st.integers(1, 97), min_size=1, max_size=40)


def _reference(data: bytes) -> tuple[list[int], list[tuple[str, bytes]]]:
    """The rule of docs/wire.md written plainly: accepted frame starts and (kind, run) of each bad run."""
    n = len(data)
    syncs = [p for p in range(n - 1) if data[p] == 0xAA and data[p + 1] == 0x55]

    def good(p):
        return p + 42 <= n and imu.check_frames(np.frombuffer(data[p : p + 42], np.uint8)[None])[0] == 0

    frames, pos = [], 0
    for p in syncs:
        if p >= pos and good(p):
            frames.append(p)
            pos = p + 42
    runs, prev = [], 0
    for end in [*frames, n]:
        cuts = [p for p in syncs if prev < p < end]
        for a, b in zip([prev, *cuts], [*cuts, end], strict=True):
            if b > a:
                run = data[a:b]
                if run[:2] != b"\xaa\x55":
                    kind = "sync"
                elif len(run) >= 3 and run[2] != 36:
                    kind = "length"
                elif len(run) < 42:
                    kind = "truncated"
                else:
                    k = imu.IMU_KINDS[int(imu.check_frames(np.frombuffer(run[:42], np.uint8)[None])[0])]
                    kind = k if k in ("format", "range") else "crc"
                runs.append((kind, run[:256]))
        prev = end + 42
    return frames, runs


def _pieces(data: bytes, cuts: list[int] | None) -> list[bytes]:
    out, pos, k = [], 0, 0
    while pos < len(data):
        step = len(data) if cuts is None else cuts[k % len(cuts)]
        out.append(data[pos : pos + step])
        pos, k = pos + step, k + 1
    return out


def _feed(reads: list[tuple[bytes, int]], batch: bool = False):
    dec = ImuStreamDecoder()
    if batch:
        offsets = np.cumsum([0] + [len(d) for d, _ in reads])
        out = [dec.feed_batch(SerialBatch([t for _, t in reads], offsets, b"".join(d for d, _ in reads)))]
    else:
        out = [dec.feed(d, t) for d, t in reads]
    dec.flush(10**12)
    return dec, np.concatenate([np.zeros(0, imu.IMU_SAMPLE_DTYPE), *out])


def _runs(dec: ImuStreamDecoder) -> list[tuple]:
    return [(b.kind, b.data, b.t_ns) for b in dec.tally.bad if b.kind in RUN_KINDS]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(STREAM, CUTS)
def test_the_decoder_follows_the_rule_and_accounts_for_every_byte(data, cuts):
    frames, runs = _reference(data)
    dec, got = _feed([(p, 0) for p in _pieces(data, cuts)])
    rows = [data[p : p + 42] for p in frames]
    handed_on = [r for i, r in enumerate(rows) if i == 0 or r != rows[i - 1]]  # exact repeats are duplicates
    assert dec.frames == len(frames) and dec.tally["duplicate"] == len(rows) - len(handed_on)
    assert [got[i].tobytes() for i in range(len(got))] == [imu.decode_one(r).tobytes() for r in handed_on]
    assert [(k, d) for k, d, _ in _runs(dec)] == runs
    assert sum(dec.tally[k] for k in RUN_KINDS) == len(runs)
    assert dec.bytes_in == len(data) == 42 * dec.frames + dec.bytes_bad


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(STREAM, CUTS, st.integers(1, 5))
def test_the_split_into_reads_changes_nothing(data, cuts, sub):
    """Reads arriving at their own times, decoded at once (one batch), read by read, each
    read cut further, and byte by byte: the same samples (arrival stamps included), the
    same counts, the same bad runs with the same stamps."""
    reads = [(p, 1000 * (k + 1)) for k, p in enumerate(_pieces(data, cuts))]
    ref, ref_s = _feed(reads, batch=True)
    finer = [(d[a : a + sub], t) for d, t in reads for a in range(0, len(d), sub)]
    bytewise = [(d[a : a + 1], t) for d, t in reads for a in range(len(d))]
    for variant in (reads, finer, bytewise):
        for batch in (False, True):
            dec, got = _feed(variant, batch)
            assert got.tobytes() == ref_s.tobytes()
            assert dec.tally.as_dict() == ref.tally.as_dict()
            assert _runs(dec) == _runs(ref)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(STREAM, CUTS)
def test_after_any_garbage_valid_frames_decode_exactly(data, cuts):
    frames, _ = _reference(data + TAIL)
    tail_at = len(data) + 42 * np.arange(8)
    # the documented ambiguity: a cut frame whose missing bytes equal the next ones is whole
    assume(set(tail_at.tolist()) <= set(frames))
    _, fresh = _feed([(TAIL, 5)])
    _, got = _feed([(p, 5) for p in _pieces(data + TAIL, cuts)])
    assert got[-8:].tobytes() == fresh.tobytes()


# ---------------------------------------------------------------------------- the split-dependent inputs
@pytest.mark.parametrize(
    ("data", "counts"),
    [
        (FB[1][:41] + FB[2], {"truncated": 1}),  # byte by byte: crc before (the 42nd byte was the next sync)
        (FB[0][:24] + FB[1][:41] + FB[2], {"truncated": 2}),
        (FB[0] + FB[1][:41] + FB[2], {"truncated": 1, "skip": 1, "lost": 1}),
        (FB[1][:41] + b"\xaa\x55\x30" + FB[2], {"truncated": 1, "length": 1}),
        (FB[1][:41] + b"\xaa" + FB[2], {"crc": 1}),  # 42 bytes: a whole frame with a bad CRC
    ],
)
def test_a_run_cut_by_a_sync_at_its_42nd_byte_is_truncated_whatever_the_reads(data, counts):
    assert FB[1][41] != 0xAA
    for cuts in (None, [1], [2], [7], [41], [42], [43]):
        dec, got = _feed([(p, 0) for p in _pieces(data, cuts)])
        assert dec.tally.as_dict() == counts, cuts
        assert got["counter"].tolist()[-1] == 2


def test_the_known_ambiguity_is_classified_the_same_way_for_every_split():
    """A frame cut by its last byte, followed by a frame whose sync byte equals that byte:
    the bytes are an intact frame, accepted; the next frame loses its sync and is a run."""
    rows = imu.encode_frames(np.arange(1, 400) * 5_000_000, np.zeros((399, 3)), np.zeros((399, 3)), 0x3F, 20.0, 0)
    k = next(i for i in range(399) if rows[i, 41] == 0xAA)
    data = rows[k, :41].tobytes() + FB[3] + FB[4]
    outcomes = set()
    for cuts in (None, [1], [2], [41], [42], [5, 37]):
        dec, got = _feed([(p, 0) for p in _pieces(data, cuts)])
        outcomes.add((tuple(got["t_ns"].tolist()), tuple(sorted(dec.tally.as_dict().items()))))
    assert len(outcomes) == 1
    (t, counts), = outcomes
    assert t[0] == int(rows[k].view(imu.FRAME_DTYPE)["time_us"][0]) * 1000 and dict(counts)["sync"] == 1
