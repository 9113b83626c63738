"""End to end through the run engine: the bench's dead-reckoning DUT, in process over the
ICD links, with its output broken from 6 s of a 10 s drive, FAILs on the named INTEGRITY
criterion; unbroken it PASSes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.acceptance.case import load_case
from bench.acceptance.suite import SuiteOptions, run_case
from bench.acceptance.verdict import Verdict
from bench.dut.estimator import DutInputs, EstimatorOutput, register_estimator
from bench.estimators.basic import DeadReckoning
from tests.acceptance.test_integrity_defaults import DRIVE

FROM_NS = 6_000_000_000


class Degrading(DeadReckoning):
    """Dead reckoning whose output goes bad from 6 s on, as ``corrupt`` says."""

    name = "degrading_dr"

    def configure(self, config):
        self.corrupt = config.get("corrupt", "none")
        super().configure({k: v for k, v in config.items() if k != "corrupt"})

    def step(self, inputs: DutInputs) -> EstimatorOutput:
        out = super().step(inputs)
        sol, q = out.solutions, out.qualities
        late = sol["t_ns"] >= FROM_NS
        if self.corrupt == "counter_stuck":
            sol["epoch"][late] = 7
            q["epoch"][q["t_ns"] >= FROM_NS] = 7
        elif self.corrupt == "height":
            sol["h"][late] = 1e6  # fits the wire's field, not the Earth
        elif self.corrupt == "latitude":
            sol["lat"][late] = np.radians(95.0)  # the int32 field carries it; the ICD's range does not
        elif self.corrupt == "nan":
            sol["lat"][late] = np.nan  # no NAV frame can carry it
        elif self.corrupt == "time_frozen":
            sol["t_ns"][late] = FROM_NS
            q["t_ns"][q["t_ns"] >= FROM_NS] = FROM_NS
        return out


register_estimator(Degrading.name, Degrading)

CASE = """
[case]
id = "DR10"
title = "dead reckoning, ten seconds"
requirements = ["R"]

[scenario]
script = "drive.toml"

[sensors]
imu = {{ grade = "seed000", rate = "200 Hz" }}
doppler = "seed000"

[dut]
kind = "in_process"
name = "degrading_dr"
config = {{ initial_position = [30.0, 110.0, 50.0], alignment = "2 s", output_rate = "100 Hz", corrupt = "{corrupt}" }}

[dut.links]
can = {{ interface = "virtual", channel = "dr10", fd = true }}

[scoring]
convergence = "3 s"

[[criterion]]
id = "H"
requirement = "R"
metric = "accuracy.horizontal.max"
window = "converged"
at_most = "100 m"
"""


@pytest.mark.parametrize(
    ("corrupt", "named"),
    [
        ("none", None),
        # the bench numbers the epochs of an in-process DUT: a stuck counter the estimator
        # writes is overwritten (wrong counters on the wire are judged: tests/fault_matrix)
        ("counter_stuck", None),
        ("height", "INTEGRITY-range"),
        ("latitude", "INTEGRITY-bad-frames"),
        ("time_frozen", "INTEGRITY-repeated"),
    ],
)
def test_a_real_dut_whose_output_goes_bad_fails_on_the_named_check(tmp_path: Path, corrupt, named):
    (tmp_path / "drive.toml").write_text(DRIVE)
    (tmp_path / "case.toml").write_text(CASE.format(corrupt=corrupt))
    result = run_case(load_case(tmp_path / "case.toml"), SuiteOptions(tmp_path / "out"))
    verdicts = {c.criterion.id: c.verdict for c in result.criteria}
    failed = sorted(k for k, v in verdicts.items() if v is Verdict.FAIL)
    if named is None:
        assert result.verdict is Verdict.PASS, {c.criterion.id: c.aggregate.reason for c in result.criteria}
        return
    assert named in failed and result.verdict is Verdict.FAIL, verdicts
    details = result.runs[0].values[named].details
    if named == "INTEGRITY-bad-frames":  # rejected by the bench's decoder, as from any DUT
        # 6 s to 10 s at 100 Hz, and their NAV_QUALITY frames left without a solution
        assert details["by_kind"] == {"range": 401, "pairing": 401}, details
        return
    assert details.get("first_at_s", details.get("first_t_s")) == pytest.approx(6.0, abs=0.011)


def test_an_in_process_dut_whose_output_no_frame_can_carry_keeps_what_it_delivered(tmp_path: Path):
    """NaN in an estimator's output: the run ends dut_failed, FAIL (the DUT failed to put its
    epochs on the bus), and the 6 s it delivered before are in the recording."""
    from bench.record.mcap_io import RecordingReader

    (tmp_path / "drive.toml").write_text(DRIVE)
    (tmp_path / "case.toml").write_text(CASE.format(corrupt="nan"))
    result = run_case(load_case(tmp_path / "case.toml"), SuiteOptions(tmp_path / "out"))
    assert result.verdict is Verdict.FAIL
    assert any("does not fit NAV frames" in i for i in result.runs[0].dut_issues), result.runs[0].dut_issues
    rec = RecordingReader(result.runs[0].recording)
    assert rec.metadata()["run_end"]["status"] == "dut_failed"
    assert "does not fit NAV frames" in rec.metadata()["run_end"]["reason"]
    nav = rec.read_columnar("/dut/nav_solution")
    assert len(nav) and nav["t_ns"].max() == FROM_NS - 10_000_000  # every epoch before the first NaN
