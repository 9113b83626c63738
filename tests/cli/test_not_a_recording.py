"""`bench info`, `score` and `replay` refuse what is not a bench recording: exit 2, naming
what they found (a text file used to be reported as an "unfinished" recording, exit 0)."""

import os
from pathlib import Path

import pytest
from mcap.writer import Writer

from bench.cli import main

CASE = Path(__file__).parent.parent / "run" / "data" / "short_dr.toml"


def _other_mcap(p: Path) -> None:
    with p.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="ros1", library="rosbag-tool")
        w.finish()


MAKERS = {
    "text": (lambda p: p.write_text("hello world\nnot a recording\n"), "starts with 'hello wo', not the MCAP magic"),
    "empty": (lambda p: p.write_bytes(b""), "is empty, not an MCAP recording"),
    "folder": (lambda p: p.mkdir(), "is a directory, not an MCAP recording"),
    "fifo": (lambda p: os.mkfifo(p), "is a FIFO, not an MCAP recording"),
    "missing": (lambda p: None, "no such file"),
    "other MCAP": (_other_mcap, "profile 'ros1' written by 'rosbag-tool', not a bench recording"),
}


@pytest.mark.parametrize("kind", sorted(MAKERS))
@pytest.mark.parametrize("command", ["info", "score", "replay"])
def test_a_file_that_is_not_a_recording_exits_2_naming_what_it_is(tmp_path, capsys, kind, command):
    make, found = MAKERS[kind]
    p = tmp_path / "input.mcap"
    make(p)
    argv = {"info": ["info", str(p)], "score": ["score", str(p)],
            "replay": ["replay", str(p), "--case", str(CASE), "-q", "-o", str(tmp_path / "out.mcap")]}[command]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert found in err and str(p) in err and "Traceback" not in err
    assert not (tmp_path / "out.mcap").exists()


@pytest.mark.parametrize("command", ["info", "score"])
def test_dev_zero_is_refused_at_once(capsys, command):
    assert main([command, "/dev/zero"]) == 2
    assert "/dev/zero: is a device, not an MCAP recording" in capsys.readouterr().err
