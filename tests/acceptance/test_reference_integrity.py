"""Every reference case judges its DUT's output integrity: its recording, with the output
degraded in the last 40 % of the run, FAILs on a named INTEGRITY criterion.

Each case runs once with the synthetic DUT (its own stand-in; S000-DR's in-process
estimator is replaced by a truth-exact one on the same drive), and the recorded output is
then corrupted in memory and judged against the case's own criteria with the defaults."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from bench.acceptance.case import TestCase, is_case_file, load_case
from bench.acceptance.corrupt import corrupt_output
from bench.acceptance.criteria import judge_value
from bench.acceptance.integrity_criteria import PREFIX
from bench.acceptance.judge import score_run
from bench.acceptance.synthetic import SyntheticRunner
from bench.acceptance.synthetic_spec import SyntheticDut
from bench.acceptance.verdict import Verdict
from bench.scoring.data import RunData, load_run
from bench.scoring.metrics import Scorer
from tests.acceptance.degradations import KINDS

pytestmark = pytest.mark.slow

#: the synthesized reference cases (S004, built on a real log, runs no synthetic stand-in:
#: its integrity defaults are judged on its real run, tests/acceptance/test_real_lasergyro_case.py)
CASES = sorted(p for p in (Path(__file__).resolve().parents[2] / "test_cases").glob("*.toml")
               if is_case_file(p) and load_case(p).scenario.log is None)

#: the whole-run check per case: rotate the kinds over the cases
WHOLE = {
    "S000_dead_reckoning.toml": "time_frozen",
    "S000_external.toml": "no_quality",
    "S000_sins_doppler.toml": "bad_crc",
    "S001_bds_sins.toml": "time_jump",
    "S002_sins_odometer_faults.toml": "drop",
    "S003a_frame_switch_polar.toml": "counter_stuck",
    "S003b_frame_switch_commanded.toml": "out_of_range",
    "S003c_frame_switch_back.toml": "time_frozen",
    "S003d_over_the_pole.toml": "bad_crc",
}


def _stand_in(case: TestCase) -> TestCase:
    if case.dut.kind == "synthetic":
        return case.for_variant(case.variants()[0])
    spec = SyntheticDut()
    if case.dut.name == "seed003":  # it switches to the grid frame poleward of 88 deg (and on commands)
        spec = dataclasses.replace(spec, switch_latitude=math.radians(88.0))
    return dataclasses.replace(case, dut=dataclasses.replace(case.dut, kind="synthetic", synthetic=spec))


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> dict[str, tuple[TestCase, RunData]]:
    out_dir = tmp_path_factory.mktemp("reference")
    out = {}
    for path in CASES:
        case = load_case(path)
        out[path.name] = (case, load_run(SyntheticRunner().run(_stand_in(case), 1, out_dir)))
    return out


def degrade(run: RunData, kind: str, fraction: float = 0.4) -> RunData:
    """The run with its DUT output broken from ``1 - fraction`` of its span on."""
    t0, t1 = run.span_ns
    start = t0 + round((1.0 - fraction) * (t1 - t0))
    assert run.nav is not None and run.quality is not None
    nav, quality, bad = run.nav.copy(), run.quality.copy(), []
    if kind == "drop":
        nav, quality = nav[nav["t_ns"] < start], quality[quality["t_ns"] < start]
    elif kind == "invalid":
        nav["valid"][nav["t_ns"] >= start] = 0
    else:
        nav, quality, bad = corrupt_output(nav, quality, kind, start)
    return dataclasses.replace(run, nav=nav, quality=quality, bad_frames=[*run.bad_frames, *bad])


def test_there_are_nine_synthesized_reference_cases():
    assert [p.name for p in CASES] == list(WHOLE) and len(CASES) == 9


@pytest.mark.parametrize("name", [p.name for p in CASES])
def test_healthy_output_passes_every_default(recordings, name):
    case, run = recordings[name]
    result = score_run(run, case)
    defaults = {k: v for k, v in result.values.items() if k.startswith(PREFIX)}
    assert len(defaults) == 10 and all(v.verdict is Verdict.PASS for v in defaults.values()), defaults
    assert result.verdict in (Verdict.PASS, Verdict.MARGINAL)


@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("name", [p.name for p in CASES])
def test_degraded_output_fails_the_named_default(recordings, name, kind):
    case, run = recordings[name]
    criterion = next(c for c in case.criteria if c.id == KINDS[kind])
    value = Scorer(degrade(run, kind), case.scoring).metric(criterion.metric, criterion.window).value
    verdict, _ = judge_value(criterion.limit, criterion.band(), value)
    assert verdict is Verdict.FAIL, (criterion.id, value)


@pytest.mark.parametrize("name", [p.name for p in CASES])
def test_a_run_degraded_in_its_last_40_percent_fails(recordings, name):
    case, run = recordings[name]
    kind = WHOLE[name]
    result = score_run(degrade(run, kind), case)
    assert result.verdict is Verdict.FAIL, {k: (v.verdict, v.reason) for k, v in result.values.items()}
    assert result.values[KINDS[kind]].verdict is Verdict.FAIL
