"""`bench run -o` and `bench accept -o`: earlier recordings are evidence, an output that
cannot be a folder is a usage error (it used to be a traceback, exit 1)."""

import json
from pathlib import Path

import pytest

from bench.cli import main
from bench.record.mcap_io import RecordingReader, RecordingWriter

CASE = Path(__file__).parent.parent / "run" / "data" / "short_dr.toml"
REC = Path("recordings") / "SHORT-DR" / "SHORT-DR-s3.mcap"


@pytest.mark.parametrize("command", ["run", "accept"])
def test_earlier_recordings_are_not_overwritten_without_force(tmp_path, capsys, command):
    out = tmp_path / "out"
    assert main([command, str(CASE), "-o", str(out), "-q", "--no-plots"]) == 0
    before = (out / REC).read_bytes()
    (out / "results.json").unlink()
    capsys.readouterr()
    assert main([command, str(CASE), "-o", str(out), "-q", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert f"{out / REC}: exists: recordings are not overwritten without --force" in err
    assert (out / REC).read_bytes() == before and not (out / "results.json").exists()  # nothing ran
    assert main([command, str(CASE), "-o", str(out), "-q", "--no-plots", "--force"]) == 0
    assert RecordingReader(out / REC).intact
    assert json.loads((out / "results.json").read_text())["verdict"] == "PASS"


def test_a_recording_another_bench_is_writing_is_refused_even_with_force(tmp_path, capsys):
    out = tmp_path / "out"
    with RecordingWriter(out / REC):
        assert main(["run", str(CASE), "-o", str(out), "-q", "--no-plots", "--force"]) == 2
    assert "is being written by another bench (pid" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["run", "accept"])
@pytest.mark.parametrize(("where", "found"), [("file", "is a file, expected a folder"),
                                              ("file/sub", "on its path is a file, not a folder")])
def test_a_file_where_a_folder_is_expected_is_a_usage_error(tmp_path, capsys, command, where, found):
    (tmp_path / "file").write_text("not a folder\n")
    assert main([command, str(CASE), "-o", str(tmp_path / where), "-q", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert found in err and "Traceback" not in err
    assert (tmp_path / "file").read_text() == "not a folder\n"
