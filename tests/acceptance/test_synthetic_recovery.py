"""The synthetic DUT outputs truth plus known error signatures; scoring its recording
must give back every injected value within the ICD output quantization."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.acceptance.case import load_case
from bench.acceptance.judge import score_recording
from bench.acceptance.synthetic import SyntheticRunner
from bench.acceptance.verdict import Verdict
from bench.scoring.data import load_run
from bench.scoring.metrics import Scorer
from bench.scoring.windows import WindowSpec

ARCMIN = math.radians(1 / 60)
POS_Q = 0.02  # m: 1e-7 deg of latitude/longitude is 1.1 cm at most
ANG_Q = math.radians(2e-7)  # rad: two steps of 1e-7 deg
VEL_Q = 2e-4  # m/s

CASE = """
[case]
id = "SIG"
title = "signature recovery"
requirements = ["R"]

[scenario]
script = "drive.toml"

[[fault]]
start = "20 s"
end = "25 s"
target = "odometer"
kind = "idling"

[[fault]]
start = "50 s"
end = "55 s"
target = "odometer"
kind = "sliding"

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

[dut.synthetic]
rate = "100 Hz"
latency = "5 ms"
sigma_position = ["1 m", "1 m", "1 m"]
sigma_velocity = ["0.1 m/s", "0.1 m/s", "0.1 m/s"]
sigma_attitude = ["1 arcmin", "1 arcmin", "1 arcmin"]

[[dut.synthetic.error]]
kind = "bias"
quantity = "position"
value = ["3 m", "-4 m", "1 m"]

[[dut.synthetic.error]]
kind = "ramp"
quantity = "heading"
rate = "0.01 arcmin/s"
end = "60 s"

[[dut.synthetic.error]]
kind = "switch_step"
quantity = "position"
value = ["0 m", "1.5 m", "0 m"]

[[dut.synthetic.error]]
kind = "switch_oscillation"
quantity = "heading"
amplitude = "2 arcmin"
period = "20 s"
duration = "40 s"

[[dut.synthetic.detect]]
target = "odometer"
windows = [0, 2]
latency = "0.5 s"
exclude = true

[[dut.synthetic.false_alarm]]
target = "odometer"
at = "80 s"
duration = "1 s"

[[dut.synthetic.output]]
kind = "late"
start = "170 s"
end = "175 s"
latency = "60 ms"

[[dut.synthetic.output]]
kind = "drop"
start = "180 s"
end = "181 s"

[[dut.synthetic.output]]
kind = "bad_frames"
every = 50

[run]
seeds = [3]

[[criterion]]
requirement = "R"
metric = "accuracy.horizontal.rms"
window = { end = "100 s" }
at_most = "5.1 m"
"""


@pytest.fixture(scope="module")
def scored(tmp_path_factory):
    from tests.acceptance.conftest import DRIVE

    d = tmp_path_factory.mktemp("sig")
    (d / "drive.toml").write_text(DRIVE)
    (d / "case.toml").write_text(CASE)
    case = load_case(d / "case.toml")
    rec = SyntheticRunner().run(case, 3, d)
    return case, rec, Scorer(load_run(rec), case.scoring)


def m(s: Scorer, name: str, window: WindowSpec | None = None, **options) -> float:
    return s.metric(name, window or WindowSpec("all"), options).value


BEFORE = WindowSpec("before", end_ns=100_000_000_000)


def test_position_bias(scored):
    _, _, s = scored
    assert m(s, "accuracy.horizontal.rms", BEFORE) == pytest.approx(5.0, abs=POS_Q)
    assert m(s, "accuracy.east.mean", BEFORE) == pytest.approx(3.0, abs=POS_Q)
    assert m(s, "accuracy.north.mean", BEFORE) == pytest.approx(-4.0, abs=POS_Q)
    assert m(s, "accuracy.vertical.mean", BEFORE) == pytest.approx(1.0, abs=0.002)
    assert m(s, "accuracy.velocity.max") == pytest.approx(0.0, abs=VEL_Q)


def test_heading_ramp(scored):
    _, _, s = scored
    # 0.01'/s for 60 s, held: 0.6' from 60 s to the switch
    assert m(s, "accuracy.heading.max", WindowSpec("ramp", end_ns=60_000_000_001)) == pytest.approx(
        0.6 * ARCMIN, abs=ANG_Q
    )
    assert m(s, "accuracy.heading.final", WindowSpec("ramp", end_ns=30_000_000_001)) == pytest.approx(
        0.3 * ARCMIN, abs=ANG_Q
    )
    assert m(s, "accuracy.heading.growth", WindowSpec("ramp", end_ns=60_000_000_001)) == pytest.approx(
        0.6 * ARCMIN, abs=ANG_Q
    )


def test_frame_switch_jump_and_oscillation(scored):
    _, _, s = scored
    assert m(s, "frameswitch.count") == 1
    assert m(s, "frameswitch.delay") == pytest.approx(0.0)
    assert m(s, "frameswitch.jump_position") == pytest.approx(1.5, abs=POS_Q)
    assert m(s, "frameswitch.jump_heading") == pytest.approx(0.0, abs=ANG_Q)
    assert m(s, "frameswitch.amplitude_heading") == pytest.approx(2 * ARCMIN, abs=ANG_Q)
    floor = math.radians(0.1 / 60)
    assert m(s, "frameswitch.excess_heading") == pytest.approx(2 * ARCMIN - floor, abs=ANG_Q)
    # last epoch outside the 0.1' band: 2' |sin(2 pi (t - 100) / 20)| > 0.1' until 139.84 s
    assert m(s, "frameswitch.settling_heading") == pytest.approx(39.84, abs=1e-9)
    pre = math.hypot(3, 4)
    post = math.hypot(3, -2.5)
    ratio = math.sqrt(post**2 + 1) / math.sqrt(pre**2 + 1)
    assert m(s, "frameswitch.rms_ratio_position") == pytest.approx(ratio, abs=0.005)


def test_fault_flags_in_some_windows_and_not_others(scored):
    _, _, s = scored
    odo = {"target": ("odometer",)}
    assert m(s, "faults.windows", **odo) == 3
    assert m(s, "faults.detected", **odo) == 2
    assert m(s, "faults.missed", **odo) == 1
    assert m(s, "faults.latency_mean", **odo) == pytest.approx(0.5)
    assert m(s, "faults.latency_max", **odo) == math.inf
    windows = s.metric("faults.windows", WindowSpec("all"), odo).details["windows"]
    assert [w["exclusion"] for w in windows] == pytest.approx([0.9, 0.0, 0.95])
    assert m(s, "faults.false_alarms", **odo) == 1


def test_late_and_missing_epochs_and_bad_frames(scored):
    _, _, s = scored
    assert m(s, "output.latency_max") == pytest.approx(0.060)
    assert m(s, "output.latency_p95") == pytest.approx(0.005)
    assert m(s, "output.missing_epochs") == 100
    assert m(s, "output.counter_gaps") == 100
    assert m(s, "output.counter_faults") == 0  # the counter steps with the time of validity
    assert m(s, "output.rate") == pytest.approx(19_900 / 200)  # delivered over the window, not 1 / median
    assert m(s, "output.median_rate") == pytest.approx(100.0)
    assert m(s, "output.bad_frames") == 4  # at 0, 50, 100, 150 s


def test_consistency_against_reported_sigmas(scored):
    _, _, s = scored
    # before the switch: (3^2 + 4^2 + 1^2) / 1 m^2 over 3 degrees of freedom
    assert m(s, "consistency.position.nees", BEFORE) == pytest.approx(26 / 3, rel=0.01)
    assert m(s, "consistency.velocity.nees", BEFORE) == pytest.approx(0.0, abs=1e-4)


def test_recording_is_laid_out_as_the_run_engine_writes(scored):
    _, rec, _ = scored
    run = load_run(rec)
    assert run.run_start["case"] == "SIG" and run.run_start["seed"] == "3" and run.run_start["runner"] == "synthetic"
    assert run.run_end == {"status": "complete", "reason": ""}
    assert run.case_attachment()[0] == "case.toml"
    assert "scenario/drive.toml" in run.attachments
    assert [w.kind for w in run.faults] == ["idling", "sliding", "no_output"]
    assert run.commands == [{"t_ns": 100_000_000_000, "command": "grid"}]
    assert len(run.segments) == 3 and run.segments[1]["gnss"] == "blocked"
    assert np.all(run.nav["t_ns"] % 1000 == 0)  # microseconds, as on the wire
    assert np.all(np.diff(run.nav["rx_ns"]) >= 0)  # arrival order
    _, result = score_recording(rec)
    # the output defects the case injects are judged by the default integrity criteria
    failed = {k for k, v in result.values.items() if v.verdict is Verdict.FAIL}
    assert failed == {"INTEGRITY-missing", "INTEGRITY-gap", "INTEGRITY-order", "INTEGRITY-bad-frames"}
    assert result.verdict is Verdict.FAIL


def test_same_seed_same_recording_payload(tmp_path_factory, scored):
    case, rec, _ = scored
    d = tmp_path_factory.mktemp("again")
    rec2 = SyntheticRunner().run(case, 3, d)
    a, b = load_run(rec), load_run(rec2)
    assert a.nav.tobytes() == b.nav.tobytes()
    assert a.quality.tobytes() == b.quality.tobytes()
    assert a.truth.tobytes() == b.truth.tobytes()
