"""A stand-in for an external DUT: its own process, plain python-can and pyserial, the ICD.

It opens the IMU and GNSS serial ports it is given (the bench's pty slaves) and the CAN
bus, decodes what the bench sends with the bench's DUT-side decoders, and in lockstep
answers every BENCH_TIME(T) with a NAV_SOLUTION and a NAV_QUALITY for epoch T, then
DUT_READY(T), as ICD section 6 asks:

* time of validity T; heading the sum of the z angle increments of every IMU frame
  with a time of validity <= T (so the bench can check every increment crossed the pty);
* north velocity the speed of the last ODOMETER frame, east velocity the last DOPPLER
  speed (so both crossed the bus);
* latitude, longitude, height of the last BDS fix (NaN-free zeros before the first);
* NAV_QUALITY: the number of IMU frames so far in SigmaPosEast (0.01 m steps).

On SIGTERM, or after the BENCH_CMD "reset filter" (3), it prints a JSON summary of what
it received (fix epochs, counts by kind) on stdout and exits.
"""

from __future__ import annotations

import argparse
import json
import math
import select
import signal
import sys
import time

import can
import numpy as np
import serial

from bench.frames import CanBatch, CanFrame
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from bench.wire.can import CanEncoder
from bench.wire.imu_stream import ImuStreamDecoder
from bench.wire.nmea_stream import NmeaStreamDecoder
from bench.wire.receive import BenchTrafficDecoder

_stop = False


def _term(*_):
    global _stop
    _stop = True


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--can-interface", required=True)
    p.add_argument("--can-channel", required=True)
    p.add_argument("--can-port", type=int, default=43113)
    p.add_argument("--imu", required=True)
    p.add_argument("--gnss", required=True)
    a = p.parse_args()
    signal.signal(signal.SIGTERM, _term)
    kw = {"port": a.can_port} if a.can_interface == "udp_multicast" else {}
    bus = can.Bus(interface=a.can_interface, channel=a.can_channel, fd=True, **kw)
    imu_port = serial.Serial(a.imu, 460_800, timeout=0)
    gnss_port = serial.Serial(a.gnss, 115_200, timeout=0)
    imu_dec, gnss_dec, can_dec = ImuStreamDecoder(), NmeaStreamDecoder(), BenchTrafficDecoder()
    enc = CanEncoder()
    heading = 0.0
    imu_t = -1
    imu_frames = 0
    pending: list[tuple[int, float]] = []  # (t_ns, dtheta_z) of IMU samples not yet summed
    fixes: list[dict] = []
    last = {"odo": 0.0, "dop": 0.0, "lat": 0.0, "lon": 0.0, "h": 0.0}
    epoch = 0
    print(json.dumps({"ready": True}), flush=True)

    def read_serial() -> None:
        nonlocal imu_t, imu_frames
        for port, dec in ((imu_port, imu_dec), (gnss_port, gnss_dec)):
            data = port.read(port.in_waiting or 1)
            if not data:
                continue
            out = dec.feed(data)
            if dec is imu_dec and out.size:
                imu_frames += out.size
                imu_t = int(out["t_ns"][-1])
                pending.extend(zip(out["t_ns"].tolist(), out["dtheta"][:, 2].tolist(), strict=True))
            elif out.size:
                for f in out:
                    fixes.append(
                        {"utc_ns": int(f["utc_ns"]), "lat": float(f["lat"]), "lon": float(f["lon"]), "h": float(f["h"])}
                    )
                    last.update(lat=float(f["lat"]), lon=float(f["lon"]), h=float(f["h"]))

    while not _stop:
        msg = bus.recv(0.05)
        read_serial()
        if msg is None or msg.is_error_frame or msg.arbitration_id in (0x300, 0x301, 0x3F0):
            continue  # nothing, or our own frames (udp_multicast loops them back)
        decoded = can_dec.feed(CanBatch.from_frames([CanFrame(0, msg.arbitration_id, bytes(msg.data), msg.is_fd)]))
        if "ODOMETER" in decoded:
            last["odo"] = float(decoded["ODOMETER"]["speed"][-1])
        if "DOPPLER" in decoded:
            last["dop"] = float(decoded["DOPPLER"]["speed"][-1])
        if "BENCH_CMD" in decoded and int(decoded["BENCH_CMD"]["command"][-1]) == 3:
            break
        if "BENCH_TIME" not in decoded:
            continue
        t = int(decoded["BENCH_TIME"]["time_ns"][-1])
        deadline = time.monotonic() + 60.0  # a hang guard: the bench wrote them before BENCH_TIME(T)
        while imu_t < t and time.monotonic() < deadline:  # lockstep: all serial input up to T first
            select.select([imu_port, gnss_port], [], [], 0.01)
            read_serial()
        select.select([gnss_port], [], [], 0.002)
        read_serial()
        while pending and pending[0][0] <= t:
            heading += pending.pop(0)[1]
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        sol["t_ns"], sol["lat"], sol["lon"], sol["h"] = t, last["lat"], last["lon"], last["h"]
        sol["vel_n"] = (last["dop"], last["odo"], 0.0)
        sol["heading"] = heading % (2 * math.pi)
        sol["mode"], sol["valid"], sol["epoch"] = 5, 1, epoch % 256
        q = np.zeros(1, NAV_QUALITY_DTYPE)
        q["t_ns"], q["epoch"] = t, epoch % 256
        q["sigma_pos"] = (min(imu_frames, 65535) * 0.01, 0.0, 0.0)
        frames = CanBatch.concat(
            [
                enc.encode_records("NAV_SOLUTION", sol, at_ns=[t]),
                enc.encode_records("NAV_QUALITY", q, at_ns=[t]),
                enc.encode("DUT_READY", [t], time_ns=[t]),
            ]
        )
        for f in frames.frames():
            bus.send(
                can.Message(arbitration_id=f.can_id, data=f.data, is_fd=f.fd, bitrate_switch=f.fd, is_extended_id=False)
            )
        epoch += 1
    summary = {
        "fixes": fixes,
        "imu_frames": imu_frames,
        "epochs": epoch,
        "counts": {"imu": imu_dec.tally.as_dict(), "gnss": gnss_dec.tally.as_dict(), "can": can_dec.tally.as_dict()},
    }
    print(json.dumps(summary), flush=True)
    bus.shutdown()
    imu_port.close()
    gnss_port.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
