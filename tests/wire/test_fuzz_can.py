"""The CAN decoders under hostile input (arbitrary identifiers, DLCs 0..64, any bytes, FD
or not, valid frames with fields out of range): every frame decodes or is counted by
kind, never another exception; the receivers' state survives; batches cut anywhere give
the same output, counts and kept frames."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.errors import CodecError
from bench.frames import CanBatch, CanFrame
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from bench.wire.can import CanEncoder, codec, codec_for_id
from bench.wire.receive import BENCH_MESSAGES, DUT_OUTPUT_MESSAGES, BenchTrafficDecoder, NavReceiver

REJECTED = ("unknown_id", "length", "crc", "format", "range")
_rng = np.random.default_rng(11)


def _pool(name: str, n: int = 4) -> list[CanFrame]:
    """Frames of ``name`` with random raw values of every signal (some out of the DBC range)."""
    c = codec(name)
    raw = {}
    for s in c.spec.signals:
        if s is c.crc_signal:
            continue
        lo, hi = s.field.raw_min, s.field.raw_max
        if _rng.random() < 0.7:
            lo, hi = c.raw_bounds(s.name)
        raw[s.name] = np.array([int(lo + _rng.random() * (hi - lo)) for _ in range(n)], s.field.raw_dtype)
    data = c.encode_raw(raw, n)
    return [CanFrame(0, c.frame_id, data[i].tobytes(), c.fd) for i in range(n)]


POOL = [f for name in (*BENCH_MESSAGES, *DUT_OUTPUT_MESSAGES) for f in _pool(name)]


def _mutate(args) -> CanFrame:
    f, op, pos, value, refresh = args
    data = bytearray(f.data)
    if op == "byte":
        data[pos % len(data)] = value
        if refresh:
            c = codec_for_id(f.can_id)
            data = bytearray(c.refresh_crc(np.frombuffer(bytes(data), np.uint8)[None].copy())[0].tobytes())
    elif op == "dlc":
        data = (data + bytes(64))[: pos % 65]
    elif op == "id":
        return CanFrame(0, value * 0x20_0000 + pos * 7 if refresh else value * 8 + pos % 8, bytes(data), f.fd)
    elif op == "fd":
        return CanFrame(0, f.can_id, bytes(data), not f.fd)
    return CanFrame(0, f.can_id, bytes(data), f.fd)


FRAME = st.one_of(
    st.sampled_from(POOL),
    st.tuples(
        st.sampled_from(POOL),
        st.sampled_from(["byte", "dlc", "id", "fd"]),
        st.integers(0, 200),
        st.integers(0, 255),
        st.booleans(),
    ).map(_mutate),
    st.tuples(st.integers(0, 0x1FFFFFFF), st.binary(max_size=64), st.booleans()).map(
        lambda a: CanFrame(0, a[0], a[1], a[2])
    ),
)
FRAMES = st.lists(FRAME, max_size=60)


def _batch(frames: list[CanFrame]) -> CanBatch:
    frames = [CanFrame(1000 * (i + 1), f.can_id, f.data, f.fd) for i, f in enumerate(frames)]
    return CanBatch.from_frames(frames) if frames else CanBatch.empty(64)


def _run(receiver, batch: CanBatch, cuts: list[int] | None):
    """Feed ``batch`` in sub-batches of the sizes ``cuts`` (cycled; None: at once)."""
    outs, pos, k = [], 0, 0
    while pos < len(batch):
        step = len(batch) if cuts is None else cuts[k % len(cuts)]
        outs.append(receiver.feed(batch.take(np.arange(pos, min(pos + step, len(batch))))))
        pos, k = pos + step, k + 1
    return outs


def _nav(outs) -> tuple:
    return tuple(
        np.concatenate([np.zeros(0, dt), *[getattr(o, name) for o in outs]]).tobytes()
        for name, dt in (("solutions", NAV_SOLUTION_DTYPE), ("qualities", NAV_QUALITY_DTYPE), ("ready_ns", np.int64))
    )


def _bench(outs) -> dict:
    cols: dict[str, list] = {}
    for o in outs:
        for name, values in o.items():
            for k, v in values.items():
                cols.setdefault(f"{name}.{k}", []).append(np.asarray(v))
    return {k: np.concatenate(v).tobytes() for k, v in cols.items()}


def _kept(receiver) -> list[tuple]:
    return sorted((b.stream, b.kind, b.t_ns, b.data) for b in receiver.tally.bad)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(FRAMES)
def test_every_frame_decodes_or_is_counted(frames):
    batch = _batch(frames)
    nav = NavReceiver()
    out = nav.feed(batch)
    handed_on = out.solutions.size + out.qualities.size + out.ready_ns.size
    assert len(batch) == handed_on + nav.tally["duplicate"] + sum(nav.tally[k] for k in REJECTED)
    dut = BenchTrafficDecoder()
    got = dut.feed(batch)
    handed_on = sum(len(v["rx_ns"]) for v in got.values())
    assert len(batch) == handed_on + dut.tally["duplicate"] + sum(dut.tally[k] for k in REJECTED)
    for f in frames:  # one frame at a time: values, or CodecError with a kind
        c = codec_for_id(f.can_id)
        if c is None:
            continue
        try:
            c.decode_one(f.data, fd=f.fd, expect_counter=3)
        except CodecError as exc:
            assert exc.kind in (*REJECTED, "counter")


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(FRAMES, st.lists(st.integers(1, 9), min_size=1, max_size=20))
def test_batches_cut_anywhere_give_the_same(frames, cuts):
    batch = _batch(frames)
    for kind, pack in ((NavReceiver, _nav), (BenchTrafficDecoder, _bench)):
        whole = kind()
        ref = pack(_run(whole, batch, None))
        for split in (cuts, [1]):
            r = kind()
            assert pack(_run(r, batch, split)) == ref
            assert r.tally.as_dict() == whole.tally.as_dict()
            assert _kept(r) == _kept(whole)


def _clean() -> CanBatch:
    n = 20
    t = (np.arange(n) + 500) * 10_000_000
    sol = np.zeros(n, NAV_SOLUTION_DTYPE)
    sol["t_ns"], sol["rx_ns"], sol["epoch"], sol["lat"], sol["heading"] = t, t, np.arange(n) + 17, 0.6, 1.0
    q = np.zeros(n, NAV_QUALITY_DTYPE)
    q["t_ns"], q["rx_ns"], q["epoch"], q["sigma_pos"] = t, t, np.arange(n) + 17, 0.5
    enc = CanEncoder()
    parts = [
        enc.encode_records("NAV_SOLUTION", sol),
        enc.encode_records("NAV_QUALITY", q),
        enc.encode("DUT_READY", t, time_ns=t),
        enc.encode("ODOMETER", t, pulse_count=np.arange(n) + 9000, speed=3.25, reverse=0, valid=1),
        enc.encode("BENCH_TIME", t, time_ns=t, lockstep=1),
    ]
    b = CanBatch.concat(parts)
    return b.take(np.argsort(b.t_ns, kind="stable"))


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(FRAMES)
def test_after_any_garbage_clean_traffic_decodes_exactly(frames):
    clean = _clean()
    garbage = _batch(frames)
    ref_nav, ref_dut = NavReceiver().feed(clean), BenchTrafficDecoder().feed(clean)
    nav, dut = NavReceiver(), BenchTrafficDecoder()
    nav.feed(garbage)
    dut.feed(garbage)
    got = nav.feed(clean)
    for name in ("solutions", "qualities", "ready_ns"):
        assert getattr(got, name).tobytes() == getattr(ref_nav, name).tobytes()
    got = dut.feed(clean)
    for name, values in ref_dut.items():
        for k, v in values.items():
            np.testing.assert_array_equal(got[name][k], v)


def test_a_quality_before_its_solution_pairs_however_the_frames_are_batched():
    """Pairing is by time of validity and epoch, whichever frame comes first, and the cut
    into batches never changes it; a quality whose solution never comes is counted at the
    end. (Before, a quality pairing only with a solution received before it, among the
    last 1024, made a DUT that sends a burst of solutions before their qualities fail.)"""
    clean = _clean()
    sol, qual = np.flatnonzero(clean.can_id == 0x300)[:4], np.flatnonzero(clean.can_id == 0x301)[:4]
    order = np.array([sol[0], qual[0], qual[1], sol[1], sol[2], qual[2], qual[3]])  # epoch 1's quality comes early
    batch = clean.take(order)  # epoch 3's solution never comes
    for cuts in (None, [1], [2], [3]):
        rx = NavReceiver()
        _run(rx, batch, cuts)
        assert rx.tally.as_dict() == {}, cuts
        rx.finish()
        assert rx.tally.as_dict() == {"pairing": 1}, cuts
        assert [b.reason for b in rx.tally.bad] == [f"epoch 20 at {clean.t_ns[qual[3]]} ns matches no NAV_SOLUTION"]


def test_pairing_holds_over_a_burst_longer_than_any_count_and_expires_by_time():
    """2000 solutions, then their 2000 qualities (a DUT that fell behind and catches up):
    all pair. A quality whose solution is more than PAIR_WINDOW_NS older than the newest
    solution when it arrives does not, and is counted without waiting for the end."""
    from bench.wire.receive import PAIR_WINDOW_NS

    n = 2000
    t = (np.arange(n) + 1) * 5_000_000
    sol = np.zeros(n, NAV_SOLUTION_DTYPE)
    sol["t_ns"], sol["rx_ns"], sol["epoch"], sol["lat"] = t, t, np.arange(n) % 256, 0.6
    q = np.zeros(n, NAV_QUALITY_DTYPE)
    q["t_ns"], q["rx_ns"], q["epoch"], q["sigma_pos"] = t, t, np.arange(n) % 256, 0.5
    enc = CanEncoder()
    burst = CanBatch.concat([enc.encode_records("NAV_SOLUTION", sol), enc.encode_records("NAV_QUALITY", q)])
    for cuts in (None, [7], [500]):
        rx = NavReceiver()
        _run(rx, burst, cuts)
        rx.finish()
        assert rx.tally.as_dict() == {}, cuts
    late = np.zeros(1, NAV_SOLUTION_DTYPE)
    late["t_ns"] = late["rx_ns"] = t[-1] + PAIR_WINDOW_NS + 1
    late["epoch"] = n % 256
    late_q = q[:1].copy()  # the first epoch's quality once more, after a solution 10 s newer
    rx = NavReceiver()
    rx.feed(burst.take(np.arange(n)))  # the solutions only
    rx.feed(enc.encode_records("NAV_SOLUTION", late))
    rx.feed(CanEncoder().encode_records("NAV_QUALITY", late_q))
    assert rx.tally["pairing"] == 1
