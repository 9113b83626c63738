"""Fuzz campaign of the decoders: 1,000,000 hostile inputs each, no crash, no split mismatch.

    .venv/bin/python benchmarks/bench_fuzz.py [--inputs N] [--seed S] [--only imu|nmea|can]

Three campaigns, seeded, each mixing random bytes with mutated valid traffic (bit flips,
cuts, insertions, deletions, splices, repeats, fields set out of range with the check
recomputed, NMEA fields replaced by ``nan``, ``inf``, ``1e400``, dates such as 29 February
of a common year or 999999, satellite counts of 9999):

* IMU: each input a byte string fed to an :class:`ImuStreamDecoder` at once and to a
  second one in random pieces (1 byte up); ``decode_one`` on its first 42 bytes;
* NMEA: each input a byte string (a few sentences, mutated, or noise) fed to an
  :class:`NmeaStreamDecoder` at once and to a second one in random pieces;
  ``parse_sentence`` and ``decode_fields`` on its first line;
* CAN: each input one frame (any identifier, DLC 0..64, FD or not, any bytes); frames
  go in batches of 1..200 to a :class:`NavReceiver` and a :class:`BenchTrafficDecoder`
  at once and to two more cut into random sub-batches; ``decode_one`` on every frame.

The decoders keep their state from input to input (one stream), so garbage is always
followed by what comes next. Printed per campaign: inputs, decoded, rejected by kind,
crashes (any exception other than the documented :class:`~bench.errors.CodecError` of a
one-frame decoder; the stream decoders raise nothing), split mismatches (the split
decoder's output, counts and kept bad frames differ from the one fed at once) and
elapsed time, with progress every 10 %. Exit status 1 if any crash or mismatch.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.errors import CodecError
from bench.frames import CanBatch
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from bench.wire import imu
from bench.wire.bits import INT64_MAX_US
from bench.wire.can import CanEncoder, codec_for_id
from bench.wire.imu_stream import RUN_KINDS, ImuStreamDecoder
from bench.wire.nmea import GNSS_FIX_DTYPE, checksum, encode_epochs
from bench.wire.nmea_fields import decode_fields, parse_sentence
from bench.wire.nmea_stream import NmeaStreamDecoder
from bench.wire.receive import BenchTrafficDecoder, NavReceiver

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fuzzing import EPOCH_UTC, HOSTILE, Campaign, mutate, noise, pieces


# ---------------------------------------------------------------------------- IMU
def imu_campaign(total: int, rng: np.random.Generator) -> Campaign:
    c = Campaign("IMU stream decoder (ImuStreamDecoder)", total)
    n = 4096
    pool = imu.encode_frames(
        (np.arange(n) + 1) * 5_000_000, rng.normal(0, 1e-4, (n, 3)), rng.normal(0, 1e-2, (n, 3)), 0x3F, 30.0,
        np.arange(n) % 256,
    )  # fmt: skip
    specials = b"\xaa\x55\x24\xaa\x55\x00\xff"
    a, b = ImuStreamDecoder(), ImuStreamDecoder()
    ptr = 0
    for i in range(total):
        r = rng.random()
        if r < 0.2:
            data = noise(rng, specials)
        else:
            k = int(rng.integers(1, 5))
            rows = pool[np.arange(ptr, ptr + k) % n].copy()
            ptr += k
            if r < 0.35:  # a field out of range or a wrong length byte, the CRC recomputed
                j = int(rng.integers(k))
                what = int(rng.integers(3))
                if what == 0:
                    rows[j, 37] = int(rng.integers(1, 256))  # reserved status bits
                elif what == 1:
                    rows[j, 4:12] = np.frombuffer((INT64_MAX_US + int(rng.integers(1, 10**6))).to_bytes(8, "little"),
                                                  np.uint8)  # fmt: skip
                else:
                    rows[j, 2] = int(rng.integers(0, 256))
                imu.refresh_crc(rows)
            data = mutate(rng, rows.tobytes(), specials)
        c.inputs += 1
        try:
            got_a = a.feed(data, i)
            got_b = b"".join(b.feed(p, i).tobytes() for p in pieces(rng, data))
            c.decoded += len(got_a)
            runs_a = [(x.kind, x.data, x.t_ns) for x in a.tally.pop_bad() if x.kind in RUN_KINDS]
            runs_b = [(x.kind, x.data, x.t_ns) for x in b.tally.pop_bad() if x.kind in RUN_KINDS]
            if got_a.tobytes() != got_b or runs_a != runs_b or a.tally.counts != b.tally.counts:
                c.mismatches += 1
                a, b = ImuStreamDecoder(), ImuStreamDecoder()
        except Exception as exc:
            c.crash(exc)
            a, b = ImuStreamDecoder(), ImuStreamDecoder()
        try:
            imu.decode_one(data[:42])
            c.one_frame["ok"] += 1
        except CodecError as exc:
            c.one_frame[exc.kind] += 1
        except Exception as exc:
            c.crash(exc)
        c.progress()
    a.flush()
    b.flush()
    if a.tally.counts != b.tally.counts:
        c.mismatches += 1
    c.report(dict(a.tally.counts), "frames handed on")
    return c


# ---------------------------------------------------------------------------- NMEA
def _hostile_sentence(rng: np.random.Generator, line: bytes) -> bytes:
    star = line.index(b"*")
    parts = line[1:star].split(b",")
    for _ in range(int(rng.integers(1, 3))):
        parts[int(rng.integers(1, len(parts)))] = HOSTILE[int(rng.integers(len(HOSTILE)))]
    body = b",".join(parts)
    tail = b"*%02X\r\n" % checksum(body) if rng.random() < 0.8 else line[star:]
    return b"$" + body + tail


def nmea_campaign(total: int, rng: np.random.Generator) -> Campaign:
    c = Campaign("NMEA stream decoder (NmeaStreamDecoder)", total)
    n = 2000
    fixes = np.zeros(n, GNSS_FIX_DTYPE)
    fixes["utc_ns"] = EPOCH_UTC + np.arange(n) * 10**9
    fixes["t_ns"] = fixes["utc_ns"] - EPOCH_UTC
    fixes["lat"], fixes["lon"] = np.radians(34.2 + rng.normal(0, 1e-4, n)), np.radians(108.9 + rng.normal(0, 1e-4, n))
    fixes["h"], fixes["vel_n"] = 380.0, rng.normal(0, 5, (n, 3))
    fixes["sigma_lat"], fixes["sigma_lon"], fixes["sigma_alt"] = 1.0, 1.5, 2.5
    fixes["sats"], fixes["hdop"], fixes["quality"] = 12, 0.9, rng.choice([0, 1, 2, 4], n)
    pool = [ch.data for ch in encode_epochs(fixes).chunks()]
    specials = b"$$,,*\r\n\r\n0123456789.-AV"
    a, b = NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC), NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC)
    ptr = 0
    for i in range(total):
        r = rng.random()
        if r < 0.15:
            data = noise(rng, specials)
        else:
            k = int(rng.integers(1, 6))
            lines = [pool[(ptr + j) % len(pool)] for j in range(k)]
            ptr += k
            if r < 0.6:
                lines = [_hostile_sentence(rng, ln) if rng.random() < 0.5 else ln for ln in lines]
            data = b"".join(lines)
            if rng.random() < 0.1:
                data = data.replace(b"\r\n", b"", 1)  # a line without its end: a length or truncated run
            data = mutate(rng, data, specials)
        c.inputs += 1
        try:
            got_a = a.feed(data, i)
            got_b = b"".join(b.feed(p, i).tobytes() for p in pieces(rng, data))
            c.decoded += len(got_a)
            bad_a = [(x.kind, x.data, x.t_ns) for x in a.tally.pop_bad()]
            bad_b = [(x.kind, x.data, x.t_ns) for x in b.tally.pop_bad()]
            if got_a.tobytes() != got_b or bad_a != bad_b or a.tally.counts != b.tally.counts:
                c.mismatches += 1
                a, b = NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC), NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC)
        except Exception as exc:
            c.crash(exc)
            a, b = NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC), NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC)
        line = data[: data.find(b"\n") + 1] if b"\n" in data else data
        try:
            decode_fields(*parse_sentence(line)[1:])
            c.one_frame["ok"] += 1
        except CodecError as exc:
            c.one_frame[exc.kind] += 1
        except Exception as exc:
            c.crash(exc)
        c.progress()
    fa, fb = a.flush(), b.flush()
    if fa.tobytes() != fb.tobytes() or a.tally.counts != b.tally.counts:
        c.mismatches += 1
    c.decoded += len(fa)
    c.report(dict(a.tally.counts), f"fixes ({a.sentences:,} good sentences in the last decoder's stream)")
    return c


# ---------------------------------------------------------------------------- CAN
def _can_pool(rng: np.random.Generator, n: int = 2000) -> CanBatch:
    enc = CanEncoder()
    t = (np.arange(n) + 1) * 10_000_000
    sol = np.zeros(n, NAV_SOLUTION_DTYPE)
    sol["t_ns"] = sol["rx_ns"] = t
    sol["epoch"] = np.arange(n) % 256
    sol["lat"], sol["lon"], sol["heading"] = 0.6 + rng.normal(0, 1e-6, n), 1.9, rng.uniform(0, 6.28, n)
    qual = np.zeros(n, NAV_QUALITY_DTYPE)
    qual["t_ns"] = qual["rx_ns"] = t
    qual["epoch"] = sol["epoch"]
    qual["sigma_pos"] = rng.uniform(0, 10, (n, 3))
    parts = [
        enc.encode_records("NAV_SOLUTION", sol),
        enc.encode_records("NAV_QUALITY", qual),
        enc.encode("DUT_READY", t, time_ns=t),
        enc.encode("BENCH_TIME", t, time_ns=t, lockstep=1),
        enc.encode("BENCH_EPOCH", t, epoch_utc_ns=np.full(n, EPOCH_UTC)),
        enc.encode("BENCH_CMD", t, command=rng.integers(1, 4, n)),
        enc.encode("ODOMETER", t, pulse_count=np.arange(n), speed=rng.uniform(-5, 20, n), reverse=0, valid=1),
        enc.encode("DRIVER_INPUT", t, left_lever=1, right_lever=1, steering=rng.uniform(-0.5, 0.5, n), brake=0),
        enc.encode("DOPPLER", t, speed=rng.uniform(0, 20, n), quality=200, valid=1, low_signal=0),
    ]
    batch = CanBatch.concat(parts).with_width(64)
    return batch.take(np.argsort(batch.t_ns, kind="stable"))


def _can_inputs(rng: np.random.Generator, pool: CanBatch, ptr: int, k: int, t0: int) -> CanBatch:
    """``k`` frames: the pool's next ones, mutated ones, random ones."""
    idx = (ptr + np.arange(k)) % len(pool)
    can_id = pool.can_id[idx].copy()
    data = pool.data[idx].copy()
    length = pool.length[idx].astype(np.int64)
    fd = pool.fd[idx].copy()
    r = rng.random(k)
    for j in np.flatnonzero(r < 0.4).tolist():  # mutated
        op = int(rng.integers(4))
        if op == 0:
            data[j, int(rng.integers(0, max(1, length[j])))] = int(rng.integers(256))
            c = codec_for_id(int(can_id[j]))
            if rng.random() < 0.6 and c is not None and length[j] == c.length:
                c.refresh_crc(data[j : j + 1, : c.length])
        elif op == 1:
            new = int(rng.integers(0, 65))
            data[j, new:] = 0
            length[j] = new
        elif op == 2:
            can_id[j] = int(rng.integers(0, 0x800)) if rng.random() < 0.7 else int(rng.integers(0, 1 << 29))
        else:
            fd[j] = not fd[j]
    for j in np.flatnonzero(r > 0.85).tolist():  # random frames
        can_id[j] = int(rng.integers(0, 1 << 29)) if rng.random() < 0.3 else int(rng.integers(0, 0x800))
        length[j] = int(rng.integers(0, 65))
        data[j] = 0
        data[j, : length[j]] = rng.integers(0, 256, length[j], dtype=np.uint8)
        fd[j] = rng.random() < 0.5
    return CanBatch(t0 + np.arange(k) * 1000, can_id, data, length, fd)


def _nav_concat(outs: list) -> tuple[bytes, ...]:
    return tuple(b"".join(getattr(o, name).tobytes() for o in outs) for name in ("solutions", "qualities", "ready_ns"))


def _bench_concat(outs: list[dict]) -> dict:
    cols: dict[str, list[np.ndarray]] = {}
    for o in outs:
        for name, values in o.items():
            for key, v in values.items():
                cols.setdefault(f"{name}.{key}", []).append(np.asarray(v))
    return {key: np.concatenate(v).tobytes() for key, v in sorted(cols.items())}


def _handed_on(out) -> int:
    if isinstance(out, dict):
        return sum(len(v["rx_ns"]) for v in out.values())
    return out.solutions.size + out.qualities.size + out.ready_ns.size


def can_campaign(total: int, rng: np.random.Generator) -> Campaign:
    c = Campaign("CAN decoders (NavReceiver, BenchTrafficDecoder, CanCodec.decode_one)", total)
    pool = _can_pool(rng)
    recv = {"nav": (NavReceiver, _nav_concat), "bench": (BenchTrafficDecoder, _bench_concat)}
    at_once = {k: cls() for k, (cls, _) in recv.items()}
    split = {k: cls() for k, (cls, _) in recv.items()}
    decoded: Counter[str] = Counter()
    ptr = 0
    while c.inputs < total:
        k = min(int(rng.integers(1, 201)), total - c.inputs)
        batch = _can_inputs(rng, pool, ptr, k, c.inputs * 1000)
        ptr += k
        c.inputs += k
        edges = [0, *np.unique(rng.integers(1, k + 1, int(rng.integers(0, 5)))).tolist()]
        edges = sorted({*edges, k})
        for name, (cls, concat) in recv.items():
            try:
                got = at_once[name].feed(batch)
                parts = [split[name].feed(batch.take(np.arange(a, b))) for a, b in itertools.pairwise(edges)]
                decoded[name] += _handed_on(got)
                kept_a = sorted((x.stream, x.kind, x.t_ns, x.data) for x in at_once[name].tally.pop_bad())
                kept_b = sorted((x.stream, x.kind, x.t_ns, x.data) for x in split[name].tally.pop_bad())
                same = concat([got]) == concat(parts) and kept_a == kept_b
                if not same or at_once[name].tally.counts != split[name].tally.counts:
                    c.mismatches += 1
                    at_once[name], split[name] = cls(), cls()
            except Exception as exc:
                c.crash(exc)
                at_once[name], split[name] = cls(), cls()
        for i in range(k):
            f = batch.frame(i)
            codec = codec_for_id(f.can_id)
            if codec is None:
                c.one_frame["unknown_id"] += 1
                continue
            try:
                codec.decode_one(f.data, fd=f.fd)
                c.one_frame["ok"] += 1
            except CodecError as exc:
                c.one_frame[exc.kind] += 1
            except Exception as exc:
                c.crash(exc)
        c.progress()
    c.decoded = sum(decoded.values())
    rejected = {f"{name}.{kind}": n for name, r in at_once.items() for kind, n in r.tally.counts.items()}
    c.report(rejected, f"frames handed on (NavReceiver {decoded['nav']:,}, BenchTrafficDecoder {decoded['bench']:,})")
    return c


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--inputs", type=int, default=1_000_000, help="inputs per decoder (default 1,000,000)")
    p.add_argument("--seed", type=int, default=2024)
    p.add_argument("--only", choices=("imu", "nmea", "can"), action="append", help="run only these campaigns")
    args = p.parse_args()
    runs = {"imu": imu_campaign, "nmea": nmea_campaign, "can": can_campaign}
    print(f"fuzz campaigns: {args.inputs:,} inputs per decoder, seed {args.seed}", flush=True)
    failed = False
    for name in args.only or list(runs):
        failed |= runs[name](args.inputs, np.random.default_rng([args.seed, list(runs).index(name)])).failed
    print("\nresult:", "FAIL (crashes or split mismatches)" if failed else "0 crashes, 0 split mismatches")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
