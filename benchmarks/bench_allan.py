"""How well ``bench imu allan`` reads the bench's own IMU grades back, over seeds.

For each grade, static logs through the bench's IMU model (``static_log``): a short one
at 200 Hz (quantization and random walks; what is not resolved in it) and a long one at
1 Hz (bias instability, rate random walk), as tests/sensors/test_allan.py uses them, for
seeds 1..S. Prints, per sensor and term, the fitted / configured ratio over all axes and
seeds (mean, sigma, min, max), how many were resolved, and how many axes would fail the
test's 10 % (rate random walk: 20 % per axis).

Run: ``.venv/bin/python benchmarks/bench_allan.py [SEEDS]`` (default 4; about a minute
of CPU per seed).
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from bench.sensors.allan import TERMS
from bench.sensors.imu.analysis import analyse
from bench.sensors.imu.grade import load_grade
from bench.sensors.imu.logs import static_log

RUNS = [
    ("navigation", 200.0, 1000.0),
    ("navigation", 1.0, 3_000_000.0),
    ("tactical", 200.0, 1000.0),
    ("tactical", 1.0, 500_000.0),
    ("mems", 200.0, 1000.0),
    ("mems", 1.0, 3_000_000.0),
]


def configured(grade, sensor: str, term: str) -> float:
    e = grade.gyro if sensor == "gyro" else grade.accel
    return {
        "quantization": e.quantization / math.sqrt(12.0),
        "random_walk": float(e.noise[0]),
        "bias_instability": float(e.bias_instability[0]),
        "rate_random_walk": float(e.bias_random_walk[0]),
        "rate_ramp": 0.0,
    }[term]


def main(seeds: int) -> None:
    for name, rate, duration in RUNS:
        grade = load_grade(name)
        ratios: dict[tuple[str, str], list[float]] = {}
        false: dict[tuple[str, str], int] = {}
        started = time.process_time()
        for seed in range(1, seeds + 1):
            rep = analyse(static_log(name, rate, duration, seed=seed))
            for sensor in ("gyro", "accel"):
                for term in TERMS:
                    want = configured(grade, sensor, term)
                    for ax in range(3):
                        got = rep.value(sensor, ax, term)
                        if want > 0.0:
                            ratios.setdefault((sensor, term), []).append(np.nan if got is None else got / want)
                        elif got is not None:
                            false[(sensor, term)] = false.get((sensor, term), 0) + 1
        cpu = (time.process_time() - started) / seeds
        print(f"\n{name} at {rate:g} Hz, {duration:g} s, {seeds} seeds ({cpu:.1f} s CPU per log)")
        head = ("sensor", "term", "resolved", "mean", "sigma", "min", "max", ">tol")
        print("  {:<6} {:<18} {:>9} {:>7} {:>7} {:>7} {:>7} {:>5}".format(*head))
        for (sensor, term), v in ratios.items():
            arr = np.array(v)
            ok = arr[np.isfinite(arr)]
            tol = 0.20 if term == "rate_random_walk" else 0.10
            bad = int(np.sum(np.abs(ok - 1.0) > tol))
            stats = (f"{ok.mean():7.3f} {ok.std():7.3f} {ok.min():7.3f} {ok.max():7.3f}" if len(ok)
                     else f"{'-':>7} {'-':>7} {'-':>7} {'-':>7}")
            print(f"  {sensor:<6} {term:<18} {len(ok):>4}/{len(arr):<4} {stats} {bad:>5}")
        for (sensor, term), k in false.items():
            print(f"  {sensor:<6} {term:<18} reported on {k} axes although the grade has none")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 4)
