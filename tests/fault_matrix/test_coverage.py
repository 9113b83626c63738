"""The fault matrix (issue 32), coverage: a verdict over a requirement nobody judged is no
PASS. The main job's report on 57b1bce said PASS while its own coverage matrix showed S001's
BENCH-OUT "named, never judged" (its only criterion, an output latency, is N/A in lockstep).

Every row runs ``bench`` as a user would (tests/fault_matrix/matrix.py). On 57b1bce the
first row PASSed (exit 0) and the shipped S001 named BENCH-OUT with only OUT-LATENCY.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from bench.acceptance.case import is_case_file, load_case
from bench.acceptance.judge import NOT_IN_LOCKSTEP
from tests.fault_matrix.matrix import bench, case

ROOT = Path(__file__).resolve().parent.parent.parent
LATENCY = """
[[criterion]]
id = "OUT-LATENCY"
requirement = "BENCH-OUT"
metric = "output.latency_p95"
at_most = "10 ms"
"""


def _case(tmp_path: Path, waiver: str = "") -> Path:
    """The matrix's small case, naming BENCH-OUT too, judged only by a latency (N/A in lockstep)."""
    p = case(tmp_path)
    text = p.read_text().replace('requirements = ["R"]', 'requirements = ["R", "BENCH-OUT"]' + waiver)
    p.write_text(text + LATENCY)
    return p


def test_a_requirement_whose_only_criterion_does_not_apply_makes_the_case_error_not_pass(tmp_path):
    out = tmp_path / "out"
    r = bench("run", str(_case(tmp_path)), "-o", str(out), "-q", "--no-plots", cwd=tmp_path, expect=3)
    assert "requirement BENCH-OUT not judged" in r.text
    c = json.loads((out / "results.json").read_text())["cases"][0]
    assert c["verdict"] == "ERROR"
    assert any(e.startswith("requirement BENCH-OUT not judged: its criteria (OUT-LATENCY) were all N/A: not "
                            "applicable in lockstep") for e in c["errors"]), c["errors"]
    assert {x["id"]: x["verdict"] for x in c["criteria"]}["H"] == "PASS"  # what was judged is still shown
    assert "requirement BENCH-OUT not judged" in (out / "summary.txt").read_text()
    junit = ET.parse(out / "junit.xml").getroot()
    assert any("requirement BENCH-OUT not judged" in (e.text or "") for e in junit.iter("error"))


def test_a_requirement_the_case_waives_with_its_reason_is_shown_and_the_case_passes(tmp_path):
    out = tmp_path / "out"
    waiver = '\nwaived = { BENCH-OUT = "the latency is judged in the real-time case M10-RT" }'
    bench("run", str(_case(tmp_path, waiver)), "-o", str(out), "-q", "--no-plots", cwd=tmp_path, expect=0)
    c = json.loads((out / "results.json").read_text())["cases"][0]
    assert c["verdict"] == "PASS" and not c["errors"]
    assert c["requirements_waived"] == [{"requirement": "BENCH-OUT",
                                         "reason": "the latency is judged in the real-time case M10-RT"}]
    assert "requirement BENCH-OUT waived: the latency is judged in the real-time case M10-RT" in \
        (out / "summary.txt").read_text()
    skipped = [tc for tc in ET.parse(out / "junit.xml").getroot().iter("testcase")
               if tc.get("name") == "requirement BENCH-OUT (waived)"]
    assert len(skipped) == 1 and skipped[0].find("skipped") is not None


def test_a_requirement_no_criterion_names_makes_the_case_error(tmp_path):
    p = case(tmp_path)
    p.write_text(p.read_text().replace('requirements = ["R"]', 'requirements = ["R", "R-FORGOTTEN"]'))
    r = bench("run", str(p), "-o", str(tmp_path / "out"), "-q", "--no-plots", cwd=tmp_path, expect=3)
    assert "requirement R-FORGOTTEN not judged: no criterion of the case names it" in r.text


@pytest.mark.parametrize(
    ("waiver", "named"),
    [
        ('\nwaived = { R-OTHER = "x" }', "case.waived.R-OTHER"),
        ('\nwaived = { BENCH-OUT = "  " }', "case.waived.BENCH-OUT"),
        ('\nwaived = { BENCH-OUT = 3 }', "case.waived.BENCH-OUT"),
        ('\nwaived = "all of them"', "case.waived"),
    ],
    ids=["unknown-requirement", "empty-reason", "not-a-string", "not-a-table"],
)
def test_a_waiver_that_names_no_requirement_of_the_case_or_no_reason_is_refused(tmp_path, waiver, named):
    r = bench("run", str(_case(tmp_path, waiver)), "-o", str(tmp_path / "out"), "-q", cwd=tmp_path, expect=2)
    assert "case.toml" in r.err and named in r.err


@pytest.mark.parametrize("path", sorted(p for p in (ROOT / "test_cases").glob("*.toml") if is_case_file(p)),
                         ids=lambda p: p.stem)
def test_every_shipped_case_judges_in_lockstep_or_waives_every_requirement_it_names(path):
    c = load_case(path)
    for req in c.requirements:
        judging = [x.id for x in c.criteria
                   if req in x.requirements and (c.clock.mode == "realtime" or x.metric not in NOT_IN_LOCKSTEP)]
        assert judging or req in c.waived, f"{path.name}: {req} is judged by no criterion that applies"
