"""An external DUT that answers every BENCH_TIME a known time after it arrived, and says
when it sent each answer (the real-time latency tests).

    delayed.py --can-channel GROUP --can-port PORT --imu PTY --gnss PTY --config FILE

For every BENCH_TIME(T) it receives (udp_multicast, the bench's run tag from the
environment) it sends NAV_SOLUTION and NAV_QUALITY valid at T, ``delay_ms`` (config)
after the BENCH_TIME arrived; a fixed position, valid, epoch counter +1 per answer. It
reads and discards its serial lines. At SIGTERM (or when the bench hangs up) it writes
``stamps`` (config): one line per answer, ``T arrival_monotonic_ns sent_monotonic_ns``,
the arrival read right after the frame was received and the send right before it went
out, both on the host's CLOCK_MONOTONIC, which the bench's ``realtime_clock`` metadata
anchors to bench time.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time
from collections import deque
from pathlib import Path

import numpy as np

from bench.errors import LinkError
from bench.frames import CanBatch
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from bench.transport.can_link import CanConfig, open_can_link
from bench.transport.serial_link import SerialConfig, open_serial_link
from bench.transport.udp import RUN_TAG_ENV
from bench.wire.can import CanEncoder, codec

_BENCH_TIME = codec("BENCH_TIME")


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--can-channel", required=True)
    p.add_argument("--can-port", type=int, required=True)
    p.add_argument("--imu", required=True)
    p.add_argument("--gnss", required=True)
    p.add_argument("--config", required=True)
    args = p.parse_args()
    config = json.loads(Path(args.config).read_text())
    delay_ns = round(float(config.get("delay_ms", 3.0)) * 1e6)
    can = open_can_link(CanConfig(interface="udp_multicast", channel=args.can_channel,
                                  options={"port": args.can_port}), run_tag=os.environ.get(RUN_TAG_ENV, ""))
    lines = [open_serial_link(SerialConfig(port=args.imu, baudrate=460_800)),
             open_serial_link(SerialConfig(port=args.gnss, baudrate=115_200))]
    enc = CanEncoder(wire_range=True)
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    due: deque[tuple[int, int, int]] = deque()  # (send at, T, arrival), monotonic ns
    stamps: list[tuple[int, int, int]] = []
    epoch = 0
    print("delayed: listening", flush=True)
    try:
        while not stop:
            for link in lines:
                try:
                    link.read(0.0, 1 << 16)
                except (OSError, LinkError):
                    stop.append(1)  # the bench hung up
            now = time.monotonic_ns()
            wait = 0.002 if not due else max(0.0, min(0.002, (due[0][0] - now - 200_000) * 1e-9))
            got = can.drain(timeout=wait)
            arrival = time.monotonic_ns()
            bt = got.take(np.flatnonzero(got.can_id == _BENCH_TIME.frame_id)) if len(got) else got
            if len(bt):
                values, status = _BENCH_TIME.decode(bt)
                for t in values["time_ns"][status == 0].tolist():
                    due.append((arrival + delay_ns, int(t), arrival))
            while due and due[0][0] - time.monotonic_ns() < 200_000:
                at, t, arr = due.popleft()
                while time.monotonic_ns() < at:
                    pass
                sol = np.zeros(1, NAV_SOLUTION_DTYPE)
                sol["t_ns"], sol["epoch"], sol["valid"] = t, epoch % 256, 1
                sol["lat"], sol["lon"], sol["h"] = np.radians(34.24605), np.radians(108.90965), 380.0
                q = np.zeros(1, NAV_QUALITY_DTYPE)
                q["t_ns"], q["epoch"], q["sigma_pos"], q["sigma_vel"], q["sigma_att"] = t, epoch % 256, 1.0, 0.1, 1e-3
                frames = CanBatch.concat([enc.encode_records("NAV_SOLUTION", sol),
                                          enc.encode_records("NAV_QUALITY", q)])
                sent = time.monotonic_ns()
                can.send_many(frames)
                stamps.append((t, arr, sent))
                epoch += 1
    finally:
        Path(config["stamps"]).write_text("".join(f"{t} {a} {s}\n" for t, a, s in stamps))
        can.close()
        for link in lines:
            link.close()
        print(f"delayed: {len(stamps)} answers", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
