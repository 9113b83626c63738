"""Closed-loop S000 with the reference estimator: in process and as an external process.

S000 (3600 s, 50.6 km, seed-000 IMU at 200 Hz, Doppler 50 Hz, 100 Hz output) in
lockstep, every link encoded and decoded, the full recording, scoring not included. Side
by side in one run, on the same seed:

1. In process (10 ms steps, the S000 case's clock): the decode-only DUT (the bench's own
   cost: every frame encoded, decoded on the DUT side, the output encoded, received,
   decoded, recorded) and the estimator in each of its modes; the estimator's own share
   is the difference. Target: at least 200x real time (at most 18 s) per mode.
2. As an external process (the S000-external case: ``{python} -m bench.dut.harness``
   over a pty and CAN on udp_multicast, 1 s lockstep steps): the decode-only harness and
   the estimator's. Target: at least 40x real time (at most 90 s). udp_multicast runs on
   the loopback of the machine's own network namespace (the bench's and the harness's
   sockets join the group on 127.0.0.1; no root needed), as ``bench accept`` runs it.

The estimator is ``seed000`` (both modes) where it is installed, else ``dead_reckoning``
(printed). Figures are meaningful on a quiet machine only.

    .venv/bin/python benchmarks/bench_estimators.py [--duration S]
"""

from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.acceptance.case import TestCase, load_case  # noqa: E402
from bench.dut.estimator import known_estimators  # noqa: E402
from bench.run.case_runner import spec_from_case  # noqa: E402
from bench.run.engine import run  # noqa: E402

EXTERNAL = ROOT / "test_cases" / "S000_external.toml"
IN_PROCESS = ROOT / "test_cases" / "S000_sins_doppler.toml"
MODES = ("attitude_position", "velocity_position")
TARGET_IN_PROCESS = 200.0
TARGET_EXTERNAL = 40.0


def _estimator() -> str:
    return "seed000" if "seed000" in known_estimators() else "dead_reckoning"


def in_process_cases(estimator: str) -> list[tuple[str, TestCase]]:
    """(label, case) of the in-process rows: S000's own variants when S000 runs the
    estimator in process, else S000-external's configuration in process."""
    s000 = load_case(IN_PROCESS)
    if s000.dut.kind == "in_process" and s000.dut.name == estimator:
        rows = [(f"{estimator} {v}", s000.for_variant(v)) for v in s000.variants()]
    else:
        ext = load_case(EXTERNAL)
        dut = dataclasses.replace(ext.dut, kind="in_process", name=estimator, command=None)
        base = dataclasses.replace(ext, dut=dut, clock=s000.clock)
        rows = [(estimator, base)]
        if estimator == "seed000":
            rows = [(f"{estimator} {m}", _with_config(base, mode=m)) for m in MODES]
    decode = dataclasses.replace(rows[0][1], dut=dataclasses.replace(rows[0][1].dut, name="decode_only", config={}))
    return [("decode_only", decode), *rows]


def external_cases(estimator: str) -> list[tuple[str, TestCase]]:
    """(label, case) of the external rows: S000-external with the harness's estimator."""
    ext = load_case(EXTERNAL)
    name = _harness_estimator(ext)

    def harness(case: TestCase, est: str, config: dict) -> TestCase:
        cmd = str(case.dut.command).replace(f"--estimator {name}", f"--estimator {est}")
        return dataclasses.replace(case, dut=dataclasses.replace(case.dut, command=cmd, config=config))

    rows = [("decode_only", harness(ext, "decode_only", {}))]
    if estimator == "seed000":
        rows += [(f"{estimator} {m}", harness(ext, estimator, {**ext.dut.config, "mode": m})) for m in MODES]
    else:
        rows.append((estimator, harness(ext, estimator, dict(ext.dut.config))))
    return rows


def _harness_estimator(case: TestCase) -> str:
    words = str(case.dut.command).split()
    return words[words.index("--estimator") + 1]


def _with_config(case: TestCase, **config) -> TestCase:
    return dataclasses.replace(case, dut=dataclasses.replace(case.dut, config={**case.dut.config, **config}))


def timed(case: TestCase, out: Path, duration_s: float, trajectories: dict) -> tuple[str, float]:
    """One run of ``case`` (seed 1): its status (with the reason when it did not complete)
    and wall time, s (the drive's trajectory built once, outside the timed runs)."""
    spec = spec_from_case(case, 1, out)
    if "s000" not in trajectories:
        trajectories["s000"] = spec.scenario.trajectory()
    spec = dataclasses.replace(spec, duration_ns=round(duration_s * 1e9), trajectory=trajectories["s000"])
    t = time.perf_counter()
    res = run(spec)
    el = time.perf_counter() - t
    return (res.status if res.status == "complete" else f"{res.status}: {res.reason}"), el


def table(title: str, rows: list[tuple[str, TestCase]], out: Path, duration_s: float, target: float) -> None:
    print(title)
    trajectories: dict = {}
    base = None
    for label, case in rows:
        status, el = timed(case, out / label.replace(" ", "_"), duration_s, trajectories)
        if status != "complete":  # a run that did not go to its end measures nothing
            print(f"   {label:<32} NOT MEASURED, the run did not complete ({status})")
            if label == "decode_only":
                base = None
            continue
        x = duration_s / el
        if label == "decode_only":
            base = el
            print(f"   {label:<32} {status:<9} {el:7.2f} s  {x:6.0f}x real time  (the bench's own cost)")
            continue
        own = f"own share {el - base:6.2f} s" if base is not None else ""
        verdict = "MET" if x >= target else "MISSED"
        print(f"   {label:<32} {status:<9} {el:7.2f} s  {x:6.0f}x real time  {own};  target >= {target:.0f}x "
              f"(<= {duration_s / target:.0f} s) {verdict}")


def _commit() -> str:
    try:
        return subprocess.run(["git", "-C", str(ROOT), "describe", "--always", "--dirty"], capture_output=True,
                              text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "?"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=3600.0, help="bench seconds of S000 to run (default 3600)")
    args = ap.parse_args()
    estimator = _estimator()
    print(f"S000 closed loop, {args.duration:g} s of bench time, seed 1, estimator {estimator!r}, commit {_commit()}")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        table("1. In process, lockstep 10 ms steps, all links, full recording", in_process_cases(estimator),
              out / "in", args.duration, TARGET_IN_PROCESS)
        table("2. External process (harness), pty + udp_multicast on the loopback, lockstep 1 s steps",
              external_cases(estimator), out / "ext", args.duration, TARGET_EXTERNAL)


if __name__ == "__main__":
    main()
