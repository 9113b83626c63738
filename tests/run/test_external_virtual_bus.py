"""An external DUT given programmatically on python-can's ``virtual`` bus (a test case is
refused at load for it: tests/fault_matrix/test_doc_examples.py) cannot hear the bench:
the start-up timeout's reason says why, beside the DUT's last output."""

from __future__ import annotations

import sys

from bench.faults.schedule import FaultSchedule
from bench.run.engine import run
from bench.run.spec import DutSpec, LinkSpec, RunSpec
from bench.scenario.loader import load_scenario
from tests.run.robust_util import SHORT, TABLES

HARNESS = (f"{sys.executable} -m bench.dut.harness --estimator decode_only --can-interface {{can_interface}} "
           "--can-channel {can_channel} --imu {imu_port} --gnss {gnss_port}")


def test_a_dut_process_on_the_virtual_bus_is_told_it_cannot_be_reached(tmp_path):
    # the harness listens (its line says so) but on its own process's virtual bus: it never
    # hears BENCH_TIME, whatever the timeout; 3 s is the start-up limit under test
    dut = DutSpec("external", command=HARNESS, startup_timeout_s=3.0, shutdown_timeout_s=60.0)
    spec = RunSpec(scenario=load_scenario(SHORT), tables=TABLES, schedule=FaultSchedule(), dut=dut,
                   out=tmp_path / "run.mcap", links=LinkSpec(), duration_ns=2_000_000_000)
    res = run(spec)
    assert not res.ok
    assert "did not answer BENCH_TIME(0 s) with DUT_READY within 3 s" in res.reason, res.reason
    assert "the CAN bus is python-can's 'virtual' one, which cannot reach another process" in res.reason, res.reason
