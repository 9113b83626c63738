"""Hostile configuration values through the command line: each is refused before anything
runs, exit 2, with one message naming the file, the key, the value and the bound.

Before the validation layer these ran to a wrong PASS (a ``nan`` limit), a traceback
(a directory as a case), or until killed (``monte_carlo = 1000000000``, ``/dev/zero`` as a
script, ``repeat = 100000000``, garbage every nanosecond). Only the public command line is
used here, so the tests read the same on any version of the bench.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli.app import run
from tests.config.conftest import DRIVE, base_case

LIMIT = 'at_most = "6 m"'


def _refused(capsys, argv: list[str], *needles: str, out: Path | None = None) -> str:
    code = run(argv)
    err = capsys.readouterr().err
    assert code == 2, f"exit {code}, expected 2 (malformed input); stderr: {err}"
    assert "Traceback" not in err
    assert err.count("\n") <= 2, f"one message expected, found: {err}"
    for n in needles:
        assert n in err, f"{n!r} not in the message: {err}"
    if out is not None:
        assert not list(out.rglob("*.mcap")), "nothing may run: a recording was written"
    return err


def _run_case(capsys, case: Path, *needles: str) -> str:
    out = case.parent / "out"
    return _refused(capsys, ["run", str(case), "-o", str(out), "-q", "--no-plots"], str(case), *needles, out=out)


# -- limits that judged everything a PASS ---------------------------------------------------
@pytest.mark.parametrize(
    "limit,key",
    [
        ("at_most = nan", "criterion[0].at_most"),
        ("within = nan", "criterion[0].within"),
        ("at_most = inf", "criterion[0].at_most"),
        ("at_least = -inf", "criterion[0].at_least"),
        ('at_most = "1e400 m"', "criterion[0].at_most"),
        ("in_range = [nan, 6]", "criterion[0].in_range[0]"),
    ],
)
def test_a_limit_that_is_not_a_finite_number_is_refused(capsys, write, limit, key):
    case = write("case.toml", base_case().replace(LIMIT, limit))
    err = _run_case(capsys, case, key)
    assert "finite" in err


def test_a_nan_band_is_refused(capsys, write):
    case = write("case.toml", base_case().replace('marginal = "0.5 m"', "marginal = nan"))
    _run_case(capsys, case, "criterion[0].marginal", "finite")


# -- counts, durations and periods that ran until killed ------------------------------------
@pytest.mark.parametrize("count", ["1000000000", "1e9"])
def test_a_monte_carlo_count_beyond_the_bound_is_refused(capsys, write, count):
    case = write("case.toml", base_case().replace("seeds = [1]", f"monte_carlo = {count}"))
    err = _run_case(capsys, case, "run.monte_carlo", "1000000000")
    assert ("<= 10000" in err) if count.isdigit() else ("an integer" in err)


def test_a_run_duration_of_1e300_s_is_refused(capsys, write):
    text = base_case().replace('script = "drive.toml"', 'script = "drive.toml"\nduration = "1e300 s"')
    case = write("case.toml", text)
    _run_case(capsys, case, "scenario.duration", "1e300 s", "<= 2592000 s")


@pytest.mark.parametrize(
    "old,new,key,needle",
    [
        ('duration = "60 s"', 'duration = "60 s"\nrepeat = 100000000', "segment[0].repeat", "<= 100000"),
        ('duration = "60 s"', 'duration = "1e300 s"', "segment[0].duration", "<= 2592000 s"),
        ('duration = "60 s"', 'duration = "1728000 s"\nrepeat = 2', "segment[0].duration", "<= 2592000 s"),
        ('duration = "60 s"', 'duration = "172800 s"', "segment[0].duration", "truth points <= 100000000"),
        ('height = "50 m"', 'height = "1e400 m"', "initial.height", "finite"),
    ],
)
def test_a_runaway_motion_script_is_refused_by_run_and_by_synth(capsys, write, old, new, key, needle):
    script = write("drive2.toml", DRIVE.replace(old, new, 1))
    case = write("case.toml", base_case().replace('script = "drive.toml"', 'script = "drive2.toml"'))
    if key != "initial.height":  # the script's start is read when the motion is built
        _run_case(capsys, case, "scenario.script", str(script), key, needle)
    out = script.parent / "synth.mcap"
    _refused(capsys, ["synth", str(script), "-o", str(out), "-q"], str(script), key, needle)
    assert not out.exists()


_GARBAGE = """
[[fault]]
layer = "wire"
target = "serial:imu"
kind = "{kind}"
start = "10 s"
end = "{end}"
params = {{ {params} }}
"""


@pytest.mark.parametrize(
    "kind,end,params,key,needle",
    [
        ("garbage", "20 s", 'every = "1 ns"', "fault[0].params.every", ">= 1 ms"),
        ("garbage", "3000 s", 'every = "1 ms"', "fault[0].params.every", "<= 1000000"),
        ("garbage", "20 s", "length = 100000000", "fault[0].params.length", "<= 65536 bytes"),
        ("duplicate", "20 s", "copies = 1000000", "fault[0].params.copies", "<= 100"),
        ("delay", "20 s", 'delay = "1e300 s"', "fault[0].params.delay", "<= 2592000 s"),
    ],
)
def test_a_wire_fault_repeating_without_bound_is_refused(capsys, write, kind, end, params, key, needle):
    fault = _GARBAGE.format(kind=kind, end=end, params=params)
    case = write("case.toml", base_case() + fault)
    _run_case(capsys, case, key, needle)
    faults = write("faults.toml", fault)
    out = faults.parent / "synth.mcap"
    _refused(capsys, ["synth", str(faults.parent / "drive.toml"), "--faults", str(faults), "-o", str(out), "-q"],
             str(faults), key, needle)
    assert not out.exists()


def test_a_fault_window_at_1e300_s_is_refused(capsys, write):
    fault = _GARBAGE.format(kind="garbage", end="1e300 s", params="")
    case = write("case.toml", base_case() + fault)
    _run_case(capsys, case, "fault[0].end", "<= 2592000 s")


# -- files that are not files ---------------------------------------------------------------
def test_a_directory_given_as_the_case_is_refused(capsys, folder):
    (folder / "cases.toml").mkdir()
    _refused(capsys, ["run", str(folder / "cases.toml"), "-o", str(folder / "out")], "is a directory",
             out=folder / "out")


@pytest.mark.parametrize("script,what", [("/dev/zero", "character device"), ("sub", "is a directory")])
def test_a_script_that_is_not_a_regular_file_is_refused_by_run_and_by_synth(capsys, write, folder, script, what):
    (folder / "sub").mkdir()
    case = write("case.toml", base_case().replace('script = "drive.toml"', f'script = "{script}"'))
    _run_case(capsys, case, "scenario.script", what)
    _refused(capsys, ["synth", script if script.startswith("/") else str(folder / script), "-o",
                      str(folder / "s.mcap"), "-q"], what)
    assert not (folder / "s.mcap").exists()


def test_a_directory_given_as_a_fault_file_is_refused(capsys, write, folder):
    (folder / "faults").mkdir()
    case = write("case.toml", 'fault_files = ["faults"]\n' + base_case())
    _run_case(capsys, case, "fault_files[0]", "is a directory")
