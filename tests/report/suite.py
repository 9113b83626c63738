"""A small real suite for the report tests: two cases of the synthetic DUT on the short
drive, run once per test session by ``bench accept`` (the command users run), so the
report, the record and the recordings are the real outputs.

* ``RPT-A`` passes: odometer faults detected, a commanded frame switch, reported
  covariance (NEES), a GNSS outage, two seeds (Monte Carlo values per seed);
  its DUT's name carries markup that the report must show as text; it names a requirement
  it waives, with the reason.
* ``RPT-B`` fails its accuracy limit and names a requirement it never judges: the case is
  ERROR (coverage is part of the verdict), its criterion still FAIL.
"""

from __future__ import annotations

from pathlib import Path

from tests.acceptance.conftest import DRIVE

HOSTILE_NAME = "<script>alert('dut')</script> filter"
HOSTILE_VERSION = "1.2.0-rc1 <b>beta</b>"

CASE_A = """
[case]
id = "RPT-A"
title = "report test: faults, frame switch, covariance"
requirements = ["R-ACC", "R-FDI", "R-NEES", "R-LATENCY"]
reference = "the report tests' own drive (tests/report/suite.py)"
assumed = ["the synthetic DUT stands in for an estimator: its errors are drawn, not estimated"]
waived = { R-LATENCY = "judged in the real-time case RPT-RT, not in lockstep" }

[scenario]
script = "drive.toml"

[[fault]]
start = "20 s"
end = "25 s"
target = "odometer"
kind = "idling"

[[fault]]
start = "150 s"
end = "160 s"
target = "odometer"
kind = "no_output"

[[command]]
at = "100 s"
command = "grid"

[dut]
kind = "synthetic"
name = "NAME"
version = "VERSION"

[dut.synthetic]
rate = "100 Hz"
latency = "5 ms"
sigma_position = ["4 m", "4 m", "2 m"]
sigma_velocity = ["0.1 m/s", "0.1 m/s", "0.1 m/s"]
sigma_attitude = ["2 arcmin", "2 arcmin", "2 arcmin"]

[[dut.synthetic.error]]
kind = "markov"
quantity = "position"
sigma = ["2 m", "2 m", "1 m"]
tau = "20 s"

[[dut.synthetic.error]]
kind = "switch_oscillation"
quantity = "heading"
amplitude = "0.5 arcmin"
period = "20 s"
duration = "40 s"

[[dut.synthetic.detect]]
target = "odometer"
latency = "0.5 s"
exclude = true

[run]
seeds = [1, 2]

[[criterion]]
id = "H-RMS"
requirement = "R-ACC"
metric = "accuracy.horizontal.rms"
at_most = "5 m"
paper = "3.2 m (fig. 7)"

[[criterion]]
id = "H-MAX"
requirement = "R-ACC"
metric = "accuracy.horizontal.max"
at_most = "15 m"

[[criterion]]
id = "DETECT"
requirement = "R-FDI"
metric = "faults.detection_rate"
at_least = "100 %"

[[criterion]]
id = "NEES"
requirement = "R-NEES"
metric = "consistency.position.nees"
at_most = 3.0
"""

CASE_B = """
[case]
id = "RPT-B"
title = "report test: a failing accuracy limit"
requirements = ["R-ACC", "R-NEVER"]

[scenario]
script = "drive.toml"

[dut]
kind = "synthetic"

[dut.synthetic]
rate = "100 Hz"

[[dut.synthetic.error]]
kind = "bias"
quantity = "position"
value = ["3 m", "4 m", "0 m"]

[run]
seeds = [1]

[[criterion]]
id = "H-RMS"
requirement = "R-ACC"
metric = "accuracy.horizontal.rms"
at_most = "4 m"
"""


REQUIREMENTS = """
[[requirement]]
id = "R-ACC"
statement = "The estimator shall keep its horizontal position error within 5 m RMS over the drive."
source = "paper"
citation = "report-test paper, table 1"

[[requirement]]
id = "R-FDI"
statement = "The estimator shall detect each odometer fault within 1 s of its start."
source = "bench"

[[requirement]]
id = "R-NEES"
statement = "The estimator's reported covariance shall cover its position error (NEES)."
source = "bench"

[[requirement]]
id = "R-LATENCY"
statement = "The estimator shall answer each step within 10 ms in real time."
source = "standard"
citation = "ICD.md, timing"

[[requirement]]
id = "R-NEVER"
statement = "A requirement named and never judged."
source = "bench"
"""


def write_suite(folder: Path) -> Path:
    """The two case files, their drive and the suite's requirements.toml in
    ``folder/cases``; returns that folder."""
    cases = folder / "cases"
    cases.mkdir(parents=True, exist_ok=True)
    (cases / "requirements.toml").write_text(REQUIREMENTS)
    (cases / "drive.toml").write_text(DRIVE)
    (cases / "rpt_a.toml").write_text(CASE_A.replace("NAME", HOSTILE_NAME).replace("VERSION", HOSTILE_VERSION))
    (cases / "rpt_b.toml").write_text(CASE_B)
    return cases
