"""Re-scoring recordings offline gives exactly the live verdicts and numbers; ``bench
accept`` and ``bench score`` write the same results; exit codes keep FAIL and ERROR apart."""

from __future__ import annotations

import json

import pytest

from bench.acceptance.case import load_case
from bench.acceptance.judge import score_recording
from bench.acceptance.suite import SuiteOptions, run_case
from bench.acceptance.verdict import Verdict
from bench.cli.app import run as cli
from bench.cli.score import score_files
from bench.report.results import case_json, results_json, run_json
from tests.acceptance.conftest import base_case

VARIANTS = """
[dut.variants.good]
description = "small error"

[dut.variants.poor]
description = "larger error, drifting in the tunnel"

[[dut.variants.poor.synthetic.error]]
kind = "bias"
quantity = "position"
value = ["3 m", "4 m", "0 m"]

[[dut.variants.poor.synthetic.error]]
kind = "markov"
quantity = "position"
sigma = ["4 m", "4 m", "1 m"]
tau = "20 s"

[[dut.variants.poor.synthetic.error]]
kind = "segment_drift"
quantity = "position"
gnss = ["blocked"]
rate = ["0.1 m/s", "0.1 m/s", "0 m/s"]
recovery = "10 s"

[[criterion]]
id = "BETTER"
variant = "good"
relative_to = "poor"
requirement = "R2"
metric = "accuracy.horizontal.rms"
at_most = 0.9

[[criterion]]
id = "TUNNEL"
requirement = "R2"
metric = "accuracy.horizontal.growth"
window = { gnss = "blocked" }
at_most = "2 m"
monte_carlo = { pass_runs = 2 }

[[criterion]]
id = "NEES"
requirement = "R2"
metric = "consistency.position.above"
at_most = "50 %"
"""


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    from tests.acceptance.conftest import DRIVE

    d = tmp_path_factory.mktemp("live")
    (d / "drive.toml").write_text(DRIVE)
    text = base_case().replace("seeds = [1]", "seeds = [1, 2, 3]") + VARIANTS
    (d / "case.toml").write_text(text)
    case = load_case(d / "case.toml")
    result = run_case(case, SuiteOptions(d / "out"))
    return d, case, result


def test_live_result_is_judged_per_variant_and_seed(live):
    _, _, result = live
    assert len(result.runs) == 6
    by_id = {(c.criterion.id, c.variant): c for c in result.criteria}
    assert by_id[("BETTER", "good")].verdict is Verdict.PASS
    assert by_id[("TUNNEL", "good")].verdict is Verdict.PASS
    assert by_id[("TUNNEL", "poor")].verdict is Verdict.FAIL  # drift and wander through the 30 s tunnel
    assert by_id[("TUNNEL", "poor")].aggregate.value > 2.0
    assert result.verdict is Verdict.FAIL


def test_rescoring_each_recording_gives_the_live_numbers_bit_for_bit(live):
    _, _, result = live
    for run in result.runs:
        _, again = score_recording(run.recording)  # the case attached to the recording
        assert json.dumps(run_json(again)) == json.dumps(run_json(run))
        for cid, rv in run.values.items():
            assert again.values[cid].value == rv.value or (
                rv.value != rv.value and again.values[cid].value != again.values[cid].value
            )


def test_rescoring_all_recordings_gives_the_live_case_result(live):
    _, _, result = live
    again = score_files([r.recording for r in result.runs])
    assert len(again) == 1
    assert json.dumps(case_json(again[0]), sort_keys=True) == json.dumps(case_json(result), sort_keys=True)


def test_bench_accept_and_bench_score_write_identical_cases(live, capsys):
    d, _, _ = live
    out = d / "cli"
    code = cli(["accept", str(d / "case.toml"), "-o", str(out), "-q", "--no-plots"])
    assert code == 1  # a criterion FAILed
    accepted = json.loads((out / "results.json").read_text())
    recordings = sorted(str(p) for p in (out / "recordings" / "T1").glob("*.mcap"))
    assert len(recordings) == 6
    code = cli(["score", *recordings, "--json", str(d / "rescored.json"), "--junit", str(d / "j.xml")])
    assert code == 1
    rescored = json.loads((d / "rescored.json").read_text())
    assert rescored["cases"] == accepted["cases"]
    for name in ("junit.xml", "summary.txt", "summary.md"):
        assert (out / name).exists()
    assert "TUNNEL" in capsys.readouterr().out


def test_score_against_another_case_file(live, tmp_path):
    d, _, result = live
    text = base_case(limit="4 m", band="0 m").replace("seeds = [1]", "seeds = [1, 2, 3]") + VARIANTS
    (d / "strict.toml").write_text(text)
    judged = score_files([result.runs[0].recording], d / "strict.toml")
    h = next(c for c in judged[0].criteria if c.criterion.id == "H")
    assert h.verdict is Verdict.FAIL and h.aggregate.value == pytest.approx(5.0, abs=0.02)


NO_DATA = """
[[criterion]]
requirement = "R1"
metric = "accuracy.horizontal.max"
window = { kind = "climb" }
at_most = "1 m"
"""


@pytest.mark.parametrize(
    ("limit", "extra", "code", "verdict"),
    [
        ("6 m", "", 0, "PASS"),
        ("5.2 m", "", 0, "MARGINAL"),
        ("4 m", "", 1, "FAIL"),
        (
            "6 m",
            NO_DATA,
            3,
            "ERROR",
        ),
    ],
)
def test_accept_exit_codes(make_case, drive_dir, limit, extra, code, verdict):
    p = make_case(base_case(limit=limit) + extra)
    out = drive_dir / "out"
    assert cli(["accept", str(p), "-o", str(out), "-q", "--no-plots"]) == code
    assert json.loads((out / "results.json").read_text())["cases"][0]["verdict"] == verdict


def test_malformed_case_is_a_usage_error_and_reported(make_case, drive_dir):
    p = make_case(base_case(limit="6 m/s"))
    out = drive_dir / "out"
    assert cli(["accept", str(p), "-o", str(out), "-q", "--no-plots"]) == 2
    doc = json.loads((out / "results.json").read_text())
    assert doc["cases"][0]["verdict"] == "ERROR"
    assert "criterion[0].at_most" in doc["cases"][0]["errors"][0]


def test_bench_error_at_run_end_is_error_not_fail(make_case, drive_dir):
    text = base_case(limit="4 m").replace('latency = "3 ms"', 'latency = "3 ms"\nbench_status = "timing_budget"')
    case = load_case(make_case(text))
    result = run_case(case, SuiteOptions(drive_dir / "out"))
    assert result.verdict is Verdict.ERROR  # would be FAIL on its numbers: the bench cannot judge
    assert result.runs[0].bench_issues and "timing_budget" in result.runs[0].bench_issues[0]
    assert result.criteria[0].runs[0].value == pytest.approx(5.0, abs=0.02)  # still measured, for the record


def test_dut_error_at_run_end_is_error(make_case, drive_dir):
    # a DUT ending the bench cannot pin on the DUT (a SIGKILL it did not send): ERROR, with the reason
    text = base_case().replace('latency = "3 ms"', 'latency = "3 ms"\nbench_status = "dut_error"')
    result = run_case(load_case(make_case(text)), SuiteOptions(drive_dir / "out"))
    assert result.verdict is Verdict.ERROR and "dut_error" in result.runs[0].bench_issues[0]
    assert "cannot tell" in result.runs[0].bench_issues[0]


def test_dut_failed_at_run_end_is_fail_even_where_the_numbers_pass(make_case, drive_dir):
    # a DUT that crashed, hung or flooded the bus failed its run: FAIL with the reason, never ERROR
    text = base_case().replace('latency = "3 ms"', 'latency = "3 ms"\nbench_status = "dut_failed"')
    result = run_case(load_case(make_case(text)), SuiteOptions(drive_dir / "out"))
    assert result.verdict is Verdict.FAIL and not result.runs[0].bench_issues
    assert "dut_failed" in result.runs[0].dut_issues[0]
    assert result.criteria[0].verdict is Verdict.PASS  # what it delivered was measured: the run fails, not it


def test_results_json_is_strict_json(live):
    _, _, result = live
    text = json.dumps(results_json([result]), allow_nan=False)
    assert "NaN" not in text and "Infinity" not in text


def test_a_reference_case_runs_end_to_end(tmp_path):
    from bench import paths

    case = paths.test_cases_dir() / "S003b_frame_switch_commanded.toml"
    out = tmp_path / "reports"
    assert cli(["accept", str(case), "-o", str(out), "--seed", "1", "-q", "--no-plots"]) == 0
    doc = json.loads((out / "results.json").read_text())
    (c,) = doc["cases"]
    assert c["verdict"] in ("PASS", "MARGINAL")
    assert {r["variant"] for r in c["runs"]} == {"with_conversion", "without_conversion", "without_conversion_copy"}
    gain = next(x for x in c["criteria"] if x["id"] == "GAIN")
    assert gain["paper"].startswith("horizontal position accuracy about 29 %")
    assert 0.0 < gain["value"] <= 1.1  # with conversion over the restarted filter, same seed
    step = next(x for x in c["criteria"] if x["id"] == "POS-STEP")
    assert step["verdict"] == "PASS" and step["value"] <= 2.0


@pytest.mark.parametrize(("mode", "verdict"), [("realtime", Verdict.ERROR), ("lockstep", Verdict.PASS)])
def test_timing_budget_applies_to_the_clock_the_run_used(make_case, mode, verdict):
    import numpy as np

    from bench.acceptance.synthetic import case_trajectory
    from tests.scoring.helpers import nav_of, quality_of, truth_of, write_recording

    text = base_case().replace("[run]", '[clock]\nmode = "lockstep"\nbudget = "1 ms"\n\n[run]')
    case = load_case(make_case(text))
    traj, _, _ = case_trajectory(case)
    truth = truth_of(traj)
    nav = nav_of(traj, truth["t_ns"], pos_enu=(3.0, 4.0, 0.0))
    timing = np.zeros(10, dtype=[("t_ns", "<i8"), ("lateness_ns", "<i8")])
    timing["lateness_ns"][3] = 2_000_000  # one step 2 ms late
    rec = write_recording(
        case.path.parent / f"{mode}.mcap",
        truth=truth,
        nav=nav,
        quality=quality_of(nav),
        timing=timing,
        run_start={"case": "T1", "seed": "1", "clock_mode": mode},
        attachments={"case/case.toml": text.encode()},
    )
    _, result = score_recording(rec)
    assert result.verdict is verdict
