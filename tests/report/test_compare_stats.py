"""``bench compare`` over runs (issue 34 item 9): the two tests it applies when the seeds
differ and both sides have several runs, checked against values computed independently
(SciPy 1.x ``mannwhitneyu(method="exact")``/``fisher_exact``, and by hand), and the rows
they judge: a verdict rate, a negative control, the significance option, the page."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from bench.cli.app import run as cli
from bench.report.compare import CHANGED, NOT_COMPARABLE, REGRESSION, SAME, compare, load_record
from bench.report.compare_stats import fisher_greater, mann_whitney_greater, median


def test_mann_whitney_exact_values():
    assert mann_whitney_greater([1, 2, 3], [4, 5, 6]) == pytest.approx(1 / 20)  # the one extreme of C(6, 3)
    assert mann_whitney_greater([4, 5, 6], [1, 2, 3]) == pytest.approx(1.0)
    assert mann_whitney_greater([1, 2], [3, 4]) == pytest.approx(1 / 6)  # 2 + 2 never reaches 0.05
    a = [1.1 + 0.1 * i for i in range(8)]
    b = [1.15 + 0.1 * i for i in range(9)]
    assert mann_whitney_greater(a, b) == pytest.approx(0.24035376388317564)  # SciPy, exact
    assert mann_whitney_greater([1, 1, 1], [1, 1, 1]) == pytest.approx(1.0)  # all tied: no evidence
    assert mann_whitney_greater([1, 2, 2], [2, 3, 3]) == pytest.approx(0.15)  # mid-ranks, counted by hand
    assert mann_whitney_greater([], [1.0]) == 1.0


def test_mann_whitney_normal_approximation_beyond_30_runs():
    a, b = list(range(20)), [x + 0.5 for x in range(20)]
    assert mann_whitney_greater(a, b) == pytest.approx(0.3985987096345874, rel=1e-9)  # SciPy, asymptotic
    assert mann_whitney_greater(a, [x + 30 for x in range(20)]) < 1e-6
    assert mann_whitney_greater([math.inf] * 16, [math.inf] * 16) == 1.0


def test_fisher_exact_values():
    assert fisher_greater(0, 3, 3, 3) == pytest.approx(0.05)  # SciPy fisher_exact, greater
    assert fisher_greater(0, 2, 2, 2) == pytest.approx(1 / 6)
    assert fisher_greater(1, 8, 1, 8) == pytest.approx(0.7666666666666667)
    assert fisher_greater(0, 0, 3, 3) == 1.0
    assert median([3, 1, 2]) == 2 and median([4, 1, 2, 3]) == 2.5


def _crit(runs: dict[int, float], verdicts: dict[int, str] | None = None, control: bool = False) -> dict:
    verdicts = verdicts or {}
    rv = [{"seed": s, "value": v, "verdict": verdicts.get(s, "PASS"), "reason": ""} for s, v in runs.items()]
    rank = ["PASS", "MARGINAL", "FAIL", "ERROR"]
    return {"id": "H", "comparator": "at_most", "value": max(runs.values()), "unit": "m",
            "verdict": max((r["verdict"] for r in rv), key=rank.index), "limit_si": {"low": None, "high": 10.0},
            "variant": "v", "control": control, "runs": rv}


def _write(path: Path, crit: dict) -> Path:
    path.write_text(json.dumps({"schema": "bench.results.v1", "verdict": "PASS", "cases": [
        {"id": "C", "title": "t", "verdict": crit["verdict"], "criteria": [crit], "runs": []}]}))
    return path


def _cmp(tmp_path: Path, a: dict, b: dict, **kw):
    cmp = compare(load_record(_write(tmp_path / "a.json", a)), load_record(_write(tmp_path / "b.json", b)), **kw)
    (row,) = cmp.rows
    return cmp, row


def test_more_runs_not_pass_is_a_regression_whatever_the_values(tmp_path):
    a = _crit({s: 2.0 for s in range(1, 7)})
    b = _crit({s: 2.0 for s in range(11, 17)}, verdicts={s: "FAIL" for s in range(11, 17)})
    cmp, row = _cmp(tmp_path, a, b)
    assert row.basis == "over runs" and row.status == REGRESSION and row.regression
    assert row.p_verdicts == pytest.approx(1 / 924)  # 1 / C(12, 6)
    # one FAIL in six more than A's is not evidence
    b = _crit({s: 2.0 for s in range(11, 17)}, verdicts={11: "FAIL"})
    cmp, row = _cmp(tmp_path, a, b)
    assert row.status == SAME and not cmp.regressed and row.p_verdicts == pytest.approx(0.5)


def test_a_significant_shift_within_the_tolerance_is_same(tmp_path):
    a = _crit({s: 2.0 + 0.001 * s for s in range(1, 7)})
    b = _crit({s: 2.05 + 0.001 * s for s in range(11, 17)})  # every run worse, by 0.05 m < 0.1 m (5 % of 2 m)
    cmp, row = _cmp(tmp_path, a, b)
    assert row.p_value <= 0.05 and row.status == SAME and not cmp.regressed
    assert row.delta == pytest.approx(0.06)  # the medians, 2.0035 -> 2.0635 m


def test_a_control_over_runs_changes_and_its_verdicts_judge(tmp_path):
    a = _crit({s: 20.0 + s for s in range(1, 7)}, control=True)
    b = _crit({s: 40.0 + s for s in range(11, 17)}, control=True)
    _, row = _cmp(tmp_path, a, b)
    assert row.status == CHANGED and not row.regression
    b = _crit({s: 20.0 + s for s in range(11, 17)}, verdicts={s: "FAIL" for s in range(11, 17)}, control=True)
    _, row = _cmp(tmp_path, a, b)
    assert row.status == REGRESSION  # the criterion no longer tells the DUT from its control


def test_two_runs_a_side_are_not_comparable_and_alpha_is_an_option(tmp_path, capsys):
    a, b = _crit({1: 1.0, 2: 1.1}), _crit({3: 5.0, 4: 5.1})
    cmp, row = _cmp(tmp_path, a, b)
    assert row.status == NOT_COMPARABLE and not cmp.regressed and cmp.compared == 0
    a, b = _crit({s: 1.0 + 0.01 * s for s in range(1, 5)}), _crit({s: 5.0 + 0.01 * s for s in range(11, 15)})
    pa, pb = _write(tmp_path / "a.json", a), _write(tmp_path / "b.json", b)
    assert cli(["compare", str(pa), str(pb), "-o", str(tmp_path / "out")]) == 1  # p = 1/70
    assert cli(["compare", str(pa), str(pb), "--alpha", "0.01"]) == 0  # not significant at 1 %
    assert cli(["compare", str(pa), str(pb), "--alpha", "0"]) == 2
    out = capsys.readouterr().out
    page = (tmp_path / "out" / "compare.html").read_text()
    assert "<h2>Seeds</h2>" in page and "A seeds 1, 2, 3, 4; B seeds 11, 12, 13, 14 -- judged over runs" in page
    assert "A seeds 1, 2, 3, 4; B seeds 11, 12, 13, 14 -- judged over runs" in out
    doc = json.loads((tmp_path / "out" / "compare.json").read_text())
    assert doc["criteria"][0]["basis"] == "over runs" and doc["criteria"][0]["p_value"] == pytest.approx(1 / 70)
    assert doc["settings"]["alpha"] == 0.05 and doc["settings"]["min_runs"] == 3
