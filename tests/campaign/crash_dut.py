"""An in-process DUT that kills the process it runs in (as a crashing native library or
the out-of-memory killer would) when its config says ``crash = true`` and the environment
has ``BENCH_TEST_CRASH_DUT=1`` (so that pytest collecting the case file runs it harmlessly);
otherwise it reports the origin at 100 Hz."""

from __future__ import annotations

import os
import signal

import numpy as np

from bench.dut.estimator import Estimator, EstimatorOutput
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE


class Crash(Estimator):
    name = "crash"

    def configure(self, config):
        self.crash = bool(config.get("crash", False)) and os.environ.get("BENCH_TEST_CRASH_DUT") == "1"

    def step(self, inputs):
        if self.crash:
            os.kill(os.getpid(), signal.SIGKILL)
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        q = np.zeros(1, NAV_QUALITY_DTYPE)
        sol["t_ns"] = q["t_ns"] = inputs.t_ns
        sol["valid"] = 1
        return EstimatorOutput(sol, q)
