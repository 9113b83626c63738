"""The fault matrix (issue 34, item 9): ``bench compare`` compares like with like.

On 57b1bce ``bench compare`` of the demo's results against a rerun with another seed called
seed-to-seed variation and the cases absent from B "REGRESSION (11)" (exit 1) and said
nowhere that the seed sets differ. Now only matched cases, variants and seeds are judged:
a case or variant on one side only is "not compared", a difference between different seed
sets is "not comparable" (or, when both sides have several runs, judged over the runs), the
seed sets are stated, and exit 1 means a like-with-like regression (docs/compare.md).

The records are synthesized (what every row checks: tests/fault_matrix/test_inputs.py):
results.json documents of the schema in bench/report/schemas, validated before use, with the
seeds of each criterion's runs, so each row runs ``bench compare`` in a second or two.
"""

from __future__ import annotations

import json
from pathlib import Path

from bench.report.results import validate_results
from tests.fault_matrix.matrix import bench

BENCH = {"bench_version": "0.1.0", "git_commit": "0" * 40, "host": "h", "python": "3.11"}


def _crit(cid: str, runs: dict[int, float], *, variant: str | None = None, limit: float = 10.0,
          control: bool = False, verdicts: dict[int, str] | None = None) -> dict:
    """An ``at_most limit m`` criterion judged on ``runs`` (seed -> value, m); the worst run
    decides (Monte Carlo ``each``), as the bench writes it."""
    verdicts = verdicts or {}
    rv = {s: verdicts.get(s, "PASS" if v <= limit else "FAIL") for s, v in runs.items()}
    rank = ["PASS", "MARGINAL", "FAIL", "ERROR"]
    worst = max(runs.values()) if runs else None
    verdict = max(rv.values(), key=rank.index) if rv else "ERROR"
    return {
        "id": cid, "requirements": ["R1"], "metric": "accuracy.horizontal.rms", "description": "",
        "window": "whole", "window_text": "the whole run", "limit": f"<= {limit} m", "comparator": "at_most",
        "limit_si": {"low": None, "high": limit}, "unit": "m", "marginal_band": None,
        "value": worst, "value_si": worst, "margin": None if worst is None else limit - worst,
        "verdict": verdict, "reason": "" if runs else "no run to judge", "paper": "", "variant": variant,
        "relative_to": None, "control": control, "must_fail_on": [], "monte_carlo": "every run",
        "runs": [{"seed": s, "value": v, "verdict": rv[s], "reason": ""} for s, v in sorted(runs.items())],
    }


def _case(cid: str, criteria: list[dict]) -> dict:
    rank = ["PASS", "MARGINAL", "FAIL", "ERROR"]
    verdict = max((c["verdict"] for c in criteria), key=rank.index) if criteria else "ERROR"
    return {"id": cid, "title": cid, "file": f"{cid}.toml", "requirements": ["R1"], "verdict": verdict,
            "errors": [], "integrity_waived": [], "dut": {"kind": "synthetic", "name": "d"},
            "criteria": criteria, "runs": []}


def _record(path: Path, cases: list[dict]) -> Path:
    """A results record of ``cases``, checked against the results schema, written to ``path``."""
    rank = ["PASS", "MARGINAL", "FAIL", "ERROR"]
    seeds = sorted({r["seed"] for c in cases for k in c["criteria"] for r in k["runs"]})
    counts = {v: sum(c["verdict"] == v for c in cases) for v in [*rank, "N/A"]}
    doc = {
        "schema": "bench.results.v1", "schema_version": 1, "schema_id": "urn:nav-hil-bench:schema:results-1",
        "verdict": max((c["verdict"] for c in cases), key=rank.index), "counts": counts,
        "identification": {"report_id": "0123456789ab", "recordings": 0, "cases": [c["id"] for c in cases],
                           "seeds": seeds, "recorded_by": [BENCH], "judged_by": BENCH, "duts": [],
                           "inputs": [], "command": "bench accept test_cases/ -o reports"},
        "cases": cases, "run_info": {},
    }
    validate_results(doc)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=1))
    return path


def _demo(seeds: tuple[int, ...], shift: float = 0.0, cases: tuple[str, ...] = ("S000", "S001", "S002")) -> list[dict]:
    """Cases of two variants each, like the demo's; a seed's values depend on the seed
    (seed-to-seed variation), ``shift`` moves every value (a real change of the DUT)."""
    out = []
    for cid in cases:
        n, crits = int(cid[-1]), []
        for variant in ("full", "no_odometer"):
            crits.append(_crit("H95", {s: 1.0 + n + 0.3 * s + shift for s in seeds}, variant=variant))
            crits.append(_crit("DR-POS", {s: 4.0 + 0.5 * s + shift for s in seeds}, variant=variant))
        out.append(_case(cid, crits))
    return out


def _compare(tmp_path: Path, a: list[dict], b: list[dict], *extra: str):
    pa, pb = _record(tmp_path / "a" / "results.json", a), _record(tmp_path / "b" / "results.json", b)
    out = tmp_path / "cmp"
    r = bench("compare", str(pa), str(pb), "-o", str(out), *extra, cwd=tmp_path, timeout=60)
    doc = json.loads((out / "compare.json").read_text()) if (out / "compare.json").exists() else {}
    return r, doc


def _last(r) -> str:
    return r.out.rstrip().splitlines()[-1]


# ------------------------------------------------------------------------------ the Why rows
def test_a_rerun_with_another_seed_and_fewer_cases_is_no_regression(tmp_path):
    """The issue's case: the demo (seeds 1, 2; three cases) against a rerun with seed 3 of
    one case: nothing is like with like, nothing is a regression, and it is said so."""
    r, doc = _compare(tmp_path, _demo((1, 2)), _demo((3,), cases=("S000",)))
    assert "REGRESSION" not in r.out, r.out
    assert r.code != 1, r.text
    assert r.code == 3, r.text  # nothing could be compared like with like: the bench could not judge
    assert "seed sets differ" in r.out and "A seeds 1, 2" in r.out and "B seeds 3" in r.out, r.out
    assert "not comparable" in r.out, r.out
    assert "S001: not compared (in A only)" in r.out and "S002: not compared (in A only)" in r.out, r.out
    assert _last(r).startswith("nothing compared like with like"), r.out
    assert doc["regression"] is False and doc["summary"]["regressions"] == 0
    assert doc["summary"]["compared"] == 0 and doc["summary"]["not_comparable"] == 4
    assert {c["status"] for c in doc["cases"] if c["case"] != "S000"} == {"NOT COMPARED"}


def test_cases_absent_from_b_are_listed_not_compared_and_are_no_regression(tmp_path):
    r, doc = _compare(tmp_path, _demo((1, 2)), _demo((1, 2), cases=("S001",)))
    assert r.code == 0, r.text
    assert _last(r) == "no regression", r.out
    assert "S000: not compared (in A only)" in r.out and "S002: not compared (in A only)" in r.out, r.out
    assert doc["summary"]["compared"] == 4 and doc["summary"]["cases_not_compared"] == 2


def test_a_variant_on_one_side_only_is_not_compared(tmp_path):
    b = _demo((1, 2))
    b[1]["criteria"] = [c for c in b[1]["criteria"] if c["variant"] != "no_odometer"]
    r, doc = _compare(tmp_path, _demo((1, 2)), b)
    assert r.code == 0, r.text
    rows = [c for c in doc["criteria"] if c["case"] == "S001" and c["variant"] == "no_odometer"]
    assert len(rows) == 2 and {c["status"] for c in rows} == {"NOT COMPARED"}, rows
    assert not any(c["regression"] for c in rows)
    assert "S001/no_odometer: not compared (in A only)" in r.out, r.out


def test_seed_to_seed_variation_is_not_comparable_and_the_seed_sets_are_stated(tmp_path):
    """Same cases, other seeds (one run each side): the worse values of seed 3 are not a
    regression; each differing seed set is named."""
    r, doc = _compare(tmp_path, _demo((1,)), _demo((3,)))
    assert "REGRESSION" not in r.out and r.code == 3, r.text
    for cid in ("S000", "S001", "S002"):
        assert f"{cid}/full: A seeds 1; B seeds 3" in r.out, r.out
    rows = doc["criteria"]
    assert len(rows) == 12 and {c["status"] for c in rows} == {"NOT COMPARABLE"}
    assert all(c["seeds_a"] == [1] and c["seeds_b"] == [3] for c in rows)


def test_common_seeds_are_compared_and_the_others_are_not(tmp_path):
    """A seeds 1, 2; B seeds 2, 3: seed 2 is compared value for value; seed 3 (worse, as
    seeds go) is not."""
    same = _demo((2, 3))
    r, doc = _compare(tmp_path, _demo((1, 2)), same)
    assert r.code == 0 and _last(r) == "no regression", r.text
    assert {c["basis"] for c in doc["criteria"]} == {"common seeds"}
    assert {c["status"] for c in doc["criteria"]} == {"SAME"}
    # and a real change on the common seed is a regression
    worse = _demo((2, 3))
    worse[0]["criteria"][0]["runs"][0]["value"] += 1.0  # S000 H95/full, seed 2
    r, doc = _compare(tmp_path / "w", _demo((1, 2)), worse)
    assert r.code == 1 and _last(r) == "REGRESSION (1)", r.text
    (row,) = [c for c in doc["criteria"] if c["regression"]]
    assert (row["case"], row["criterion"], row["variant"]) == ("S000", "H95", "full")


def test_several_runs_each_side_are_judged_over_runs(tmp_path):
    """Eight runs each side, other seeds: the same distribution is no regression (the worst
    run differs, as worst runs do); a shift of the whole distribution beyond the tolerance
    is a regression, a significant one."""
    a = [_case("MC", [_crit("H95", {s: 1.0 + 0.1 * s for s in range(1, 9)})])]
    like = [_case("MC", [_crit("H95", {s: 1.05 + 0.1 * (s - 10) for s in range(11, 20)})])]
    r, doc = _compare(tmp_path, a, like)
    assert r.code == 0 and "REGRESSION" not in r.out, r.text
    (row,) = doc["criteria"]
    assert row["basis"] == "over runs" and row["status"] == "SAME" and row["p_value"] > 0.05, row
    worse = [_case("MC", [_crit("H95", {s: 3.0 + 0.1 * (s - 10) for s in range(11, 19)})])]
    r, doc = _compare(tmp_path / "w", a, worse)
    assert r.code == 1 and _last(r) == "REGRESSION (1)", r.text
    (row,) = doc["criteria"]
    assert row["basis"] == "over runs" and row["status"] == "REGRESSION" and row["p_value"] <= 0.05, row


# ----------------------------------------------------------- what must stay a regression
def test_a_real_regression_on_the_same_seeds_still_exits_1(tmp_path):
    r, doc = _compare(tmp_path, _demo((1, 2)), _demo((1, 2), shift=2.0))
    assert r.code == 1 and _last(r) == "REGRESSION (12)", r.text  # 12 criteria; case verdicts stay PASS
    assert "seeds: the same in every case and variant compared" in r.out and "seed sets differ in" not in r.out
    assert doc["summary"]["compared"] == 12 and doc["summary"]["seed_sets_differ"] == 0


def test_a_regression_beside_other_seeds_and_missing_cases_is_counted_alone(tmp_path):
    a = _demo((1, 2))
    b = [*_demo((1, 2), cases=("S000",)), *_demo((5,), cases=("S001",))]
    b[0]["criteria"][1]["runs"][1]["value"] += 1.0  # S000 DR-POS/full seed 2: 5.0 -> 6.0
    b[0]["criteria"][1]["value"] += 1.0
    r, doc = _compare(tmp_path, a, b)
    assert r.code == 1 and _last(r) == "REGRESSION (1)", r.text
    assert doc["summary"]["not_comparable"] == 4 and doc["summary"]["cases_not_compared"] == 1


def test_a_case_that_ran_nothing_in_b_is_still_a_regression(tmp_path):
    """B's case ran no run at all (its criteria unjudged, ERROR): no seed set to differ, so
    it is judged, and it is a regression -- never "not comparable"."""
    b = _demo((1, 2))
    b[0] = _case("S000", [_crit(c["id"], {}, variant=c["variant"]) for c in b[0]["criteria"]])
    r, doc = _compare(tmp_path, _demo((1, 2)), b)
    assert r.code == 1 and "REGRESSION" in _last(r), r.text
    assert all(c["regression"] for c in doc["criteria"] if c["case"] == "S000")


def test_a_worse_verdict_among_other_seeds_is_shown_not_judged(tmp_path):
    """B's seed 5 FAILs a criterion where A's seeds 1, 2 passed: another seed, so not a
    regression -- but the last line says that a worse verdict sits among the not comparable."""
    b = [*_demo((1, 2), cases=("S000", "S002")), *_demo((5,), shift=6.0, cases=("S001",))]
    r, doc = _compare(tmp_path, _demo((1, 2)), b)
    assert r.code == 0, r.text
    assert _last(r) == ("no regression among the 8 criteria compared like with like (4 not comparable: seed sets "
                        "differ, 2 of them with a worse verdict in B)"), r.out
    assert "worse   S001 DR-POS/full: PASS -> FAIL [not comparable: seeds differ (A 1, 2; B 5)" in r.out, r.out
    assert "case S001: case verdict worse: PASS -> FAIL (not judged: its variants or seeds differ)" in r.out, r.out
    assert doc["summary"]["regressions"] == 0 and doc["summary"]["case_verdicts_worse"] == 0
