"""The reference estimators on the real laser-gyro log against an independent alignment.

The whole PSINS log of test_cases/data (30.8 min, 100 Hz, a parked vehicle with its engine
running) is fed in process to seed000 and seed003 (S004's estimators, configured as S004
does: a navigation-grade RLG's class figures, 300 s alignment) in three ways:

* ``100 Hz / 10 ms``: the log's own frames, one a step (S004, `make demo`);
* ``200 Hz / 10 ms``: each sample split into two half-increments 5 ms apart (the same
  motion at twice the rate, two frames a step);
* ``100 Hz / 1 s``: the log's frames, a hundred a step.

For each it prints, in arcmin, the heading, pitch and roll minus the independent
inertial-frame alignment's (tests/independent/inertial_alignment.py, numpy only) with the
estimator's own 1-sigma in brackets, at the end of the alignment (300 s) and at the end of
the log, the largest |error| over the whole second epochs after the alignment (against the
alignment's 0.1 s track), and the largest horizontal distance from the surveyed point over
the log (position held, no aiding: the standstill's zero-velocity updates).

    .venv/bin/python benchmarks/real_lasergyro.py
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.dut.estimator import DutInputs, create_estimator  # noqa: E402
from bench.wire.imu import IMU_SAMPLE_DTYPE  # noqa: E402
from tests.independent.inertial_alignment import align, read_psins  # noqa: E402

LOG = ROOT / "test_cases" / "data" / "psins_lasergyro.imu"
AM = math.degrees(1.0) * 60.0
ALIGNED_S = 300.0
CONFIG = {"gyro_bias": "0.01 deg/h", "gyro_noise": "0.001 deg/sqrt(h)", "accel_bias": "100 ug",
          "accel_noise": "10 ug/sqrt(Hz)", "alignment": "300 s"}


def frames(split: int) -> np.ndarray:
    """The log's samples as IMU records, each split into ``split`` equal parts."""
    log = read_psins(LOG)
    n = len(log.dtheta) * split
    dt_ns = round(log.dt * 1e9) // split
    rec = np.zeros(n, IMU_SAMPLE_DTYPE)
    rec["t_ns"] = np.arange(1, n + 1, dtype=np.int64) * dt_ns
    rec["dtheta"] = np.repeat(log.dtheta / split, split, axis=0)
    rec["dvel"] = np.repeat(log.dvel / split, split, axis=0)
    rec["status"] = 0x3F
    return rec


def drive(name: str, rec: np.ndarray, per_step_ns: int) -> tuple[np.ndarray, np.ndarray]:
    """The estimator's epochs at whole seconds (solutions, qualities), steps of ``per_step_ns``."""
    log = read_psins(LOG)
    est = create_estimator(name, {"initial_position": [log.lat_deg, log.lon_deg, log.h], **CONFIG})
    sols, quals = [], []
    edges = np.searchsorted(rec["t_ns"], np.arange(per_step_ns, int(rec["t_ns"][-1]) + per_step_ns, per_step_ns),
                            side="right")
    start = 0
    for k, stop in enumerate(edges):
        part = rec[start:stop].copy()
        start = stop
        t = (k + 1) * per_step_ns
        part["rx_ns"] = t
        out = est.step(DutInputs(t, part, np.zeros(0), {}))
        if len(out.solutions):
            keep = out.solutions["t_ns"] % 1_000_000_000 == 0
            sols.append(out.solutions[keep])
            quals.append(out.qualities[keep])
    return np.concatenate(sols), np.concatenate(quals)


def _at(e: np.ndarray, s: np.ndarray, i: int) -> str:
    return " / ".join(f"{e[i, j]:+.2f} ({s[i, j]:.2f})" for j in range(3))


def main() -> int:
    log = read_psins(LOG)
    t_ref, ref = align(log, 0.1)
    lat0, lon0 = math.radians(log.lat_deg), math.radians(log.lon_deg)
    print(f"{LOG.name}: {len(log.dtheta)} samples, {len(log.dtheta) * log.dt:.0f} s; errors against the independent "
          "alignment in arcmin, the estimator's sigma in brackets")
    print(f"{'estimator':10} {'rate / step':14} {'at 300 s: heading / pitch / roll':38} "
          f"{'at the end: heading / pitch / roll':38} {'max |err| after 300 s':24} {'held':>8}")
    for name in ("seed000", "seed003"):
        for label, split, step_ns in (("100 Hz / 10 ms", 1, 10_000_000), ("200 Hz / 10 ms", 2, 10_000_000),
                                      ("100 Hz / 1 s", 1, 1_000_000_000)):
            sol, qual = drive(name, frames(split), step_ns)
            v = sol["valid"] == 1
            sol, qual = sol[v], qual[v]
            t = sol["t_ns"] * 1e-9
            want = np.column_stack([np.interp(t, t_ref, ref[:, i]) for i in range(3)])
            e = np.column_stack([sol["heading"], sol["pitch"], sol["roll"]]) - want
            e[:, 0] = (e[:, 0] + math.pi) % (2 * math.pi) - math.pi
            e *= AM
            s = qual["sigma_att"] * AM
            i0 = int(np.searchsorted(t, ALIGNED_S))


            worst = np.abs(e[i0:]).max(axis=0)
            east = (sol["lon"] - lon0) * 6.38e6 * math.cos(lat0)
            north = (sol["lat"] - lat0) * 6.36e6
            held = float(np.hypot(east, north).max())
            print(f"{name:10} {label:14} {_at(e, s, i0):38} {_at(e, s, len(e) - 1):38} "
                  f"{' / '.join(f'{w:.2f}' for w in worst):24} {held:7.3f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
