"""The batch DUT kind through ``bench run``: a good one PASSes, a failing one FAILs with
the reason named (never a crash, never ERROR), and its case keys are checked on load."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.acceptance.case import load_case, parse_case
from bench.cli import main
from bench.errors import ConfigError
from bench.record.mcap_io import RecordingReader

HERE = Path(__file__).parent
CASE = HERE / "batch_case.toml"
SCRIPT = HERE / "batch_dut.py"
REC = Path("recordings") / "BATCH" / "BATCH-s1.mcap"


def _case(tmp_path: Path, mode: str, timeout: str = "60 s") -> Path:
    text = CASE.read_text()
    text = text.replace('"batch_dut.py"', json.dumps(str(SCRIPT))).replace('"truth"]', f'"{mode}"]')
    text = text.replace('timeout = "60 s"', f'timeout = "{timeout}"')
    p = tmp_path / f"batch_{mode}.toml"
    p.write_text(text)
    return p


def _results(out: Path) -> dict:
    return json.loads((out / "results.json").read_text())["cases"][0]


def test_a_good_batch_dut_passes(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(CASE), "-o", str(out), "-q", "--no-plots"]) == 0
    case = _results(out)
    assert case["verdict"] == "PASS"
    assert {c["id"] for c in case["criteria"]} >= {"POS", "HDG", "INTEGRITY-quality"}
    with RecordingReader(out / REC) as r:
        assert r.intact and r.metadata()["run_end"]["status"] == "complete"
        assert r.metadata()["run_start"]["runner"] == "batch"
        assert len(r.read_columnar("/dut/nav_solution")) == 3001  # the truth's epochs, 100 Hz over 30 s
        assert len(r.read_columnar("/dut/nav_quality")) == 3001
        assert any("wrote 3001 epochs" in doc["text"] for _, doc in r.iter_json("/dut/log"))
        assert len(r.read_columnar("/imu")) == 6000
    work = out / REC.parent / "BATCH-s1.batch"
    assert (work / "input" / "imu.txt").is_file() and (work / "input" / "kf-gins.yaml").is_file()
    # the recording is judged again by bench score with the same verdict
    assert main(["score", str(out / REC)]) == 0


@pytest.mark.parametrize(
    ("mode", "timeout", "reason"),
    [
        ("fail", "60 s", "the batch DUT exited with code 3 (last output: fatal: no GNSS fix to initialise from)"),
        ("garbage", "60 s", "result.nav: line 1, column 11 (yaw): expected a number, found 'not-a-number'"),
        ("nothing", "60 s", "the batch DUT exited with code 0 but wrote no result (result.nav)"),
        ("hang", "1 s", "the batch DUT did not finish within its timeout of 1 s (killed)"),
    ],
)
def test_a_failing_batch_dut_fails_with_the_reason(tmp_path, capsys, mode, timeout, reason):
    out = tmp_path / "out"
    assert main(["run", str(_case(tmp_path, mode, timeout)), "-o", str(out), "-q", "--no-plots"]) == 1
    case = _results(out)
    assert case["verdict"] == "FAIL" and not case["errors"]
    run = case["runs"][0]
    assert run["verdict"] == "FAIL" and not run["bench_issues"]
    assert any(reason in issue for issue in run["dut_issues"]), run["dut_issues"]
    with RecordingReader(out / REC) as r:
        assert r.intact and r.metadata()["run_end"]["status"] == "dut_failed"
        assert reason in r.metadata()["run_end"]["reason"]
    assert main(["score", str(out / REC)]) == 1


def test_batch_keys_are_checked_on_load(tmp_path):
    base = CASE.read_text()

    def load(text: str):
        return parse_case(text, file="case.toml", base=HERE)

    with pytest.raises(ConfigError, match=r"dut.command: expected the command as a non-empty array of words"):
        load(base.replace('command = ["{python}", "batch_dut.py", "{input}", "{output}", "truth"]',
                          'command = "python batch_dut.py"'))
    with pytest.raises(ConfigError, match=r"dut.command: unknown placeholder \{imu_port\}"):
        load(base.replace('"{input}"', '"{imu_port}"'))
    with pytest.raises(ConfigError, match=r"dut.timeout: expected"):
        load(base.replace('timeout = "60 s"', 'timeout = "2 m"'))
    with pytest.raises(ConfigError, match=r"dut.imu: expected one of 'measured', 'ideal'"):
        load(base.replace('timeout = "60 s"', 'timeout = "60 s"\nimu = "raw"'))
    batch_lines = 'kind = "batch"\ncommand = ["{python}", "batch_dut.py", "{input}", "{output}", "truth"]\n'
    in_process = base.replace(batch_lines, 'kind = "in_process"\nname = "dead_reckoning"\n')
    with pytest.raises(ConfigError, match=r"dut.timeout: 'timeout' is a key of a batch DUT, not of kind"):
        load(in_process)
    case = load_case(CASE)
    assert case.dut.kind == "batch" and case.dut.batch.timeout_s == 60.0 and case.dut.batch.imu == "measured"
