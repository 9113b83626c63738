"""A replay or re-score of an unfinished or damaged recording is ERROR, with the reason.

The replay's own recording is complete, so the state of its source travels with it
(``run_start.source_*``); only ``bench replay --accept-damaged-source`` lets it be judged,
and the results say so. A replay of such a replay inherits its source's problems.
"""

import json
import shutil
from pathlib import Path

import pytest

from bench.cli import main
from bench.record.mcap_io import RecordingReader
from tests.record.damage import chunk_flipped as _chunk_flipped
from tests.record.damage import footer_damaged as _footer_damaged
from tests.record.damage import killed as _killed

CASE = Path(__file__).parent / "data" / "short_dr.toml"


@pytest.fixture(scope="module")
def run_rec(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("src")
    assert main(["run", str(CASE), "-o", str(out), "-q", "--no-plots"]) == 0
    return out / "recordings" / "SHORT-DR" / "SHORT-DR-s3.mcap"


def _replay(src: Path, out: Path, *extra: str) -> int:
    return main(["replay", str(src), "--case", str(CASE), "-q", "-o", str(out), *extra])


def _score(rec: Path, tmp: Path) -> tuple[int, dict]:
    js = tmp / f"{rec.stem}.json"
    code = main(["score", str(rec), "--json", str(js)])
    return code, json.loads(js.read_text())["cases"][0]["runs"][0]


@pytest.mark.parametrize(
    ("damage", "why"),
    [
        (_killed, "was never finished (the run was killed)"),
        (_footer_damaged, "is damaged, 1 stretch(es) could not be read (footer at byte"),
        (_chunk_flipped, "CRC mismatch"),
    ],
)
def test_a_replay_of_a_killed_or_damaged_recording_is_error_with_the_reason(run_rec, tmp_path, capsys, damage, why):
    src = damage(run_rec, tmp_path / "src.mcap")
    out = tmp_path / "replay.mcap"
    assert _replay(src, out) == 3
    err = capsys.readouterr().err
    assert "the source cannot be trusted" in err and why in err
    start = RecordingReader(out).metadata()["run_start"]
    assert start["source_complete"] == "false" and start["accept_damaged_source"] == "false"
    assert why in start["source_problems"]
    assert RecordingReader(out).intact  # the replay's own file is fine: the verdict must not be
    code, run = _score(out, tmp_path)
    assert code == 3 and run["verdict"] == "ERROR"
    assert any("a replay of a source that cannot be trusted" in i and why in i for i in run["bench_issues"])


def test_the_damaged_recording_itself_scores_error_naming_the_chunk(run_rec, tmp_path):
    src = _chunk_flipped(run_rec, tmp_path / "flipped.mcap")
    code, run = _score(src, tmp_path)
    assert code == 3 and run["verdict"] == "ERROR"
    (issue,) = [i for i in run["bench_issues"] if "damaged" in i]
    assert "could not be read: chunk" in issue and "messages logged at bench time" in issue and "CRC" in issue


def test_accept_damaged_source_judges_it_and_says_so(run_rec, tmp_path, capsys):
    src = _killed(run_rec, tmp_path / "src.mcap")
    out = tmp_path / "accepted.mcap"
    assert _replay(src, out, "--accept-damaged-source") == 0
    assert "judged anyway, as asked" in capsys.readouterr().err
    r = RecordingReader(out)
    assert r.metadata()["run_start"]["accept_damaged_source"] == "true"
    assert r.read_columnar("/truth")["t_ns"][-1] <= 60.1e9  # it replays what the source holds, not the plan
    code, run = _score(out, tmp_path)
    # judged, not ERROR: the dead reckoning is as good as before; the source's lost last
    # stretch leaves the DUT without input, which the output-integrity defaults see
    assert run["verdict"] != "ERROR" and code in (0, 1) and not run["bench_issues"]
    assert run["criteria"]["c1"]["verdict"] == "PASS"
    assert run["notes"] and "accepted with --accept-damaged-source" in run["notes"][0]
    assert "was never finished" in run["notes"][0]
    # a replay of that replay inherits the problem: ERROR again unless accepted again
    again = tmp_path / "again.mcap"
    assert _replay(out, again) == 3
    code, run = _score(again, tmp_path)
    assert code == 3 and "was never finished" in " ".join(run["bench_issues"])


def test_a_replay_of_an_intact_recording_is_judged_as_before(run_rec, tmp_path):
    out = tmp_path / "clean.mcap"
    assert _replay(run_rec, out) == 0
    start = RecordingReader(out).metadata()["run_start"]
    assert start["source_complete"] == "true" and json.loads(start["source_problems"]) == []
    code, run = _score(out, tmp_path)
    assert code == 0 and run["verdict"] == "PASS" and run["notes"] == []


def test_a_replay_onto_its_own_source_is_refused(run_rec, tmp_path, capsys):
    src = tmp_path / "same.mcap"
    shutil.copy(run_rec, src)
    before = src.read_bytes()
    assert _replay(src, src, "--force") == 2
    assert "a replay cannot overwrite what it reads" in capsys.readouterr().err
    assert src.read_bytes() == before
