"""An in-process DUT that kills the process it runs in (as a crashing native library or
the out-of-memory killer would) when its config says ``crash = true``; otherwise it
reports the origin, which the case's criteria FAIL."""

from __future__ import annotations

import os
import signal

import numpy as np

from bench.dut.estimator import Estimator, EstimatorOutput
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE


class Crash(Estimator):
    name = "crash"

    def configure(self, config):
        self.crash = bool(config.get("crash", False))

    def step(self, inputs):
        if self.crash:
            os.kill(os.getpid(), signal.SIGKILL)
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        q = np.zeros(1, NAV_QUALITY_DTYPE)
        sol["t_ns"] = q["t_ns"] = inputs.t_ns
        return EstimatorOutput(sol, q)
