"""The batch DUT's inputs are the bench's own: synthesized inputs that came out unfinished or
damaged are never given to the command, and the run is the bench's ERROR naming the damage
(never the DUT's FAIL, never a PASS on what could be read)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from bench.cli import main
from bench.exchange.batch import BatchRunner
from bench.record.mcap_io import RecordingReader
from tests.record.damage import chunk_flipped, killed

HERE = Path(__file__).parent
REC = Path("recordings") / "BATCH" / "BATCH-s1.mcap"


@pytest.mark.parametrize(("damage", "named"), [(killed, "was never finished"), (chunk_flipped, "is damaged")],
                         ids=["killed", "flipped"])
def test_damaged_synthesized_inputs_make_the_run_error_and_the_command_never_runs(tmp_path, monkeypatch, capsys,
                                                                                 damage, named):
    synthesize = BatchRunner._synthesize

    def damaged(case, run, spec, path, progress):
        synthesize(case, run, spec, path, progress)
        whole = path.with_name("whole.mcap")
        shutil.move(path, whole)
        damage(whole, path)

    monkeypatch.setattr(BatchRunner, "_synthesize", staticmethod(damaged))
    case = tmp_path / "batch_case.toml"
    shutil.copy(HERE / "batch_case.toml", case)
    shutil.copy(HERE / "batch_dut.py", tmp_path / "batch_dut.py")
    out = tmp_path / "out"
    assert main(["run", str(case), "-o", str(out), "-q", "--no-plots"]) == 3
    capsys.readouterr()
    run = json.loads((out / "results.json").read_text())["cases"][0]["runs"][0]
    assert run["verdict"] == "ERROR" and not run["dut_issues"], run
    assert any("inputs.mcap " + named in i and "the bench's own failure" in i for i in run["bench_issues"]), run
    with RecordingReader(out / REC) as r:
        md = r.metadata()
        assert r.intact and md["run_end"]["status"] == "error" and named in md["run_end"]["reason"]
        assert md["run_start"]["source_made_by"] == "batch" and md["run_start"]["source_complete"] == "false"
        assert "/dut/nav_solution" not in r.topics() or r.topics()["/dut/nav_solution"].messages == 0
    work = out / REC.parent / "BATCH-s1.batch"
    assert not (work / "stdout.txt").exists() and not (work / "input").exists()  # nothing exported, nothing ran
    # judged again, still ERROR
    assert main(["score", str(out / REC)]) == 3
