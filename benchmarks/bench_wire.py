"""The wire: encoding the whole S000 traffic, and encode+send+receive+decode per link type.

    .venv/bin/python benchmarks/bench_wire.py [--quick]

Part 1 encodes one hour of S000 traffic with the vectorised codecs: IMU frames at
200 Hz, ODOMETER and BENCH_TIME at 100 Hz, DRIVER_INPUT and DOPPLER at 50 Hz, the five
NMEA sentences of a 1 Hz BDS fix (target: the whole hour in at most 5 s), once in one
call per stream and once in 1 s windows as a run engine calls the codecs; then the same
with the DUT-side decoders.

Part 2 moves frames through each kind of link and decodes them on the far side, counting
frames per second end to end: CAN ``virtual``, ``udp_multicast`` (in a throw-away network
namespace when the machine allows it), SocketCAN ``vcan0`` where it exists; IMU frames
over a pty pair and over pyserial ``loop://``.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import itertools

from bench.frames import CanBatch
from bench.transport.can_link import CanConfig, CanLink, open_can_link, socketcan_unavailable
from bench.transport.serial_link import PtyLink, PySerialLink, SerialConfig
from bench.wire import imu
from bench.wire.can import CanEncoder
from bench.wire.imu_stream import ImuStreamDecoder
from bench.wire.nmea import GNSS_FIX_DTYPE, encode_epochs
from bench.wire.nmea_stream import NmeaStreamDecoder
from bench.wire.receive import BenchTrafficDecoder

MS = 1_000_000
EPOCH_UTC = 1_748_736_000 * 10**9


def s000_signals(duration_s: int, rng: np.random.Generator) -> dict:
    """Plain signal values of S000's streams over ``duration_s`` (the codecs' inputs)."""

    def grid(hz: int) -> np.ndarray:
        return np.arange(1, duration_s * hz + 1, dtype=np.int64) * (1_000_000_000 // hz)

    t200, t100, t50 = grid(200), grid(100), grid(50)
    fixes = np.zeros(duration_s, GNSS_FIX_DTYPE)
    fixes["t_ns"] = grid(1)
    fixes["utc_ns"] = EPOCH_UTC + fixes["t_ns"]
    fixes["lat"] = np.radians(34.246 + np.cumsum(rng.normal(0, 1e-5, duration_s)))
    fixes["lon"] = np.radians(108.909 + np.cumsum(rng.normal(0, 1e-5, duration_s)))
    fixes["h"] = 380 + rng.normal(0, 3, duration_s)
    fixes["vel_n"] = rng.normal(0, 10, (duration_s, 3))
    fixes["sigma_lat"], fixes["sigma_lon"], fixes["sigma_alt"] = 2.0, 1.5, 3.5
    fixes["sats"], fixes["hdop"], fixes["quality"] = 14, 0.8, 1
    return {
        "imu": (t200, rng.normal(0, 1e-4, (t200.size, 3)), rng.normal(0, 5e-2, (t200.size, 3))),
        "t100": t100,
        "t50": t50,
        "pulses": np.cumsum(rng.integers(0, 40, t100.size)),
        "odo_speed": rng.uniform(0, 22, t100.size),
        "steer": rng.uniform(-0.5, 0.5, t50.size),
        "dop_speed": rng.uniform(0, 22, t50.size),
        "fixes": fixes,
    }


def encode_s000(sig: dict, window_s: float | None) -> tuple[dict[str, float], dict[str, int], list]:
    """Encode every stream, in one call or in windows; (seconds per stream, frames, outputs)."""
    enc = CanEncoder()
    times: dict[str, float] = {}
    counts: dict[str, int] = {}
    out: list = []
    t_imu, dth, dv = sig["imu"]
    t100, t50 = sig["t100"], sig["t50"]
    end = int(t_imu[-1])
    step = end if window_s is None else round(window_s * 1e9)

    def windows(t):
        cuts = np.searchsorted(t, np.arange(0, end + step, step), side="right")
        return [slice(a, b) for a, b in itertools.pairwise(cuts) if b > a]

    jobs = {
        "IMU 200 Hz (serial)": (
            t_imu,
            lambda s: imu.encode_batch(t_imu[s], dth[s], dv[s], 0x3F, 31.0, np.arange(s.start, s.stop) % 256),
        ),
        "BENCH_TIME 100 Hz": (t100, lambda s: enc.encode("BENCH_TIME", t100[s], time_ns=t100[s], lockstep=1)),
        "ODOMETER 100 Hz": (
            t100,
            lambda s: enc.encode(
                "ODOMETER", t100[s], pulse_count=sig["pulses"][s], speed=sig["odo_speed"][s], reverse=0, valid=1
            ),
        ),
        "DRIVER_INPUT 50 Hz": (
            t50,
            lambda s: enc.encode(
                "DRIVER_INPUT", t50[s], left_lever=0, right_lever=0, steering=sig["steer"][s], brake=0
            ),
        ),
        "DOPPLER 50 Hz": (
            t50,
            lambda s: enc.encode("DOPPLER", t50[s], speed=sig["dop_speed"][s], quality=200, valid=1, low_signal=0),
        ),
        "BDS 1 Hz (5 NMEA sentences)": (
            sig["fixes"]["t_ns"],
            lambda s: encode_epochs(sig["fixes"][s], talker="GB", at_ns=sig["fixes"]["t_ns"][s] + 80 * MS),
        ),
    }
    for name, (t, fn) in jobs.items():
        t0 = time.perf_counter()
        parts = [fn(s) for s in windows(t)]
        times[name] = time.perf_counter() - t0
        counts[name] = sum(len(p) for p in parts)
        out.append((name, parts))
    t0 = time.perf_counter()
    can_parts = [
        p for name, parts in out if "Hz" in name and "serial" not in name and "NMEA" not in name for p in parts
    ]
    merged = CanBatch.concat(can_parts).sorted()
    times["merge CAN streams, sort by time"] = time.perf_counter() - t0
    counts["merge CAN streams, sort by time"] = len(merged)
    return times, counts, out


def decode_s000(out: list) -> dict[str, float]:
    times = {}
    for name, parts in out:
        t0 = time.perf_counter()
        if name.startswith("IMU"):
            dec = ImuStreamDecoder()
            for p in parts:
                dec.feed(p.tobytes())
        elif name.startswith("BDS"):
            dec = NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC)
            for p in parts:
                dec.feed(p.tobytes())
        else:
            dec = BenchTrafficDecoder()
            for p in parts:
                dec.feed(p)
        times[name] = time.perf_counter() - t0
        assert not dec.tally.as_dict(), dec.tally.as_dict()
    return times


def part1(duration_s: int) -> None:
    sig = s000_signals(duration_s, np.random.default_rng(0))
    decode_s000(encode_s000(s000_signals(2, np.random.default_rng(1)), None)[2])  # compiled kernels loaded
    print(f"\n1. S000 traffic, {duration_s} s (target for 3600 s: encode in <= 5 s)")
    print(f"  {'stream':<34} {'frames':>10} {'one call':>10} {'1 s windows':>12} {'decode (1 s)':>13}")
    t_all, n_all, _ = encode_s000(sig, None)
    t_win, _, out = encode_s000(sig, 1.0)
    t_dec = decode_s000(out)
    for name in t_all:
        dec = t_dec.get(name)
        print(
            f"  {name:<34} {n_all[name]:>10} {t_all[name]:>9.3f}s {t_win[name]:>11.3f}s "
            f"{'' if dec is None else f'{dec:>12.3f}s'}"
        )
    total = sum(v for k, v in t_all.items() if not k.startswith("merge"))
    total_w = sum(v for k, v in t_win.items() if not k.startswith("merge"))
    frames = sum(v for k, v in n_all.items() if not k.startswith("merge"))
    print(f"  {'total encode':<34} {frames:>10} {total:>9.3f}s {total_w:>11.3f}s {sum(t_dec.values()):>12.3f}s")
    print(
        f"  encode of the whole traffic, 1 s windows: {total_w:.2f} s for {duration_s} s of bench time "
        f"({duration_s / max(total_w, 1e-9):.0f}x real time)"
    )


# ------------------------------------------------------------------------------------ links
def _can_round_trip(tx: CanLink, rx: CanLink, n: int, chunk: int = 500) -> tuple[float, int, dict]:
    enc = CanEncoder()
    dec = BenchTrafficDecoder()
    t = np.arange(1, n + 1, dtype=np.int64) * 10 * MS
    speed = np.random.default_rng(1).uniform(0, 20, n)
    got = 0
    t0 = time.perf_counter()
    for a in range(0, n, chunk):
        s = slice(a, min(n, a + chunk))
        tx.send_many(
            enc.encode("ODOMETER", t[s], pulse_count=np.arange(s.start, s.stop), speed=speed[s], reverse=0, valid=1)
        )
        want = s.stop
        deadline = time.monotonic() + 2.0
        while got < want and time.monotonic() < deadline:
            batch = rx.drain(timeout=0.2)
            dec.feed(batch)
            got += len(batch)
    return time.perf_counter() - t0, got, dec.tally.as_dict()


def _serial_round_trip(write, read, n: int, chunk: int = 200) -> tuple[float, int]:
    rng = np.random.default_rng(2)
    t = np.arange(1, n + 1, dtype=np.int64) * 5 * MS
    dth, dv = rng.normal(0, 1e-4, (n, 3)), rng.normal(0, 1e-2, (n, 3))
    dec = ImuStreamDecoder()
    got = [0]
    done = threading.Event()

    def reader():
        while got[0] < n:
            data = read()
            if data:
                got[0] += dec.feed(data).size
        done.set()

    th = threading.Thread(target=reader, daemon=True)
    t0 = time.perf_counter()
    th.start()
    for a in range(0, n, chunk):
        s = slice(a, min(n, a + chunk))
        write(imu.encode_batch(t[s], dth[s], dv[s], 0x3F, 30.0, np.arange(s.start, s.stop) % 256))
    done.wait(30)
    return time.perf_counter() - t0, got[0]


def _serial_in_turn(link, n: int, chunk: int = 90) -> tuple[float, int]:
    rng = np.random.default_rng(3)
    t = np.arange(1, n + 1, dtype=np.int64) * 5 * MS
    dth, dv = rng.normal(0, 1e-4, (n, 3)), rng.normal(0, 1e-2, (n, 3))
    dec = ImuStreamDecoder()
    got = 0
    t0 = time.perf_counter()
    for a in range(0, n, chunk):
        s = slice(a, min(n, a + chunk))
        link.write_many(imu.encode_batch(t[s], dth[s], dv[s], 0x3F, 30.0, np.arange(s.start, s.stop) % 256))
        got += dec.feed(link.read(timeout=1.0)).size
    return time.perf_counter() - t0, got


def _row(name: str, n: int, dt: float, extra: str = "") -> None:
    print(f"  {name:<48} {n:>8} {dt:>8.3f}s {n / dt:>12,.0f} frames/s  {extra}")


def part2(n: int) -> None:
    print(f"\n2. encode + send + receive + decode, per link ({n} frames each)")
    with CanLink(CanConfig(channel="bench-wire")) as tx, CanLink(CanConfig(channel="bench-wire")) as rx:
        dt, got, tally = _can_round_trip(tx, rx, n)
    _row("CAN virtual (ODOMETER, classic)", got, dt, str(tally or ""))

    try:
        from tests.transport import netns
    except ImportError:
        netns = None
    reason = netns.unavailable() if netns else "tests.transport.netns not importable"
    if reason:
        print(f"  {'CAN udp_multicast':<48} skipped: {reason}")
    else:
        with netns.multicast_netns() as ns:
            cfg = CanConfig(interface="udp_multicast", channel="239.74.163.9", options={"port": 43900})
            tx = netns.call_in(ns, lambda: open_can_link(cfg, run_tag="wire"))  # two links of one run
            rx = netns.call_in(ns, lambda: open_can_link(cfg, run_tag="wire"))
            try:
                dt, got, tally = _can_round_trip(tx, rx, n)
                _row("CAN udp_multicast (netns loopback)", got, dt, f"drops {rx.stats()['drops']}")
            finally:
                tx.close()
                rx.close()

    reason = socketcan_unavailable("vcan0")
    if reason:
        print(f"  {'CAN socketcan vcan0':<48} skipped: {reason}")
    else:
        cfg = CanConfig(interface="socketcan", channel="vcan0")
        with CanLink(cfg) as tx, CanLink(cfg) as rx:
            dt, got, tally = _can_round_trip(tx, rx, n)
        _row("CAN socketcan vcan0", got, dt)

    with PtyLink(SerialConfig()) as link:
        fd = os.open(link.dut_port, os.O_RDWR | os.O_NOCTTY)
        try:
            dt, got = _serial_round_trip(lambda b: link.write_many(b), lambda: os.read(fd, 1 << 16), n)
        finally:
            os.close(fd)
    _row("serial pty pair (IMU frames, 42 B)", got, dt, f"{got * 42 / dt / 1e6:.1f} MB/s; no pacing")

    with PySerialLink(SerialConfig(port="loop://")) as link:  # one thread: loop:// holds 4 KiB
        dt, got = _serial_in_turn(link, n)
    _row("serial pyserial loop:// (IMU frames)", got, dt)
    print("  (real-time mode paces serial bytes at the baud rate: 460800 8N1 carries at most 1097 IMU frames/s)")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="360 s of traffic and fewer link frames")
    a = p.parse_args()
    part1(360 if a.quick else 3600)
    part2(5_000 if a.quick else 50_000)
    return 0


if __name__ == "__main__":
    sys.exit(main())
