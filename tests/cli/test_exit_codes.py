"""Exit codes of every command: 0 pass, 1 DUT FAIL, 2 usage or malformed input, 3 ERROR.

An exception that escapes a subcommand is never a traceback alone and never exit 1 (the
FAIL code): ERROR 3 with one line naming it and the traceback in a log file, or 2 when it
is an OSError about an input the user gave (bench.cli.app, bench.crashlog).
"""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.cli import main
from bench.crashlog import LOG_NAME

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"


@pytest.fixture(autouse=True)
def state_home(tmp_path, monkeypatch) -> Path:
    """Logs without an output folder go to the user's state folder: a temporary one here."""
    d = tmp_path / "state"
    monkeypatch.setenv("XDG_STATE_HOME", str(d))
    monkeypatch.delenv("BENCH_TRACEBACK", raising=False)
    return d / "bench"


def _crash_info(monkeypatch, exc: BaseException) -> None:
    """Make ``bench info`` raise ``exc`` from inside its handler."""
    import bench.cli.info as info

    def boom(path):
        raise exc

    monkeypatch.setattr(info, "describe", boom)


@pytest.mark.parametrize(
    "exc",
    [
        ZeroDivisionError("division by zero"),
        ValueError("could not convert"),
        MemoryError(),
        RecursionError("maximum recursion depth exceeded"),
        OSError(errno.ENOSPC, "No space left on device"),
        KeyError("lever_arm"),
    ],
    ids=lambda e: type(e).__name__,
)
def test_an_internal_exception_is_error_3_with_one_line_and_the_traceback_in_a_log(
    monkeypatch, capsys, state_home, exc
):
    _crash_info(monkeypatch, exc)
    assert main(["info", str(SHORT)]) == 3
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    kind = "error" if isinstance(exc, OSError) else "internal error"
    log = state_home / LOG_NAME
    assert lines[0].startswith(f"bench: {kind}: {type(exc).__name__}") and lines[0].endswith(f"(traceback in {log})")
    text = log.read_text()
    assert "Traceback (most recent call last)" in text and "in boom" in text and type(exc).__name__ in text


def test_the_one_line_shows_control_characters_and_the_traceback_option_prints_it(monkeypatch, capsys):
    _crash_info(monkeypatch, RuntimeError("bad \x1b[2J\x1b]0;pwned\x07 text\nsecond line"))
    assert main(["info", str(SHORT)]) == 3
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\x07" not in err and err.count("\n") == 1
    assert "bad \\x1b[2J\\x1b]0;pwned\\x07 text\\nsecond line" in err
    assert main(["--traceback", "info", str(SHORT)]) == 3
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and err.rstrip().splitlines()[-1].startswith("bench: internal")
    monkeypatch.setenv("BENCH_TRACEBACK", "1")
    assert main(["info", str(SHORT)]) == 3
    assert "Traceback (most recent call last)" in capsys.readouterr().err


def test_an_os_error_about_a_given_input_is_usage_2_about_anything_else_error_3(monkeypatch, capsys, tmp_path):
    given = tmp_path / "cases"
    given.mkdir()
    _crash_info(monkeypatch, IsADirectoryError(errno.EISDIR, "Is a directory", str(given)))
    assert main(["info", str(given)]) == 2
    assert capsys.readouterr().err == f"bench: usage error: {given}: Is a directory\n"
    inside = given / "a.toml"
    _crash_info(monkeypatch, PermissionError(errno.EACCES, "Permission denied", str(inside)))
    assert main(["info", str(given)]) == 2  # a file inside a folder the user gave
    assert "usage error" in capsys.readouterr().err
    _crash_info(monkeypatch, PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "elsewhere")))
    assert main(["info", str(given)]) == 3  # not what the user gave: the bench's problem
    assert "bench: error: PermissionError" in capsys.readouterr().err


def test_output_paths_are_not_inputs(monkeypatch, capsys, tmp_path):
    import bench.scenario.loader as loader

    out = tmp_path / "run.mcap"

    def full(*args, **kw):
        raise OSError(errno.ENOSPC, "No space left on device", str(out))

    monkeypatch.setattr(loader, "load_scenario", full)
    assert main(["synth", str(SHORT), "-o", str(out), "-q"]) == 3
    assert "bench: error: OSError: [Errno 28] No space left on device" in capsys.readouterr().err


def test_a_crash_of_bench_accept_outside_a_case_logs_into_its_output_folder(monkeypatch, capsys, tmp_path):
    import bench.acceptance.suite as suite

    def broken(paths):
        raise ZeroDivisionError("collecting")

    monkeypatch.setattr(suite, "collect_cases", broken)
    (tmp_path / "drive.toml").write_text(SHORT.read_text())
    case = tmp_path / "c.toml"
    case.write_text(_SYNTHETIC_CASE)
    out = tmp_path / "out"
    assert main(["accept", str(case), "-o", str(out), "-q", "--no-plots"]) == 3
    err = capsys.readouterr().err
    assert err.strip().endswith(f"(traceback in {out / LOG_NAME})") and "in broken" in (out / LOG_NAME).read_text()


_SYNTHETIC_CASE = """
[case]
id = "EXIT"
title = "exit codes"
requirements = ["R"]

[scenario]
script = "drive.toml"

[dut]
kind = "synthetic"

[run]
seeds = [1]

[[criterion]]
requirement = "R"
metric = "accuracy.horizontal.rms"
at_most = "50 m"
"""


@pytest.mark.parametrize("command", [["run"], ["synth", "-o", "x.mcap", "-q"], ["score"], ["info"], ["imu", "allan"]])
def test_a_directory_given_as_the_input_is_a_usage_error(tmp_path, capsys, command):
    args = [*command[:2], str(tmp_path), *command[2:]] if command[0] == "imu" else [command[0], str(tmp_path),
                                                                                   *command[1:]]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and str(tmp_path) in err and len(err.splitlines()) == 1


class _UnprintableError(Exception):
    def __str__(self):
        raise ValueError("no")


def test_an_exception_that_cannot_even_be_printed_is_still_one_line(monkeypatch, capsys, state_home):
    _crash_info(monkeypatch, _UnprintableError())
    assert main(["info", str(SHORT)]) == 3
    err = capsys.readouterr().err
    log = state_home / LOG_NAME
    assert err == f"bench: internal error: _UnprintableError: (message unprintable) (traceback in {log})\n"


def test_the_console_script_exits_3_not_1_on_an_internal_crash(tmp_path):
    code = ("import sys, bench.cli.info as i\n"
            "def boom(p): raise ZeroDivisionError('division by zero')\n"
            "i.describe = boom\n"
            "from bench.cli import main\n"
            f"sys.exit(main(['info', {str(SHORT)!r}]))\n")
    env = {**os.environ, "XDG_STATE_HOME": str(tmp_path)}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert p.returncode == 3, p.stderr
    assert p.stderr.startswith("bench: internal error: ZeroDivisionError: division by zero (traceback in ")
    assert "Traceback" not in p.stderr
