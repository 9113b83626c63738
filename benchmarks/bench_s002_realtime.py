"""Closed-loop S002 with the seed-002 estimator in process: how many times real time.

S002 (the 1685 s tracked-vehicle drive of seed 002 with its five odometer faults; the
TrackedVehicle FMU at 1 ms, the seed's IMU at 200 Hz on the IMU line, odometer and driver
input on CAN, 100 Hz output) in lockstep, every link encoded and decoded, the full
recording, scoring not included, seed 1. Timed apart and together:

- the plant: the FMU driven through the command timeline at 1 ms (the trajectory every
  run of the drive shares, built once per scenario and seed-independent);
- the run with the decode-only DUT (the bench's own cost: every frame encoded, decoded on
  the DUT side, the output encoded, received, decoded, recorded);
- the run with seed002 in its ``with_detection`` and ``without_detection`` variants (the
  estimator's warm-up, its numba kernel compiled or loaded, included).

Closed loop = plant + run. Target (issue 14): at least 100x real time. Figures are
meaningful on a quiet machine only (the fastest of ``--repeat`` is printed; the CPU
seconds beside the wall seconds, which a loaded machine stretches more).

    .venv/bin/python benchmarks/bench_s002_realtime.py [--repeat N] [--duration S]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.acceptance.case import TestCase, load_case  # noqa: E402
from bench.run.case_runner import spec_from_case  # noqa: E402
from bench.run.engine import run  # noqa: E402
from benchmarks.bench_s001_realtime import _commit  # noqa: E402

CASE = ROOT / "test_cases" / "S002_sins_odometer_faults.toml"
TARGET = 100.0


def _case(variant: str) -> TestCase:
    case = load_case(CASE)
    if variant == "decode_only":
        full = case.for_variant("with_detection")
        return dataclasses.replace(full, dut=dataclasses.replace(full.dut, name="decode_only", config={}))
    return case.for_variant(variant)


def _plant(out: Path) -> tuple[object, float, float]:
    """The drive's trajectory through the FMU: (trajectory, wall s, CPU s)."""
    spec = spec_from_case(_case("with_detection"), 1, out)
    t, c = time.perf_counter(), time.process_time()
    traj = spec.scenario.trajectory()
    return traj, time.perf_counter() - t, time.process_time() - c


def _timed(variant: str, out: Path, traj: object, duration_s: float | None) -> tuple[str, float, float, float]:
    spec = spec_from_case(_case(variant), 1, out)
    dur_ns = round(duration_s * 1e9) if duration_s is not None else spec.duration_ns
    spec = dataclasses.replace(spec, duration_ns=dur_ns, trajectory=traj)
    t, c = time.perf_counter(), time.process_time()
    res = run(spec)
    el, cpu = time.perf_counter() - t, time.process_time() - c
    sim = (dur_ns if dur_ns is not None else traj.duration_ns) / 1e9  # type: ignore[attr-defined]
    status = res.status if res.status == "complete" else f"{res.status}: {res.reason}"
    return status, sim, el, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs of each; the fastest is printed (default 1)")
    ap.add_argument("--duration", type=float, default=None, help="bench seconds of the runs (default: all)")
    args = ap.parse_args()
    n = max(1, args.repeat)
    print(f"S002 closed loop in process, lockstep, seed 1, commit {_commit()}, fastest of {n}")
    with tempfile.TemporaryDirectory() as tmp:
        plants = [_plant(Path(tmp) / f"plant{i}") for i in range(n)]
        traj, p_el, p_cpu = min(plants, key=lambda r: r[1])
        total = traj.duration_ns / 1e9  # type: ignore[attr-defined]
        print(f"   plant (FMU, 1 ms)   {total:5.0f} s simulated in {p_el:6.2f} s wall ({p_cpu:6.2f} s CPU)  "
              f"{total / p_el:5.0f}x real time")
        _timed("with_detection", Path(tmp) / "warm", traj, 1.0)  # numba's cache
        base = None
        for v in ("decode_only", "with_detection", "without_detection"):
            runs = [_timed(v, Path(tmp) / f"{v}{i}", traj, args.duration) for i in range(n)]
            status, sim, el, cpu = min(runs, key=lambda r: r[2])
            if status != "complete":
                print(f"   {v:<19} NOT MEASURED, the run did not complete ({status})")
                continue
            line = f"   {v:<19} {sim:5.0f} s simulated in {el:6.2f} s wall ({cpu:6.2f} s CPU)  {sim / el:5.0f}x"
            if v == "decode_only":
                base = el
                print(f"{line}  (the bench's own cost)")
                continue
            own = f", own share {el - base:5.2f} s" if base is not None else ""
            closed = sim / (el + p_el * sim / total)
            verdict = "MET" if closed >= TARGET else "MISSED"
            print(f"{line}{own}; closed loop with the plant {closed:5.0f}x real time, target >= {TARGET:.0f}x "
                  f"{verdict}")


if __name__ == "__main__":
    main()
