"""The fault matrix (issue 32), reference cases over Monte Carlo: a consistency that a per-run
band cannot judge fairly (one slowly varying error draw per run) is judged as the Monte Carlo
test over the runs (ANEES against the band of N runs) with a per-run sanity bound, and the
reference cases do so, citing their budget, with the demo's seeds kept.

The long check on the real reference cases is a campaign (docs/estimators.md gives its table):
``bench campaign test_cases/<case>.toml --runs 20 --workers 2``."""

from __future__ import annotations

import json
import re
from pathlib import Path

from bench.acceptance.case import load_case
from tests.fault_matrix.matrix import bench

HERE = Path(__file__).parent.parent
ROOT = HERE.parent
#: the reference cases with consistency criteria, and the seeds bench accept runs (the demo's, kept)
REFERENCE = {"S000_sins_doppler": (1, 2), "S000_external": (1,), "S001_bds_sins": (1, 2),
             "S002_sins_odometer_faults": (1, 2), "S003a_frame_switch_polar": (1, 2),
             "S003b_frame_switch_commanded": (1, 2), "S003c_frame_switch_back": (1, 2),
             "S003d_over_the_pole": (1, 2)}
SANITY = 10.83  # the 99.9 % point of chi-square(1)


def _campaign(folder: Path, text: str) -> dict:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "drive.toml").write_bytes((HERE / "campaign" / "drive.toml").read_bytes())
    (folder / "case.toml").write_text(text)
    bench("campaign", "case.toml", "--runs", "20", "--workers", "1", "-o", "out", "-q", "--no-report", cwd=folder)
    return json.loads((folder / "out" / "campaign.json").read_text())


def test_one_error_draw_per_run_fails_a_per_run_band_and_passes_over_the_runs(tmp_path):
    """A consistent synthetic DUT whose position and heading errors are one slowly varying
    draw per run (as large as its sigmas): judged run by run (the reference cases' former
    criteria) it FAILs on some of 20 seeds; judged by ANEES over the 20 runs it PASSes, and
    the same DUT with errors twice its sigmas FAILs (its negative control)."""
    anees_case = (HERE / "campaign" / "anees_case.toml").read_text()
    per_run = re.sub(r"^(monte_carlo = \{ anees = .*\}|must_fail_on = .*)$", "", anees_case, flags=re.M)
    before = _campaign(tmp_path / "per_run", per_run)["verdicts"]["ANEES-SYN"]
    assert before["verdict"] == "FAIL"
    failed = {c["id"] for c in before["criteria"] if c["verdict"] == "FAIL"}
    assert failed == {"NEES-HDG"}  # a consistent heading, failed on the seeds whose draw is extreme

    after = _campaign(tmp_path / "anees", anees_case)["verdicts"]["ANEES-SYN"]
    assert after["verdict"] == "PASS", after
    got = {(c["id"], c["control"]): c for c in after["criteria"]}
    for cid in ("NEES-POS", "NEES-HDG"):
        assert got[cid, False]["verdict"] == "PASS"
        assert got[cid, False]["monte_carlo"] == "ANEES over 20 runs in its 99 % band"
        assert got[cid, False]["anees"]["runs"] == 20
        assert got[cid, True]["verdict"] == "PASS"  # the overconfident DUT FAILs it, as it must
        assert got[cid, True]["anees"]["above"] > 0.9
        assert got[f"{cid}-RUN", False]["verdict"] == "PASS"


def test_the_reference_cases_judge_consistency_over_the_runs_with_a_sanity_bound_and_their_budget():
    for name, seeds in REFERENCE.items():
        path = ROOT / "test_cases" / f"{name}.toml"
        case = load_case(path)
        assert case.run.seeds == seeds, name  # bench accept keeps the demo's seeds
        crit = [c for c in case.criteria if c.metric.startswith("consistency.")]
        mc = [c for c in crit if c.monte_carlo.mode == "anees"]
        runs = [c for c in crit if c.monte_carlo.mode == "each"]
        assert mc and len(mc) + len(runs) == len(crit), name
        for c in mc:  # each with its per-run sanity bound on the same quantity, variant and window
            q = c.metric.split(".")[1]
            twin = [r for r in runs if r.metric == f"consistency.{q}.nees" and r.variant == c.variant
                    and r.window == c.window]
            assert twin and twin[0].limit.comparator == "at_most" and twin[0].limit.high == SANITY, (name, c.id)
        for r in runs:  # nothing else judged run by run
            assert r.metric.endswith(".nees") and r.limit.high == SANITY, (name, r.id)
        budget = " ".join(case.assumed)
        assert "tests/acceptance/test_anees.py" in budget and "99.9 % point of chi-square(1)" in budget, name
