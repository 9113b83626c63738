"""An external DUT that opens its serial lines, reads nothing for ``lag_s`` (config), then
reads everything; at SIGTERM (or hang-up) it writes ``out`` (config): the bytes it read on
each line, as JSON ``{"imu": HEX_SHA256, "imu_bytes": N, ...}``. No CAN."""

from __future__ import annotations

import hashlib
import json
import os
import select
import signal
import sys
import time
from pathlib import Path


def main() -> int:
    args = dict(zip(sys.argv[1::2], sys.argv[2::2], strict=False))
    config = json.loads(Path(args["--config"]).read_text())
    fds = {name: os.open(args[f"--{name}"], os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK) for name in ("imu", "gnss")}
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    sums = {name: hashlib.sha256() for name in fds}
    counts = dict.fromkeys(fds, 0)
    print("lagging: opened, not reading yet", flush=True)
    t_read = time.monotonic() + float(config.get("lag_s", 1.0))
    while not stop and time.monotonic() < t_read:
        select.select([], [], [], 0.05)  # signals end the wait at once
    poller = select.poll()
    for fd in fds.values():
        poller.register(fd, select.POLLIN)
    try:
        while not stop:
            poller.poll(50)
            for name, fd in fds.items():
                try:
                    data = os.read(fd, 1 << 16)
                except BlockingIOError:
                    continue
                except OSError:  # the bench hung up
                    stop.append(1)
                    continue
                sums[name].update(data)
                counts[name] += len(data)
    finally:
        out = {name: sums[name].hexdigest() for name in fds} | {f"{n}_bytes": c for n, c in counts.items()}
        Path(config["out"]).write_text(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
