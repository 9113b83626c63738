"""What a DUT writes on its serial lines: how fast the bench drains a pty, and what an idle
line costs.

    .venv/bin/python benchmarks/bench_serial_rx.py

1. A writer thread pushes 64 MiB as fast as it can into the slave of a pty pair while a
   :class:`~bench.transport.serial_reader.SerialReader` drains the master and the main
   thread takes the chunks every 10 ms (as a lockstep run does after each step); prints
   MB/s, the chunks and whether every byte arrived in order. The ICD's fastest line
   (imu, 460800 baud) carries 46 kB/s.
2. Two readers on idle lines for 2 s: the CPU time they used (their 50 ms polls).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.transport.serial_link import SerialConfig, open_serial_link
from bench.transport.serial_reader import SerialReader

BLOCK = bytes(range(256)) * 256  # 64 KiB


def drain(total_mib: int = 64) -> None:
    with open_serial_link(SerialConfig(port="pty")) as link:
        fd = os.open(link.dut_port, os.O_WRONLY | os.O_NOCTTY)
        reader = SerialReader(link, time.monotonic_ns, name="imu")
        done = threading.Event()

        def write() -> None:
            for _ in range(total_mib * 16):
                view = memoryview(BLOCK)
                while view:
                    view = view[os.write(fd, view) :]
            done.set()

        t0 = time.perf_counter()
        threading.Thread(target=write, daemon=True).start()
        got, chunks, ok = 0, 0, True
        while True:
            finished = done.wait(0.01)
            batch = reader.take() if not finished else reader.close()
            data = batch.tobytes()
            ok &= data == (BLOCK * (len(data) // len(BLOCK) + 2))[got % len(BLOCK) : got % len(BLOCK) + len(data)]
            got += len(data)
            chunks += len(batch)
            if finished and got >= total_mib << 20:
                break
        el = time.perf_counter() - t0
        os.close(fd)
    print(f"1. {got / 2**20:.0f} MiB drained from a pty in {el:.2f} s: {got / el / 1e6:.0f} MB/s, "
          f"{chunks} chunks, every byte in order: {ok}")


def idle(seconds: float = 2.0) -> None:
    with open_serial_link(SerialConfig(port="pty")) as a, open_serial_link(SerialConfig(port="pty")) as b:
        c0 = time.thread_time(), time.process_time()
        readers = [SerialReader(a, time.monotonic_ns), SerialReader(b, time.monotonic_ns)]
        time.sleep(seconds)
        for r in readers:
            r.close()
        cpu = time.process_time() - c0[1] - (time.thread_time() - c0[0])
    print(f"2. two readers on idle lines for {seconds:g} s: {cpu * 1e3:.1f} ms of CPU ({cpu / seconds * 100:.3f} %)")


if __name__ == "__main__":
    drain()
    idle()
