"""Two processes: the bench here, a stand-in external DUT (external_dut.py) in its own process.

The DUT gets IMU frames and NMEA sentences on two pty pairs the bench creates and CAN
traffic on a bus, and answers each lockstep BENCH_TIME(T) with NAV_SOLUTION,
NAV_QUALITY and DUT_READY(T). The bus is python-can ``udp_multicast`` inside a network
namespace the test creates (works in CI), and SocketCAN ``vcan0`` where it exists.
"""

from __future__ import annotations

import json
import math
import select
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from bench.frames import CanBatch
from bench.transport.can_link import CanConfig, CanLink, open_can_link, socketcan_unavailable
from bench.transport.serial_link import PtyLink, SerialConfig
from bench.wire import imu
from bench.wire.can import CanEncoder
from bench.wire.nmea import GNSS_FIX_DTYPE, encode_epochs
from bench.wire.receive import NavReceiver
from tests.transport import netns

DUT = Path(__file__).with_name("external_dut.py")
EPOCH_UTC = 1_748_736_000 * 10**9
STEPS = 250  # 2.5 s of bench time in 10 ms lockstep steps
MS = 1_000_000
HANG_S = 60.0  # hang guard of every wait for the DUT (start, each step, exit), s; never a speed bound


def _traffic():
    rng = np.random.default_rng(2024)
    t_imu = np.arange(1, STEPS * 2 + 1) * 5 * MS
    n = t_imu.size
    imu_frames = imu.encode_frames(
        t_imu, rng.normal(0, 2e-3, (n, 3)), rng.normal(0, 5e-2, (n, 3)), 0x3F, 31.5, np.arange(n) % 256
    )
    enc = CanEncoder()
    t10 = np.arange(1, STEPS + 1) * 10 * MS
    t20 = t10[1::2]
    odo_speed = 10 + rng.normal(0, 1, t10.size)
    dop_speed = 10 + rng.normal(0, 1, t20.size)
    can_frames = CanBatch.concat(
        [
            enc.encode("BENCH_EPOCH", [0], epoch_utc_ns=[EPOCH_UTC]),
            enc.encode(
                "ODOMETER", t10 - 3 * MS, pulse_count=np.arange(t10.size) * 11, speed=odo_speed, reverse=0, valid=1
            ),
            enc.encode("DOPPLER", t20 - 7 * MS, speed=dop_speed, quality=220, valid=1, low_signal=0),
        ]
    ).sorted()
    fixes = np.zeros(3, GNSS_FIX_DTYPE)
    fixes["t_ns"] = np.arange(3) * 1000 * MS
    fixes["utc_ns"] = EPOCH_UTC + fixes["t_ns"]
    fixes["lat"] = np.radians(34.246 + rng.normal(0, 1e-4, 3))
    fixes["lon"] = np.radians(108.909 + rng.normal(0, 1e-4, 3))
    fixes["h"] = 380 + rng.normal(0, 1, 3)
    fixes["vel_n"] = rng.normal(0, 3, (3, 3))
    fixes[["sigma_lat", "sigma_lon", "sigma_alt"]] = (2.0, 1.5, 3.0)
    fixes["sats"], fixes["hdop"], fixes["quality"] = 14, 0.8, 1
    nmea = encode_epochs(fixes, at_ns=fixes["t_ns"] + 80 * MS)
    return t_imu, imu_frames, can_frames, nmea, fixes, (t10 - 3 * MS, odo_speed), (t20 - 7 * MS, dop_speed)


def _run(can_link: CanLink, dut_cmd_prefix: list[str], can_args: list[str]) -> None:
    t_imu, imu_frames, can_frames, nmea, fixes, odo, dop = _traffic()
    with PtyLink(SerialConfig(baudrate=460_800)) as imu_link, PtyLink(SerialConfig(baudrate=115_200)) as gnss_link:
        cmd = [
            *dut_cmd_prefix,
            sys.executable,
            str(DUT),
            *can_args,
            "--imu",
            imu_link.dut_port,
            "--gnss",
            gnss_link.dut_port,
        ]
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            ready, _, _ = select.select([proc.stdout], [], [], HANG_S)
            assert ready and json.loads(proc.stdout.readline()) == {"ready": True}, proc.stderr.read()
            receiver = NavReceiver()
            enc = CanEncoder()
            solutions, qualities = [], []
            sent_imu = sent_can = sent_nmea = 0
            for k in range(1, STEPS + 1):
                T = k * 10 * MS
                n_nmea = int(np.searchsorted(nmea.t_ns, T, side="right"))
                if n_nmea > sent_nmea:
                    gnss_link.write_many(nmea.take(np.arange(sent_nmea, n_nmea)))
                    sent_nmea = n_nmea
                n_imu = int(np.searchsorted(t_imu, T, side="right"))
                imu_link.write(imu_frames[sent_imu:n_imu].tobytes())
                sent_imu = n_imu
                n_can = int(np.searchsorted(can_frames.t_ns, T, side="right"))
                can_link.send_many(can_frames.take(np.arange(sent_can, n_can)))
                sent_can = n_can
                can_link.send_many(enc.encode("BENCH_TIME", [T], time_ns=[T], lockstep=1))
                deadline = time.monotonic() + HANG_S
                while True:  # lockstep: wait for DUT_READY >= T
                    out = receiver.feed(can_link.drain(timeout=0.5))
                    solutions.append(out.solutions)
                    qualities.append(out.qualities)
                    if out.ready_ns.size and out.ready_ns.max() >= T:
                        break
                    assert time.monotonic() < deadline and proc.poll() is None, (
                        f"no DUT_READY({T}) within {HANG_S:g} s: "
                        f"{proc.stderr.read() if proc.poll() is not None else ''}"
                    )
            can_link.send_many(enc.encode("BENCH_CMD", [STEPS * 10 * MS + 1], command=[3]))
            stdout, stderr = proc.communicate(timeout=HANG_S)
        finally:
            if proc.poll() is None:
                proc.terminate()
                proc.wait(HANG_S)
    assert proc.returncode == 0, stderr
    report = json.loads(stdout.strip().splitlines()[-1])
    sol, qual = np.concatenate(solutions), np.concatenate(qualities)

    # the DUT saw every byte and frame intact
    assert report["counts"] == {"imu": {}, "gnss": {}, "can": {}}
    assert report["imu_frames"] == STEPS * 2 and report["epochs"] == STEPS
    assert [f["utc_ns"] for f in report["fixes"]] == fixes["utc_ns"].tolist()
    np.testing.assert_allclose([f["lat"] for f in report["fixes"]], fixes["lat"], atol=math.radians(1e-5 / 60))
    # and the bench got every answer back intact, in lockstep
    assert receiver.tally.as_dict() == {}
    T = np.arange(1, STEPS + 1) * 10 * MS
    np.testing.assert_array_equal(sol["t_ns"], T)
    np.testing.assert_array_equal(qual["t_ns"], T)
    np.testing.assert_array_equal(sol["epoch"], np.arange(STEPS) % 256)
    rec = imu_frames.view(imu.FRAME_DTYPE).reshape(-1)
    dz = np.cumsum(rec["dtheta"][:, 2] * imu.DTHETA_LSB)
    want_heading = np.mod(dz[np.searchsorted(t_imu, T, side="right") - 1], 2 * math.pi)
    err = (sol["heading"] - want_heading + math.pi) % (2 * math.pi) - math.pi
    assert np.max(np.abs(err)) <= math.radians(0.5e-7) + 1e-12
    np.testing.assert_allclose(qual["sigma_pos"][:, 0], np.searchsorted(t_imu, T, side="right") * 0.01, atol=1e-9)
    odo_last = odo[1][np.searchsorted(odo[0], T, side="right") - 1]
    np.testing.assert_allclose(sol["vel_n"][:, 1], odo_last, atol=0.005 + 0.5e-4)
    dop_idx = np.searchsorted(dop[0], T, side="right") - 1
    np.testing.assert_allclose(sol["vel_n"][dop_idx >= 0, 0], dop[1][dop_idx[dop_idx >= 0]], atol=0.5e-4 + 0.5e-4)
    fix_idx = np.searchsorted(fixes["t_ns"] + 80 * MS, T, side="right") - 1
    has = fix_idx >= 0
    np.testing.assert_allclose(sol["lat"][has], fixes["lat"][fix_idx[has]], atol=math.radians(1e-5 / 60 + 1e-7))


@pytest.mark.slow
def test_external_dut_over_udp_multicast_in_a_netns():
    reason = netns.unavailable()
    if reason:
        pytest.skip(f"udp_multicast between processes needs a network namespace: {reason}")
    with netns.multicast_netns() as ns:
        cfg = CanConfig(interface="udp_multicast", channel="239.74.163.3", options={"port": 43300})
        link = netns.call_in(ns, lambda: open_can_link(cfg))
        try:
            _run(
                link,
                ["ip", "netns", "exec", ns],
                ["--can-interface", "udp_multicast", "--can-channel", "239.74.163.3", "--can-port", "43300"],
            )
            stats = link.stats()
            assert stats["drops"] == 0 and stats["untagged"] == 3 * STEPS  # the DUT's frames, plain python-can
        finally:
            link.close()


@pytest.mark.slow
@pytest.mark.hardware
def test_external_dut_over_vcan():
    reason = socketcan_unavailable("vcan0")
    if reason:
        pytest.skip(reason)
    with CanLink(CanConfig(interface="socketcan", channel="vcan0")) as link:
        _run(link, [], ["--can-interface", "socketcan", "--can-channel", "vcan0"])
