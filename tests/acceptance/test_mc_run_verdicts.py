"""A run's own verdict holds only the criteria judged run by run: a value that feeds a
statistic over the runs (``pass_runs``, ``percentile``, ``aggregate``) is judged in that
statistic, so one run beyond the limit does not FAIL a case whose statistic meets it, and a
statistic beyond the limit still FAILs it."""

from __future__ import annotations

import pytest

from bench.acceptance.case import load_case
from bench.acceptance.suite import SuiteOptions, run_case
from bench.acceptance.verdict import Verdict
from bench.cli.score import score_files
from tests.acceptance.conftest import DRIVE, base_case

WANDER = """
[[dut.synthetic.error]]
kind = "markov"
quantity = "position"
sigma = ["3 m", "3 m", "0 m"]
tau = "30 s"

[[criterion]]
id = "SPREAD"
requirement = "R2"
metric = "accuracy.horizontal.max"
at_most = "{limit}"
{mode}
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("mc")
    (d / "drive.toml").write_text(DRIVE)
    text = base_case(limit="50 m").replace("seeds = [1]", "seeds = [1, 2, 3]")
    (d / "case.toml").write_text(text + WANDER.replace("{limit}", "1000 m").replace("{mode}", ""))
    result = run_case(load_case(d / "case.toml"), SuiteOptions(d / "out"))
    values = sorted(r.values["SPREAD"].value for r in result.runs)
    assert values[0] < values[1] < values[2]  # three different wanders
    return d, [r.recording for r in result.runs], values


def _judge(d, recordings, limit: float, mode: str):
    path = d / f"judge_{abs(hash((limit, mode)))}.toml"
    text = base_case(limit="50 m").replace("seeds = [1]", "seeds = [1, 2, 3]")
    path.write_text(text + WANDER.replace("{limit}", f"{limit} m").replace("{mode}", mode))
    (cr,) = score_files(recordings, path)
    spread = next(c for c in cr.criteria if c.criterion.id == "SPREAD")
    return cr, spread


@pytest.mark.parametrize(
    ("mode", "between", "verdict"),
    [
        ("monte_carlo = { pass_runs = 2 }", (0, 1), Verdict.FAIL),  # one run meets the limit, two needed
        ("monte_carlo = { pass_runs = 2 }", (1, 2), Verdict.PASS),  # two runs meet it, the third does not
        ('monte_carlo = { aggregate = "min" }', (0, 1), Verdict.PASS),
        ('monte_carlo = { aggregate = "max" }', (1, 2), Verdict.FAIL),
        ("", (1, 2), Verdict.FAIL),  # each: the worst run decides
    ],
)
def test_the_statistic_decides_not_the_runs_beyond_the_limit(runs, mode, between, verdict):
    d, recordings, values = runs
    limit = (values[between[0]] + values[between[1]]) / 2
    cr, spread = _judge(d, recordings, limit, mode)
    assert spread.verdict is verdict
    assert cr.verdict is verdict  # the case follows the criterion: no run verdict overrides it
    beyond = [r for r in cr.runs if r.values["SPREAD"].value > limit]
    assert beyond and all(r.values["SPREAD"].verdict is Verdict.FAIL for r in beyond)  # still shown per run
    each = mode == ""
    assert all((r.verdict is Verdict.FAIL) == each for r in beyond)
