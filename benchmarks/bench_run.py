"""Run-engine speed and timing quality.

1. Lockstep S000 (3600 s, 50.6 km) with the decode-only DUT in process, all links
   (every frame encoded, decoded on the DUT side, the DUT's output encoded, received and
   decoded) and the full recording. Target: at least 300x real time (at most 12 s).
   Beside it, for information, the dead-reckoning DUT, and a shorter run with the DUT as
   an external process over pty + udp_multicast (in a network namespace, when permitted).
2. Real time, 60 s, 1 kHz IMU plus all other traffic (odometer, Doppler, driver, BDS,
   BENCH_*), emitted to an external DUT process over pty + udp_multicast: lateness p50,
   p99, p99.9, max of every emission. Targets: p99 <= 50 us, max <= 3x the max of an
   empty 1 kHz loop in the same run. Printed side by side, to show what is ruled out:
   the empty loop (SCHED_FIFO and SCHED_OTHER), the bench under SCHED_FIFO (default),
   under SCHED_FIFO sleeping instead of spinning (headroom from the kernel's real-time
   throttling), spinning the last 800 us instead of 300 us, under SCHED_OTHER, with the
   DUT pinned to the other core, and python-can's own player (``can.MessageSync``) on the
   same emissions and links. The empty loop uses the bench's clock with its defaults.

    .venv/bin/python benchmarks/bench_run.py [--quick]
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.clock.pacing import TimingLog  # noqa: E402
from bench.faults.schedule import FaultSchedule  # noqa: E402
from bench.run.engine import run  # noqa: E402
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec  # noqa: E402
from bench.scenario.loader import load_scenario  # noqa: E402

SHORT = ROOT / "tests" / "data" / "short_drive.toml"
TABLES_1K = {"imu": {"grade": "navigation", "rate": "1000 Hz"}, "doppler": {"model": "seed000"},
             "odometer": {"model": "typical_wheeled"}, "bds": {"model": "seed001", "latency": "80 ms"},
             "driver": {"vehicle": "wheeled"}}


def lockstep(out: Path) -> None:
    sc = load_scenario("S000")
    traj = sc.trajectory()  # built once, outside the timed runs (0.5 s)
    print("1. Lockstep S000, 3600 s of bench time, in-process DUT, all links, full recording")
    for name, config in (("decode_only", {}),
                         ("dead_reckoning", {"initial_position": [34 + 14.763 / 60, 108 + 54.579 / 60, 380.0],
                                             "alignment": "250 s"})):
        spec = RunSpec(scenario=sc, tables=sc.doc, schedule=FaultSchedule(), trajectory=traj,
                       dut=DutSpec("in_process", name=name, config=config), out=out / f"s000_{name}.mcap")
        t = time.perf_counter()
        res = run(spec)
        el = time.perf_counter() - t
        frames = sum(res.counts.values())
        size = spec.out.stat().st_size / 1e6
        verdict = ("MET" if el <= 12.0 else "MISSED") if name == "decode_only" else "(information)"
        print(f"   {name:<15} {res.status:<8} {el:6.2f} s  {3600 / el:6.0f}x real time  target >= 300x "
              f"(<= 12 s) {verdict}; {frames} samples, recording {size:.0f} MB")


def _netns():
    from tests.transport import netns

    reason = netns.unavailable()
    return (None, reason) if reason else (netns, None)


def external_lockstep(out: Path) -> None:
    netns, reason = _netns()
    if netns is None:
        print(f"   external DUT: skipped ({reason})")
        return
    sc = load_scenario(SHORT)
    with netns.multicast_netns() as ns:
        cmd = (f"ip netns exec {ns} {sys.executable} -m bench.dut.harness --estimator decode_only "
               "--can-interface {can_interface} --can-channel {can_channel} --can-port 43391 "
               "--imu {imu_port} --gnss {gnss_port}")
        for step_ms in (10, 100):
            spec = RunSpec(scenario=sc, tables=sc.doc, schedule=FaultSchedule(), dut=DutSpec("external", command=cmd),
                           links=LinkSpec(can={"interface": "udp_multicast", "channel": "239.74.163.91",
                                               "port": 43391}),
                           clock=ClockSpec(step_ns=step_ms * 1_000_000), out=out / f"ext_{step_ms}.mcap")
            t = time.perf_counter()
            res = netns.call_in(ns, lambda spec=spec: run(spec))
            el = time.perf_counter() - t
            print(f"   external process (pty + udp_multicast), {step_ms:3d} ms lockstep steps, 90 s drive: "
                  f"{res.status}, {el:.1f} s, {90 / el:.0f}x real time")


#: The real-time variants printed side by side: (label, SCHED_FIFO, spin before each due
#: time in ns, DUT pinned to the other core).
VARIANTS = (
    ("bench, SCHED_FIFO, spin 300 us (default)", True, 300_000, False),
    ("bench, SCHED_FIFO, spin 800 us", True, 800_000, False),
    ("bench, SCHED_FIFO, sleep only (headroom)", True, 0, False),
    ("bench, SCHED_OTHER, spin 300 us", False, 300_000, False),
    ("bench, SCHED_FIFO, DUT pinned to cpu 1", True, 300_000, True),
)


def _rt_run(netns, ns, out: Path, seconds: float, fifo: bool, spin_ns: int, pin: bool):
    """One real-time run of the 1 kHz traffic to the decode-only harness; (result, lateness)."""
    import functools
    import os

    from bench.clock.pacing import RealTimeClock
    from bench.run import session

    sc = load_scenario(SHORT)
    pre = "taskset -c 1 " if pin else ""
    cmd = (f"{pre}ip netns exec {ns} {sys.executable} -m bench.dut.harness --estimator decode_only "
           "--can-interface {can_interface} --can-channel {can_channel} --can-port 43392 "
           "--imu {imu_port} --gnss {gnss_port}")
    spec = RunSpec(scenario=sc, tables=TABLES_1K, schedule=FaultSchedule(), dut=DutSpec("external", command=cmd),
                   links=LinkSpec(can={"interface": "udp_multicast", "channel": "239.74.163.92", "port": 43392}),
                   clock=ClockSpec(mode="realtime"), out=out / "rt.mcap", duration_ns=round(seconds * 1e9))
    saved_env, saved_clock = os.environ.get("BENCH_RT_PRIORITY"), session.RealTimeClock
    saved_aff = os.sched_getaffinity(0)
    os.environ["BENCH_RT_PRIORITY"] = "50" if fifo else "0"
    session.RealTimeClock = functools.partial(RealTimeClock, spin_ns=spin_ns)  # type: ignore[misc]
    try:
        if pin:
            os.sched_setaffinity(0, {0})
        res = netns.call_in(ns, lambda: run(spec))
    finally:
        os.sched_setaffinity(0, saved_aff)
        session.RealTimeClock = saved_clock
        if saved_env is None:
            os.environ.pop("BENCH_RT_PRIORITY", None)
        else:
            os.environ["BENCH_RT_PRIORITY"] = saved_env
    return res, _lateness_of(spec.out), spec.out


def realtime(out: Path, seconds: float) -> None:
    print(f"\n2. Real time, {seconds:g} s, IMU 1 kHz + odometer 100 Hz + Doppler 50 Hz + driver 50 Hz + BDS 1 Hz + "
          "BENCH_TIME 100 Hz, external DUT (decode-only harness) over pty + udp_multicast; lateness of every emission")
    netns, reason = _netns()
    if netns is None:
        print(f"   skipped ({reason})")
        return
    with netns.multicast_netns() as ns:
        floor = platform_floor(seconds)
        floor_other = platform_floor(seconds, fifo=False)
        print(f"   {'empty 1 kHz loop, SCHED_FIFO':<44} {_fmt(floor)}")
        print(f"   {'empty 1 kHz loop, SCHED_OTHER':<44} {_fmt(floor_other)}")
        first = None
        for label, fifo, spin, pin in VARIANTS:
            res, late, path = _rt_run(netns, ns, out, seconds, fifo, spin, pin)
            print(f"   {label:<44} {_fmt(late)} ({res.status}{_output_note(path)})")
            if first is None:
                first = late, path
        assert first is not None
        ours, path = first
        theirs = netns.call_in(ns, lambda: _message_sync(path))
        print(f"   {'can.MessageSync, same emissions and links':<44} {_fmt(theirs)}")
    p99, mx = np.percentile(ours, 99), ours.max()
    print(f"   targets (default variant): p99 <= 50 us {'MET' if p99 <= 50e3 else 'MISSED'} ({p99 / 1e3:.1f} us); "
          f"max <= 3x the empty loop's max ({3 * floor.max() / 1e3:.0f} us) "
          f"{'MET' if mx <= 3 * floor.max() else 'MISSED'} ({mx / 1e3:.0f} us); "
          f"max / MessageSync's max {mx / max(theirs.max(), 1):.2f}")


def platform_floor(seconds: float, fifo: bool = True) -> np.ndarray:
    """Lateness of an empty 1 kHz sleep-then-spin loop under the same scheduling: what the
    host (here a virtual machine) itself allows, with no work done at all."""
    import gc
    import os

    from bench.clock import realtime_priority
    from bench.clock.pacing import RealTimeClock

    saved = os.environ.get("BENCH_RT_PRIORITY")
    os.environ["BENCH_RT_PRIORITY"] = "50" if fifo else "0"
    realtime_priority.acquire()
    try:
        clock = RealTimeClock()
        clock.start()
        n = int(seconds * 1000)
        late = np.empty(n, np.int64)
        for k in range(n):
            late[k] = clock.wait_until((k + 1) * 1_000_000)
    finally:
        realtime_priority.release()
        gc.collect()
        if saved is None:
            os.environ.pop("BENCH_RT_PRIORITY", None)
        else:
            os.environ["BENCH_RT_PRIORITY"] = saved
    return late


def _output_note(path: Path) -> str:
    """What the DUT's output and its lines looked like: bad frames, lines held."""
    import json

    from bench.record.mcap_io import RecordingReader

    md = RecordingReader(path).metadata()
    bad = json.loads(md.get("dut_output", {}).get("bad_frames", "{}") or "{}")
    held = json.loads(md.get("dut_exit", {}).get("serial_held", "{}") or "{}")
    note = f"; DUT output bad frames {bad or 0}"
    for name, h in held.items():
        note += f"; {name} line held {h['episodes']}x, up to {h['max_bytes']} B, {h['longest_s'] * 1e3:.0f} ms"
    return note


def _fmt(late_ns: np.ndarray) -> str:
    s = TimingLog.summarize(late_ns)
    return s.text()


def _lateness_of(path: Path) -> np.ndarray:
    from bench.record.mcap_io import RecordingReader

    return RecordingReader(path).read_columnar("/bench/timing")["lateness_ns"]


def _message_sync(path: Path) -> np.ndarray:
    """python-can's player on the emissions the bench made (CAN frames and serial byte
    groups), sending through the same kinds of links; its lateness per emission."""
    import can

    from bench.record.mcap_io import RecordingReader
    from bench.record.wire_topics import CAN_TX, SERIAL_TX, read_can, read_serial
    from bench.run.realtime_plan import EMIT_CAN, EMIT_IMU, plan_emissions
    from bench.run.traffic import Traffic
    from bench.transport.serial_link import PtyLink, SerialConfig

    r = RecordingReader(path)
    traffic = Traffic(read_can(r, CAN_TX), read_serial(r, SERIAL_TX["imu"]), read_serial(r, SERIAL_TX["gnss"]),
                      np.zeros(0))
    plan = plan_emissions(traffic, 460800, 115200)
    payloads = {EMIT_CAN: plan.can, EMIT_IMU: plan.imu}
    emissions = [(t, kind, payloads.get(kind, plan.gnss)[i]) for t, kind, i in zip(plan.times, plan.kinds, plan.index,
                                                                                   strict=True)]
    t0 = emissions[0][0]
    msgs = [can.Message(timestamp=(t - t0) * 1e-9, arbitration_id=i, data=b"") for i, (t, _, _) in enumerate(emissions)]
    bus = can.Bus(interface="udp_multicast", channel="239.74.163.93", port=43393, fd=True)
    imu, gnss = PtyLink(SerialConfig(baudrate=460800)), PtyLink(SerialConfig(baudrate=115200))
    drain = [open(imu.dut_port, "rb", buffering=0), open(gnss.dut_port, "rb", buffering=0)]  # noqa: SIM115
    for fh in drain:
        import os

        os.set_blocking(fh.fileno(), False)
    late = np.empty(len(msgs), np.int64)
    start = time.monotonic_ns()
    try:
        for k, m in enumerate(can.MessageSync(msgs, timestamps=True, gap=0.0, skip=1e9)):
            now = time.monotonic_ns()
            late[k] = now - (start + round(m.timestamp * 1e9))
            _, kind, payload = emissions[m.arbitration_id]
            if kind == EMIT_CAN:
                f = payload
                bus.send(can.Message(arbitration_id=f.can_id, data=f.data, is_fd=f.fd, is_extended_id=False))
            elif kind == EMIT_IMU:
                imu.write(payload)
            else:
                gnss.write(payload)
            if k % 64 == 0:
                for fh in drain:
                    with contextlib.suppress(BlockingIOError):
                        fh.read(1 << 16)
    finally:
        bus.shutdown()
        for fh in drain:
            fh.close()
        imu.close()
        gnss.close()
    return late


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="real-time part over 10 s instead of 60 s")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        lockstep(out)
        external_lockstep(out)
        realtime(out, 10.0 if args.quick else 60.0)


if __name__ == "__main__":
    main()
