"""The bench against a DUT written from the ICD text alone (tests/run/duts/icd_select.py):
lockstep over pty and udp_multicast CAN in a network namespace, the DUT reading its
serial lines and the bus from one select loop with no waiting of its own.

What the DUT checks, and what the recording must show:

* ICD 6, serial before BENCH_TIME(T): no IMU frame due by T arrives after the DUT handled
  BENCH_TIME(T) (0 late of 100,000: a 1000 Hz IMU for 100 s in 10 ms steps);
* ICD 1, alive counters: every BENCH_TIME and BENCH_EPOCH is the previous one +1 modulo
  16, the start-up handshake's repeated BENCH_TIME(0) included;
* ICD 6, start-up: BENCH_EPOCH(0) (every frame with time <= 0) before BENCH_TIME(0);
* the recording is in wire order: ``/wire/can/tx`` read back is the order the frames
  went out (times never decrease, BENCH_EPOCH(0) before the first BENCH_TIME, the
  counters continuous).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.faults.schedule import FaultSchedule
from bench.record.mcap_io import RecordingReader
from bench.run.engine import run
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.scenario.loader import load_scenario
from tests.transport import netns

HERE = Path(__file__).parent
DUT = HERE / "duts" / "icd_select.py"
SCENARIO = HERE / "data" / "icd_drive.toml"
TABLES = {"imu": {"grade": "navigation", "rate": "1000 Hz"}, "doppler": {"model": "seed000"},
          "odometer": {"model": "typical_wheeled"}, "bds": {"model": "seed001", "latency": "80 ms"},
          "driver": {"vehicle": "wheeled"}}
BENCH_TIME, BENCH_EPOCH = 0x010, 0x011


def _dut_report(path: Path) -> dict:
    lines = [d["text"] for _, d in RecordingReader(path).iter_json("/dut/log") if d["text"].startswith("{")]
    assert lines, "the DUT printed no report"
    return json.loads(lines[-1])


def _wire_order_problems(path: Path) -> list[str]:
    can = RecordingReader(path).read_columnar("/wire/can/tx")
    problems = []
    if not np.all(np.diff(can["t_ns"]) >= 0):
        problems.append("/wire/can/tx is not in the order the frames went out (a time goes back)")
    ids = can["can_id"]
    first_time = int(np.flatnonzero(ids == BENCH_TIME)[0])
    if BENCH_EPOCH not in ids[:first_time].tolist():
        problems.append("/wire/can/tx: BENCH_EPOCH(0) is not recorded before the first BENCH_TIME")
    for cid in (BENCH_TIME, BENCH_EPOCH):
        alive = can["data"][ids == cid, 6].astype(np.int64) & 0x0F
        if not np.all(np.diff(alive) % 16 == 1):
            problems.append(f"/wire/can/tx: the recorded 0x{cid:03X} alive counters are not continuous")
    return problems


@pytest.mark.slow
@pytest.mark.parametrize("step_ms", [10, 100])
def test_an_icd_dut_in_one_select_loop_sees_every_frame_in_time(ns, tmp_path, step_ms):
    """10 ms steps: 420 bytes of IMU frames a step; 100 ms: 4200, more than the pty's
    line discipline holds (the rest moves in as the DUT reads)."""
    port = 43361
    cmd = (f"ip netns exec {ns} {sys.executable} {DUT} --can-interface {{can_interface}} "
           f"--can-channel {{can_channel}} --can-port {port} --imu {{imu_port}} --gnss {{gnss_port}}")
    spec = RunSpec(
        scenario=load_scenario(SCENARIO), tables=TABLES, schedule=FaultSchedule(), out=tmp_path / "icd.mcap",
        dut=DutSpec("external", command=cmd), seed=3, clock=ClockSpec(step_ns=step_ms * 1_000_000),
        links=LinkSpec(can={"interface": "udp_multicast", "channel": "239.74.163.61", "port": port}),
    )
    res = netns.call_in(ns, lambda: run(spec))
    assert res.ok, res.reason
    report = _dut_report(res.path)
    assert report["imu_frames"] == 100_000 and report["imu_crc"] == 0 and report["imu_counter_gaps"] == 0
    assert report["can_crc"] == 0 and report["bench_epoch"] >= 101 and report["bench_time"] >= 10_001
    problems = []
    if report["late"]:
        problems.append(f"{report['late']} IMU frames came after their BENCH_TIME (first: {report['first_late']})")
    if report["counter_errors"]:
        problems.append(f"{report['counter_errors']} BENCH_TIME/BENCH_EPOCH alive counter errors")
    if report["epoch_after_time"]:
        problems.append("the first BENCH_EPOCH came after the first BENCH_TIME")
    assert not problems + _wire_order_problems(res.path), problems + _wire_order_problems(res.path)
