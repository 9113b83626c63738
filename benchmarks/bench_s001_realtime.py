"""Closed-loop S001 with the seed-001 estimator in process: how many times real time.

S001 (the 20 min urban drive with two 60 s BDS outages; navigation-grade IMU at 200 Hz,
BDS 1 Hz on the GNSS line, odometer on CAN, 100 Hz output) in lockstep 10 ms steps, every
link encoded and decoded, the full recording, scoring not included, seed 1: the
decode-only DUT (the bench's own cost: every frame encoded, decoded on the DUT side, the
output encoded, received, decoded, recorded), then seed001 in its ``full`` and
``map_matched`` variants; the estimator's own share is the difference. The drive's
trajectory is built once, outside the timed runs; the estimator's warm-up (its numba
kernel compiled or loaded) is part of each run. Target (issue 13): at least 200x real
time per variant. ``--profile`` adds, per variant, where the time goes (cProfile, the
functions with the most time of their own, and the run's main phases).

    .venv/bin/python benchmarks/bench_s001_realtime.py [--duration S] [--repeat N] [--profile]
        [--variants full,map_matched]

Figures are meaningful on a quiet machine only (the fastest of ``--repeat`` runs is
printed, and the CPU seconds beside the wall seconds, which a loaded machine stretches
more).
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import io
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.acceptance.case import TestCase, load_case  # noqa: E402
from bench.run.case_runner import spec_from_case  # noqa: E402
from bench.run.engine import run  # noqa: E402

CASE = ROOT / "test_cases" / "S001_bds_sins.toml"
TARGET = 200.0
#: cumulative time of these functions: where a run's wall time goes, phase by phase
PHASES = {
    "sensors + wire (bench side)": ("bench/run/provider.py", "window"),
    "DUT-side decoding": ("bench/dut/inputs.py", "feed"),
    "estimator steps": (None, "step"),
    "NAV output encoding": ("bench/run/inprocess.py", "_frames"),
    "recording": ("bench/record/", None),
}


def _case(variant: str) -> TestCase:
    case = load_case(CASE)
    if variant == "decode_only":
        full = case.for_variant("full")
        return dataclasses.replace(full, dut=dataclasses.replace(full.dut, name="decode_only", config={}))
    return case.for_variant(variant)


def timed(variant: str, out: Path, duration_s: float | None, trajectories: dict,
          profile: bool) -> tuple[str, float, float, float, pstats.Stats | None]:
    """One run of S001's ``variant`` (seed 1): status, bench seconds, wall and CPU seconds
    (of this process, every thread), profile."""
    spec = spec_from_case(_case(variant), 1, out)
    if "s001" not in trajectories:
        trajectories["s001"] = spec.scenario.trajectory()
    traj = trajectories["s001"]
    dur_ns = round(duration_s * 1e9) if duration_s is not None else spec.duration_ns
    spec = dataclasses.replace(spec, duration_ns=dur_ns, trajectory=traj)
    prof = cProfile.Profile() if profile else None
    t, c = time.perf_counter(), time.process_time()
    if prof is not None:
        prof.enable()
    res = run(spec)
    if prof is not None:
        prof.disable()
    el, cpu = time.perf_counter() - t, time.process_time() - c
    simulated = (dur_ns if dur_ns is not None else traj.duration_ns) / 1e9
    status = res.status if res.status == "complete" else f"{res.status}: {res.reason}"
    return status, simulated, el, cpu, (pstats.Stats(prof) if prof is not None else None)


def _summary(stats: pstats.Stats, wall: float, top: int = 12) -> str:
    """The run's phases (cumulative) and the functions with the most time of their own."""
    lines = []
    cum: dict[str, float] = {}
    for (path, _, func), (_, _, tt, ct, _) in stats.stats.items():  # type: ignore[attr-defined]
        rel = path.replace(str(ROOT) + "/", "")
        for phase, (where, name) in PHASES.items():
            if (where is None or rel.startswith(where)) and (name is None or func == name) and \
                    (where is not None or rel.startswith("bench/estimators/")):
                cum[phase] = max(cum.get(phase, 0.0), ct) if name is not None else cum.get(phase, 0.0) + tt
    for phase, sec in cum.items():
        lines.append(f"      {phase:<30} {sec:6.2f} s  {100 * sec / wall:5.1f} %")
    buf = io.StringIO()
    stats.stream = buf  # type: ignore[attr-defined]
    stats.sort_stats("tottime").print_stats(top)
    body = buf.getvalue().splitlines()
    start = next((i for i, line in enumerate(body) if line.strip().startswith("ncalls")), 0)
    lines.append("      top functions by own time:")
    lines += ["      " + line.replace(str(ROOT) + "/", "") for line in body[start:] if line.strip()]
    return "\n".join(lines)


def _commit() -> str:
    try:
        return subprocess.run(["git", "-C", str(ROOT), "describe", "--always", "--dirty"], capture_output=True,
                              text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "?"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=None, help="bench seconds of S001 to run (default: all)")
    ap.add_argument("--variants", default="full,map_matched", help="comma-separated S001 variants")
    ap.add_argument("--repeat", type=int, default=1, help="runs per variant; the fastest is printed (default 1)")
    ap.add_argument("--profile", action="store_true", help="profile each run (cProfile; slows it down)")
    args = ap.parse_args()
    variants = ["decode_only", *[v for v in args.variants.split(",") if v]]
    print(f"S001 closed loop in process, lockstep 10 ms steps, seed 1, commit {_commit()}, fastest of "
          f"{args.repeat}{' (profiled: figures slowed by cProfile)' if args.profile else ''}")
    trajectories: dict = {}
    base = None
    with tempfile.TemporaryDirectory() as tmp:
        timed("full", Path(tmp) / "warm", 1.0, trajectories, False)  # the drive's trajectory, numba's cache
        for v in variants:
            runs = [timed(v, Path(tmp) / f"{v}{i}", args.duration, trajectories, args.profile)
                    for i in range(max(1, args.repeat))]
            status, sim, el, cpu, stats = min(runs, key=lambda r: r[2])
            if status != "complete":
                print(f"   {v:<14} NOT MEASURED, the run did not complete ({status})")
                continue
            x = sim / el
            line = f"   {v:<14} {sim:5.0f} s simulated in {el:6.2f} s wall ({cpu:6.2f} s CPU)  {x:5.0f}x real time"
            if v == "decode_only":
                base = el
                print(f"{line}  (the bench's own cost)")
            else:
                own = f"  own share {el - base:5.2f} s" if base is not None else ""
                verdict = "MET" if x >= TARGET else "MISSED"
                print(f"{line}{own};  target >= {TARGET:.0f}x {verdict}")
            if stats is not None:
                print(_summary(stats, el))


if __name__ == "__main__":
    main()
