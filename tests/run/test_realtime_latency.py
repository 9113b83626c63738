"""A 60 s real-time run with an external DUT (tests/run/duts/delayed.py over pty +
udp_multicast in a network namespace) that answers every BENCH_TIME 3 ms after it
arrived and reports when it sent each answer.

What the bench must get right, and what this asserts (no wall-clock figure of the
machine is asserted: only the bench's measurement against the DUT's own stamps):

* every answer recorded, the last epoch (the answer to the run's end) included, none
  counted as a pairing error or any other bad frame, so the output criteria, the
  ``INTEGRITY-*`` defaults among them, PASS;
* each answer stamped when it arrived: never before the DUT sent it, and the measured
  latency (``output.latency_mean``, ``latency_p95``) within 0.5 ms of the latency the DUT
  itself added (its send time, put on bench time by the recorded clock anchor, minus the
  time of validity).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.acceptance.case import parse_case
from bench.acceptance.judge import score_recording
from bench.acceptance.verdict import Verdict
from bench.faults.schedule import FaultSchedule
from bench.record.mcap_io import RecordingReader
from bench.run.engine import run
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.scenario.loader import load_scenario
from tests.run.robust_util import SHORT, TABLES
from tests.transport import netns

DELAYED = Path(__file__).parent / "duts" / "delayed.py"
PORT = 43471
GROUP = "239.74.164.71"
CASE = f"""
[case]
id = "RT-LATENCY"
title = "real-time output of an external DUT with a known latency"
requirements = ["BENCH-OUT"]

[scenario]
script = "{SHORT}"

[dut]
kind = "external"
command = "delayed"

[dut.links]
can = {{ interface = "udp_multicast", channel = "{GROUP}" }}

[clock]
mode = "realtime"

[[criterion]]
id = "OUT-RATE"
requirement = "BENCH-OUT"
metric = "output.rate"
at_least = "99.9 Hz"

[[criterion]]
id = "OUT-LATENCY"
requirement = "BENCH-OUT"
metric = "output.latency_p95"
at_most = "20 ms"

[[criterion]]
id = "OUT-LATENCY-MEAN"
requirement = "BENCH-OUT"
metric = "output.latency_mean"
at_most = "20 ms"
"""


@pytest.mark.slow
def test_60_s_real_time_run_passes_and_measures_the_dut_latency_it_adds(ns, tmp_path):
    stamps = tmp_path / "stamps.txt"
    cmd = (f"ip netns exec {ns} {sys.executable} {DELAYED} --can-channel {{can_channel}} --can-port {{can_port}} "
           "--imu {imu_port} --gnss {gnss_port} --config {config}")
    dut = DutSpec("external", command=cmd, config={"delay_ms": 3.0, "stamps": str(stamps)},
                  startup_timeout_s=60.0, shutdown_timeout_s=60.0)  # hang guards
    spec = RunSpec(scenario=load_scenario(SHORT), tables=TABLES, schedule=FaultSchedule(), dut=dut,
                   links=LinkSpec(can={"interface": "udp_multicast", "channel": GROUP, "port": PORT}),
                   clock=ClockSpec(mode="realtime"), out=tmp_path / "rt60.mcap", duration_ns=60_000_000_000)
    res = netns.call_in(ns, lambda: run(spec))
    assert res.status == "complete", res.reason
    r = RecordingReader(res.path)
    meta = r.metadata()
    assert json.loads(meta["dut_output"]["bad_frames"]) == {}  # no pairing (or other) error
    sol = r.read_columnar("/dut/nav_solution")
    qual = r.read_columnar("/dut/nav_quality")
    sent = np.loadtxt(stamps, dtype=np.int64, ndmin=2)
    t_dut, arrived_mono, sent_mono = sent[:, 0], sent[:, 1], sent[:, 2]
    # every answer the DUT sent is recorded, once, in order; the last one answers the end
    assert np.array_equal(sol["t_ns"], t_dut) and np.array_equal(qual["t_ns"], t_dut)
    assert np.array_equal(t_dut, np.arange(len(t_dut)) * 10_000_000) and t_dut[-1] == 60_000_000_000
    assert np.all(sent_mono - arrived_mono >= 3_000_000)  # the DUT did add its 3 ms
    # the DUT's send times on bench time (same host, same CLOCK_MONOTONIC)
    anchor = meta["realtime_clock"]
    assert float(anchor["speed"]) == 1.0
    sent_bench = int(anchor["origin_ns"]) + (sent_mono - int(anchor["monotonic_ns"]))
    rx = sol["rx_ns"]
    assert np.all(rx >= sent_bench)  # stamped when it arrived, never before it was sent
    dut_latency = (sent_bench - t_dut) * 1e-9
    case = parse_case(CASE, file="rt_latency.toml", check_files=False)
    _, judged = score_recording(res.path, case)
    verdicts = {k: v.verdict for k, v in judged.values.items()}
    assert verdicts and all(v is Verdict.PASS for v in verdicts.values()), verdicts
    assert any(k.startswith("INTEGRITY-") for k in verdicts) and judged.verdict is Verdict.PASS
    scorer_values = {k: v.value for k, v in judged.values.items()}
    assert abs(scorer_values["OUT-LATENCY"] - np.percentile(dut_latency, 95)) <= 0.5e-3
    assert abs(scorer_values["OUT-LATENCY-MEAN"] - dut_latency.mean()) <= 0.5e-3
    print(f"bench latency mean {scorer_values['OUT-LATENCY-MEAN'] * 1e3:.3f} ms, p95 "
          f"{scorer_values['OUT-LATENCY'] * 1e3:.3f} ms; the DUT's own mean {dut_latency.mean() * 1e3:.3f} ms, p95 "
          f"{np.percentile(dut_latency, 95) * 1e3:.3f} ms; arrival after send p50 "
          f"{np.median(rx - sent_bench) / 1e3:.1f} us, max {(rx - sent_bench).max() / 1e3:.1f} us")
