"""A stand-in for a hardware DUT: a unit already on its links that the bench does not start.

    python hardware_unit.py --channel GROUP --config CONFIG.json

It makes two serial lines, each a pair of pseudo-terminals joined by a relay (the bench's
end and the unit's end, as a USB-serial adapter and the unit's UART), prints the bench's
ends as one JSON line (``{"imu": "/dev/pts/N", "gnss": "/dev/pts/M"}``), and runs the
misbehaving test DUT (tests/run/duts/misbehave.py, the bench's reference harness) on the
unit's ends and on udp_multicast group GROUP. When the unit dies the relay keeps the
bench's ends open and drops what the bench writes, as a serial line to a dead unit does:
the bench sees a unit that went silent, never a lost link. It ends on SIGTERM (the test
stops it) or when its standard input closes.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import select
import signal
import subprocess
import sys
import tty
from pathlib import Path

MISBEHAVE = Path(__file__).resolve().parent.parent / "run" / "duts" / "misbehave.py"


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--channel", required=True)
    p.add_argument("--config", required=True)
    args = p.parse_args()
    ends: dict[str, str] = {}
    unit: dict[str, str] = {}
    joins: dict[int, int] = {}  # master fd -> the master fd its bytes go to
    keep = []
    for name in ("imu", "gnss"):
        bench_m, bench_s = os.openpty()
        unit_m, unit_s = os.openpty()
        for fd in (bench_s, unit_s):
            tty.setraw(fd)
        ends[name], unit[name] = os.ttyname(bench_s), os.ttyname(unit_s)
        joins[bench_m], joins[unit_m] = unit_m, bench_m
        keep += [bench_s, unit_s]  # open here too: a side's close is no hang-up of the line
    print(json.dumps(ends), flush=True)
    child = subprocess.Popen([sys.executable, str(MISBEHAVE), "--estimator", "misbehave", "--can-interface",
                              "udp_multicast", "--can-channel", args.channel, "--imu", unit["imu"], "--gnss",
                              unit["gnss"], "--config", args.config])
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    unit_fds = {joins[b] for b in list(joins)[::2]}  # the unit's masters (joins holds bench, unit, bench, unit)
    while not stop:
        try:
            ready, _, _ = select.select([*joins, sys.stdin], [], [], 0.2)
        except InterruptedError:
            continue
        if sys.stdin in ready and not os.read(sys.stdin.fileno(), 4096):
            break
        dead = child.poll() is not None
        for fd in ready:
            if fd is sys.stdin:
                continue
            try:
                data = os.read(fd, 65536)
            except OSError:
                continue
            if data and not (dead and fd not in unit_fds):  # a dead unit takes nothing
                with contextlib.suppress(OSError):
                    os.write(joins[fd], data)
    if child.poll() is None:
        child.terminate()
        try:
            child.wait(timeout=30)
        except subprocess.TimeoutExpired:
            child.kill()
    return 0


if __name__ == "__main__":
    sys.exit(main())
