"""An external DUT that writes where the bench does not expect it, for the run tests.

The reference harness (:mod:`bench.dut.harness`) around an estimator that answers one
NAV_SOLUTION per step and, from its configuration file (``{config}``)::

    serial        at bench time ``at_s`` write ``imu_bytes`` bytes on its imu line and
                  ``gnss_bytes`` on its gnss line (:func:`pattern`), blocking until the
                  bench has taken them all, then go on
    hostile_text  at ``at_s`` write terminal escapes, markup, NUL and pipes on stderr
                  (:data:`HOSTILE`), then exit with code 3

The serial lines are opened a second time by path (the harness holds them too), from the
``--imu``/``--gnss`` arguments of the command line.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from bench.dut import harness
from bench.dut.estimator import DutInputs, Estimator, EstimatorOutput, register_estimator
from bench.topics import NAV_SOLUTION_DTYPE

HOSTILE = ("\x1b[31mRED\x1b[0m \x1b]0;pwned\x07 \x1b[2J <script>alert(1)</script> ]]> a|b \x00 nul "
           "& <![CDATA[x]]> `code` \u202eevil")


def pattern(n: int, seed: int) -> bytes:
    """``n`` bytes that show any loss, duplication or reordering."""
    return bytes((i * 7 + seed) % 251 for i in range(n))


def _port(flag: str) -> str:
    return sys.argv[sys.argv.index(flag) + 1]


def _write_all(path: str, data: bytes) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_NOCTTY)  # blocking: waits while the line is full
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view[:65536]) :]
    finally:
        os.close(fd)


class Talker(Estimator):
    name = "talker"

    def configure(self, config):
        self.mode = config["mode"]
        self.at_ns = round(float(config.get("at_s", 0.5)) * 1e9)
        self.imu_bytes = int(config.get("imu_bytes", 0))
        self.gnss_bytes = int(config.get("gnss_bytes", 0))
        self.done = False
        self.epoch = 0

    def step(self, inputs: DutInputs) -> EstimatorOutput:
        t = inputs.t_ns
        if t >= self.at_ns and not self.done:
            self.done = True
            if self.mode == "serial":
                _write_all(_port("--imu"), pattern(self.imu_bytes, 3))
                _write_all(_port("--gnss"), pattern(self.gnss_bytes, 5))
                print(f"talker: wrote {self.imu_bytes} + {self.gnss_bytes} bytes", flush=True)
            elif self.mode == "hostile_text":
                print(f"talker: {HOSTILE}", file=sys.stderr, flush=True)
                sys.exit(3)
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = t
        sol["epoch"] = self.epoch % 256
        self.epoch += 1
        return EstimatorOutput(sol)


if __name__ == "__main__":
    register_estimator("talker", Talker)
    sys.exit(harness.main())
