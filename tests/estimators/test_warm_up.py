"""The reference estimators' ``warm_up`` compiles the step kernel a run then uses: on a
short in-process run (the bench's decoders, the estimator past its alignment into the
compiled step), no kernel specialization is added after the warm-up. A warm-up that
compiled for other argument types (another dtype, a contiguous IMU slice) would leave the
first step to compile again, inside the run."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.estimators import seed000_kernel, seed001_kernel, seed003_kernel
from bench.estimators.seed000 import Seed000
from bench.estimators.seed001 import Seed001
from bench.estimators.seed003 import Seed003
from bench.faults.schedule import FaultSchedule
from bench.record.mcap_io import RecordingReader
from bench.run.engine import run
from bench.run.spec import DutSpec, RunSpec
from bench.scenario.loader import load_scenario

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"
POS = [34.246, 108.909, 380.0]
CASES = {
    "seed000": (Seed000, seed000_kernel, {"imu": {"grade": "seed000", "rate": "200 Hz"},
                                          "doppler": {"model": "seed000"}}),
    "seed001": (Seed001, seed001_kernel, {"imu": {"grade": "navigation", "rate": "200 Hz"},
                                          "bds": {"model": "seed001_driving", "rate": "1 Hz"},
                                          "odometer": {"model": "typical_wheeled"}}),
    "seed003": (Seed003, seed003_kernel, {"imu": {"grade": "seed003_vehicle", "rate": "200 Hz"},
                                          "bds": {"model": "seed003", "rate": "1 Hz"},
                                          "doppler": {"model": "seed003"}}),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_warm_up_compiles_what_the_run_steps_with(name, tmp_path, monkeypatch):
    cls, kernel, tables = CASES[name]
    after: list[set] = []
    warm_up = cls.warm_up

    def noted(self):
        warm_up(self)
        after.append(set(kernel.run_step.signatures))

    monkeypatch.setattr(cls, "warm_up", noted)
    config = {"initial_position": POS, "coarse_alignment": "2 s", "alignment": "4 s"}
    spec = RunSpec(scenario=load_scenario(SHORT), tables=tables, schedule=FaultSchedule(),
                   dut=DutSpec("in_process", name=name, config=config), out=tmp_path / "r.mcap",
                   duration_ns=8_000_000_000)
    res = run(spec)
    assert res.status == "complete", res.reason
    assert len(after) == 1 and after[0], after  # warmed up once, and it compiled (or loaded) the kernel
    sol = RecordingReader(res.path).read_columnar("/dut/nav_solution")
    assert len(sol) == 801 and sol["mode"][-1] != sol["mode"][0]  # past the alignment: the kernel ran
    assert set(kernel.run_step.signatures) == after[0]  # nothing compiled inside the run
