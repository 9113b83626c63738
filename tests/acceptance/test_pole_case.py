"""End to end over the North Pole: the synthetic DUT of tests/data/S003d_synthetic.toml
(truth plus known errors, reporting in the ENU frame at its own position) is run,
recorded and scored; the errors come back as injected, finite, and every criterion
passes. A scoring that compared its ENU components with the truth's would see the DUT's
frame turn by up to 180 deg near the pole."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bench.acceptance.case import load_case
from bench.acceptance.suite import SuiteOptions, run_case
from bench.acceptance.verdict import Verdict
from bench.scoring.align import nav_errors
from bench.scoring.data import load_run

CASE = Path(__file__).resolve().parents[1] / "data" / "S003d_synthetic.toml"
ARCMIN = math.radians(1.0 / 60.0)


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    return run_case(load_case(CASE), SuiteOptions(tmp_path_factory.mktemp("pole")))


def test_the_pole_case_passes(result):
    assert result.verdict is Verdict.PASS, [(c.criterion.id, c.verdict) for c in result.criteria]
    assert len(result.runs) == 1 and not result.runs[0].bench_issues


def test_scored_errors_are_the_injected_ones(result):
    run = load_run(Path(result.runs[0].recording))
    truth, nav = run.require_truth(), run.require_nav()
    assert np.max(np.abs(truth["lat"])) > math.radians(89.99999)  # the truth passes within cm of the pole
    e = nav_errors(truth, nav)
    assert np.all(e.usable)
    for a in (e.pos, e.vel, e.att):
        assert np.all(np.isfinite(a))
    near = np.abs(e.t_ns - 167_540_000_000) < 2_000_000_000
    assert near.sum() > 300
    # 1' heading bias plus a 0.1' Gauss-Markov, the same before, at and after the pole
    for when in (e.t_ns < 160e9, near, e.t_ns > 175e9):
        assert np.all(np.abs(e.att[when, 0] - ARCMIN) < 0.5 * ARCMIN)
    # the 0.05 m/s east bias (velocity quantised to 0.1 mm/s)
    np.testing.assert_allclose(e.vel, np.tile([0.05, 0.0, 0.0], (len(e.vel), 1)), atol=1e-4)
    assert np.max(np.hypot(e.pos[:, 0], e.pos[:, 1])) < 8.0
