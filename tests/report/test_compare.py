"""``bench compare``: real runs of a short case with a good and a worse synthetic DUT
configuration, and hand-made records for the direction logic and malformed inputs."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from bench.cli.app import run as cli
from bench.report.compare import (
    CHANGED,
    IMPROVEMENT,
    MISSING,
    NEW,
    REGRESSION,
    SAME,
    badness,
    compare,
    load_record,
    value_status,
    verdict_change,
)
from tests.acceptance.conftest import DRIVE, base_case

# Two more criteria on the same metric with a loose limit, so only the tolerance decides:
# the worse configuration moves the value by 0.598 m, just over H2's and just under H3's.
TOLERANCES = """
[[criterion]]
id = "H2"
requirement = "R2"
metric = "accuracy.horizontal.rms"
at_most = "20 m"
compare_tolerance = "0.59 m"

[[criterion]]
id = "H3"
requirement = "R2"
metric = "accuracy.horizontal.rms"
at_most = "20 m"
compare_tolerance = "61 cm"
"""
GOOD = 'value = ["3 m", "4 m", "0 m"]'  # 5 m horizontal bias
WORSE = 'value = ["3.36 m", "4.48 m", "0 m"]'  # 5.6 m: H (<= 6 m, 0.5 m band) PASS -> MARGINAL
SCRIPT = "<script>alert(1)</script>"


def _accept(folder: Path, name: str, text: str) -> Path:
    case = folder / f"{name}.toml"
    case.write_text(text)
    out = folder / name
    assert cli(["accept", str(case), "-o", str(out), "--no-plots", "-q"]) in (0, 1)
    return out / "results.json"


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """results.json of the good configuration (twice) and of the worse one."""
    d = tmp_path_factory.mktemp("compare")
    (d / "drive.toml").write_text(DRIVE)
    good = base_case() + TOLERANCES
    worse = good.replace(GOOD, WORSE).replace('kind = "synthetic"', f'kind = "synthetic"\nname = "{SCRIPT}"')
    assert worse != good
    return {"a": _accept(d, "a", good), "a2": _accept(d, "a2", good), "b": _accept(d, "b", worse)}


def _compare(capsys, *args: str) -> tuple[int, str, str]:
    code = cli(["compare", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def _rows(out_dir: Path) -> dict[str, dict]:
    data = json.loads((out_dir / "compare.json").read_text())
    return {r["criterion"]: r for r in data["criteria"]}


def test_two_identical_runs_have_no_regression(runs, capsys, tmp_path):
    code, out, _ = _compare(capsys, runs["a"], runs["a2"].parent, "-o", tmp_path)
    assert code == 0
    assert "no regression" in out and "REGRESSION" not in out
    rows = _rows(tmp_path)
    assert rows["H"]["a"] == pytest.approx(5.0, abs=0.01) and rows["H"]["delta"] == 0.0
    assert {r["status"] for r in rows.values()} == {SAME}
    assert json.loads((tmp_path / "compare.json").read_text())["regression"] is False


def test_worse_configuration_is_a_regression(runs, capsys, tmp_path):
    code, out, _ = _compare(capsys, runs["a"], runs["b"], "-o", tmp_path)
    assert code == 1
    rows = _rows(tmp_path)
    h = rows["H"]
    assert h["status"] == REGRESSION and h["regression"]
    assert (h["a"], h["b"]) == (pytest.approx(5.0, abs=0.01), pytest.approx(5.6, abs=0.01))
    assert h["delta"] == pytest.approx(h["b"] - h["a"]) == pytest.approx(0.6, abs=0.01)
    assert h["relative_delta"] == pytest.approx(h["delta"] / h["a"])
    assert h["tolerance"] == pytest.approx(0.05 * h["a"]) and h["tolerance_source"] == "default"  # 5 % of A
    assert (h["verdict_a"], h["verdict_b"], h["verdict_change"]) == ("PASS", "MARGINAL", "worse")
    # tolerances from the case: 0.598 m is just over 0.59 m and just under 0.61 m
    assert 0.59 < h["delta"] < 0.61
    assert rows["H2"]["status"] == REGRESSION and rows["H2"]["tolerance"] == pytest.approx(0.59)
    assert rows["H3"]["status"] == SAME and rows["H3"]["tolerance"] == pytest.approx(0.61)
    assert rows["H3"]["tolerance_source"] == "case"
    assert rows["INTEGRITY-gap"]["status"] == SAME  # the worse bias changes nothing else
    assert "verdict changes:" in out and "worse   T1 H: PASS -> MARGINAL" in out
    assert "case T1: case verdict worse: PASS -> MARGINAL" in out
    assert out.rstrip().splitlines()[-1] == "REGRESSION (3)"  # H, H2 and the case verdict PASS -> MARGINAL
    assert json.loads((tmp_path / "compare.json").read_text())["summary"]["regressions"] == 3


def test_better_configuration_is_an_improvement(runs, capsys, tmp_path):
    code, out, _ = _compare(capsys, runs["b"], runs["a"], "-o", tmp_path)
    assert code == 0 and "no regression" in out
    rows = _rows(tmp_path)
    assert rows["H"]["status"] == IMPROVEMENT and rows["H"]["delta"] == pytest.approx(-0.6, abs=0.01)
    assert rows["H"]["verdict_change"] == "better" and not rows["H"]["regression"]
    assert rows["H2"]["status"] == IMPROVEMENT and rows["H3"]["status"] == SAME


@pytest.mark.parametrize(
    ("options", "h2", "h3"),
    [
        (["--tol", "H2=0.61"], SAME, SAME),  # a bare number: the display unit (m)
        (["--tol", "H2=59 cm"], REGRESSION, SAME),
        (["--tol", "T1:H3=0.5m"], REGRESSION, REGRESSION),  # the command line overrides the case
        (["--tol-rel", "H2=13%"], SAME, SAME),  # 0.65 m
        (["--tol-rel", "H2=0.11"], REGRESSION, SAME),  # 0.55 m
    ],
)
def test_command_line_tolerances(runs, capsys, tmp_path, options, h2, h3):
    code, _, err = _compare(capsys, runs["a"], runs["b"], "-o", tmp_path, *options)
    assert code == 1, err  # H's verdict got worse: a regression whatever the tolerance
    rows = _rows(tmp_path)
    assert (rows["H2"]["status"], rows["H3"]["status"]) == (h2, h3)


def test_verdict_change_is_a_regression_within_tolerance(runs, capsys, tmp_path):
    code, out, _ = _compare(capsys, runs["a"], runs["b"], "-o", tmp_path, "--tol", "H=1 m")
    assert code == 1
    h = _rows(tmp_path)["H"]
    assert h["status"] == SAME and h["verdict_change"] == "worse" and h["regression"]
    assert "REGRESSION (verdict)" in out


def test_dut_text_is_escaped_in_html(runs, capsys, tmp_path):
    data = json.loads(runs["b"].read_text())
    data["cases"][0]["criteria"][0]["reason"] = f"DUT said {SCRIPT}\x1b[2J"
    b = tmp_path / "b.json"
    b.write_text(json.dumps(data))
    code, out, _ = _compare(capsys, runs["a"], b, "-o", tmp_path)
    assert code == 1
    page = (tmp_path / "compare.html").read_text()
    assert "<script" not in page
    assert page.count("&lt;script&gt;alert(1)&lt;/script&gt;") >= 2  # the DUT name and the reason
    assert "\x1b" not in page and "\\x1b[2J" in page
    assert "\x1b" not in out and SCRIPT in out  # the terminal gets it visible, not interpreted


def _record(criteria: list[dict], case: str = "C", verdict: str = "PASS", **top) -> dict:
    return {"schema": "bench.results.v1", "verdict": verdict, "cases": [
        {"id": case, "title": "t", "verdict": verdict, "dut": {"kind": "synthetic", "name": "d"}, "criteria": criteria}
    ], **top}


def _crit(cid: str, value, comparator: str = "at_most", low=None, high=10.0, verdict: str = "PASS", **kw) -> dict:
    return {"id": cid, "comparator": comparator, "value": value, "unit": "m", "verdict": verdict,
            "limit_si": {"low": low, "high": high}, "variant": None, "control": False, **kw}


def _write(tmp_path: Path, name: str, rec: dict) -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(rec))
    return p


def _cmp(tmp_path, a: list[dict], b: list[dict], **kw):
    return compare(load_record(_write(tmp_path, "a.json", _record(a))),
                   load_record(_write(tmp_path, "b.json", _record(b))), **kw)


def test_direction_follows_the_comparator():
    assert badness(3.0, "at_most", None, 5.0) < badness(4.0, "at_most", None, 5.0)
    assert badness(3.0, "at_least", 1.0, None) > badness(4.0, "at_least", 1.0, None)
    assert badness(-2.0, "within", None, 5.0) == badness(2.0, "within", None, 5.0)
    assert badness(1.0, "in_range", 0.0, 4.0) > badness(2.5, "in_range", 0.0, 4.0)
    at_least = lambda x: badness(x, "at_least", 1.0, None)  # noqa: E731
    assert value_status(5.0, 4.0, at_least, 0.5) == REGRESSION
    assert value_status(5.0, 6.0, at_least, 0.5) == IMPROVEMENT
    assert value_status(5.0, 5.4, at_least, 0.5) == SAME
    assert value_status(-2.0, 2.0, lambda x: badness(x, "within", None, 5.0), 0.0) == SAME
    in_range = lambda x: badness(x, "in_range", 0.0, 4.0)  # noqa: E731
    assert value_status(2.0, 3.5, in_range, 0.5) == REGRESSION and value_status(3.8, 1.0, in_range, 0.5) == IMPROVEMENT
    at_most = lambda x: badness(x, "at_most", None, 5.0)  # noqa: E731
    assert value_status(1.0, math.inf, at_most, 1e9) == REGRESSION  # beyond any tolerance
    assert value_status(math.inf, 1.0, at_most, 1e9) == IMPROVEMENT
    assert value_status(math.inf, math.inf, at_most, 0.0) == SAME
    assert value_status(1.0, None, at_most, 0.0) == REGRESSION  # B lost the measurement
    assert value_status(None, 1.0, at_most, 0.0) == IMPROVEMENT
    assert value_status(None, None, at_most, 0.0) == SAME
    assert value_status(1.0, 3.0, at_most, 0.5, control=True) == CHANGED
    assert value_status(1.0, 1.2, at_most, 0.5) == SAME and value_status(1.0, 1.5, at_most, 0.5) == SAME
    assert value_status(1.0, 1.5000001, at_most, 0.5) == REGRESSION


def test_verdict_changes():
    assert verdict_change("PASS", "PASS") is None
    assert verdict_change("PASS", "MARGINAL") == verdict_change("FAIL", "ERROR") == "worse"
    assert verdict_change("ERROR", "FAIL") == verdict_change("MARGINAL", "PASS") == "better"
    assert verdict_change("PASS", "N/A") == verdict_change("N/A", "FAIL") == "changed"


def test_hand_made_records(tmp_path):
    cmp = _cmp(tmp_path,
               [_crit("up", 2.0), _crit("floor", 0.0), _crit("gone", 1.0), _crit("inf", "inf"),
                _crit("rng", 2.0, "in_range", 0.0, 4.0), _crit("tol", 2.0, compare_tolerance_relative=0.5)],
               [_crit("up", 2.2), _crit("floor", 0.09), _crit("new", 1.0), _crit("inf", 3.0),
                _crit("rng", 1.0, "in_range", 0.0, 4.0, verdict="MARGINAL"), _crit("tol", 2.9)])
    rows = {r.criterion: r for r in cmp.rows}
    assert rows["up"].status == REGRESSION and rows["up"].delta == pytest.approx(0.2)  # 5 % of 2 m is 0.1 m
    assert rows["up"].relative_delta == pytest.approx(0.1)
    assert rows["floor"].status == SAME and rows["floor"].tolerance == pytest.approx(0.1)  # 1 % of the 10 m limit
    assert rows["gone"].status == MISSING and rows["gone"].regression
    assert rows["new"].status == NEW and not rows["new"].regression
    assert rows["inf"].status == IMPROVEMENT and rows["inf"].delta == -math.inf
    assert rows["rng"].status == REGRESSION and rows["rng"].verdict_change == "worse"
    assert rows["tol"].status == SAME and rows["tol"].tolerance == pytest.approx(1.0)
    assert cmp.regressed


def test_cases_on_one_side_only(tmp_path, capsys):
    a = _record([_crit("x", 1.0)], case="OLD")
    b = _record([_crit("x", 1.0)], case="OLD")
    b["cases"].append({**b["cases"][0], "id": "NEW"})
    pa, pb = _write(tmp_path, "a.json", a), _write(tmp_path, "b.json", b)
    code, out, _ = _compare(capsys, pa, pb)
    assert code == 0 and "case NEW: not compared (in B only)" in out  # a new case is noted
    # a case absent from B is not compared, not a regression (issue 34: like with like);
    # the case both have is compared
    code, out, _ = _compare(capsys, pb, pa)
    assert code == 0 and "case NEW: not compared (in A only)" in out and out.rstrip().endswith("no regression")
    # and when no case is on both sides, nothing was compared: exit 3, never "no regression"
    code, out, _ = _compare(capsys, pb, _write(tmp_path, "c.json", _record([_crit("x", 1.0)], case="OTHER")))
    assert code == 3 and "no regression" not in out and "nothing compared like with like" in out


def test_identification_is_shown(tmp_path, capsys):
    b = _record([_crit("x", 1.0)], identification={"bench": {"version": "9.9", "commit": "cafe"},
                                                   "inputs": [{"sha256": "00"}]})
    code, out, _ = _compare(capsys, _write(tmp_path, "a.json", _record([_crit("x", 1.0)])),
                            _write(tmp_path, "b.json", b))
    assert code == 0
    assert "bench.version 9.9" in out and "bench.commit cafe" in out and "sha256" not in out


@pytest.mark.parametrize(
    ("content", "field"),
    [
        ("not json {", "not JSON"),
        ("[1, 2]", "expected a JSON object"),
        ('{"schema": "bench.results.v1"}', "cases"),
        ('{"schema": "other", "cases": []}', "schema"),
        (json.dumps(_record([_crit("x", 1.0, comparator="below")])), "cases[0].criteria[0].comparator"),
        (json.dumps(_record([_crit("x", "lots")])), "cases[0].criteria[0].value"),
    ],
)
def test_malformed_input_is_a_usage_error_naming_the_file(tmp_path, capsys, content, field):
    good = _write(tmp_path, "good.json", _record([_crit("x", 1.0)]))
    bad = tmp_path / "bad.json"
    bad.write_text(content)
    code, _, err = _compare(capsys, good, bad)
    assert code == 2
    assert str(bad) in err and field in err


def test_missing_inputs_and_bad_options(tmp_path, capsys):
    good = _write(tmp_path, "good.json", _record([_crit("x", 1.0)]))
    code, _, err = _compare(capsys, good, tmp_path / "nope.json")
    assert code == 2 and "nope.json" in err
    (tmp_path / "empty").mkdir()
    code, _, err = _compare(capsys, good, tmp_path / "empty")
    assert code == 2 and str(tmp_path / "empty" / "results.json") in err
    code, _, err = _compare(capsys, good, good, "--tol", "nothere=1")
    assert code == 2 and "nothere" in err
    code, _, err = _compare(capsys, good, good, "--tol", "x=1 s")
    assert code == 2 and "--tol x" in err
