"""The fault matrix (issue 10), inputs: the hostile configurations, DUT outputs and
recordings found by trying the bench from outside, each given to the ``bench`` command
as a user would, and the outcome of each asserted.

Every row runs ``bench`` as its own process and checks, besides what the row is about:

* the exit code is one of the four documented ones (0 pass, 1 DUT FAIL, 2 usage or
  malformed input, 3 ERROR) and the one the row expects;
* no traceback reaches the terminal, and the message names what was wrong;
* where a recording is written, it is readable (``bench info`` exits 0 on it);
* nothing the command started is left running (every process that inherited the row's
  marker in its environment has ended).

The bigger inputs of the issue (a 1,000,000-input fuzz campaign, a 60 s real-time run)
live in benchmarks/; the mechanisms behind each row have their own tests next to their
modules. This package is the one place that says, row by row, what a user sees.
"""

from __future__ import annotations

import json
import os
import subprocess
import time

import pytest

from tests.fault_matrix.matrix import BENCH, SHORT, SHORT_DR, bench, case, readable
from tests.record.damage import chunk_flipped, footer_damaged, killed


# ------------------------------------------------------------ limits and configuration
@pytest.mark.parametrize(
    ("limit", "named"),
    [
        ("at_most = nan", "at_most"),
        ("at_most = inf", "at_most"),
        ('within = nan', "within"),
        ('in_range = ["0 m", nan]', "in_range"),
        ('at_most = "1e400 m"', "at_most"),
        ('at_mots = "1 m"', "at_mots"),
        ('at_most = "1 m"\nmarginal = nan', "marginal"),
    ],
    ids=["at_most-nan", "at_most-inf", "within-nan", "in_range-nan", "overflow", "misspelt", "marginal-nan"],
)
def test_a_limit_that_is_not_a_finite_number_is_refused_never_passes(tmp_path, limit, named):
    r = bench("run", str(case(tmp_path, limit=limit)), "-o", str(tmp_path / "out"), "-q", cwd=tmp_path, expect=2)
    assert "case.toml" in r.err and named in r.err
    assert not (tmp_path / "out" / "recordings").exists()  # refused before anything ran


@pytest.mark.parametrize(
    ("edit", "named"),
    [
        ({"run": "monte_carlo = 1000000000"}, "monte_carlo"),
        ({"run": "monte_carlo = 1e9"}, "monte_carlo"),
        ({"duration": "1e300 s"}, "duration"),
        ({"extra": "repeat = 100000000"}, "repeat"),
        ({"faults": '[[fault]]\nlayer = "wire"\ntarget = "serial:imu"\nkind = "garbage"\nstart = "1 s"\n'
                    'end = "9 s"\nparams = { length = 4, every = "1 ns" }\n'}, "every"),
        ({"script": "/dev/zero"}, "/dev/zero"),
        ({"script": "."}, "directory"),
    ],
    ids=["monte_carlo-int", "monte_carlo-float", "duration-1e300", "repeat-1e8", "fault-every-1ns", "dev-zero",
         "script-is-dir"],
)
def test_an_input_that_would_run_until_killed_is_refused_up_front(tmp_path, edit, named):
    r = bench("run", str(case(tmp_path, **edit)), "-o", str(tmp_path / "out"), "-q", cwd=tmp_path, timeout=60,
              expect=2)
    assert named in r.err, r.err


def test_a_directory_given_as_a_case_or_a_script_is_a_usage_error(tmp_path):
    r = bench("run", str(tmp_path), cwd=tmp_path, expect=2)
    assert str(tmp_path) in r.err and "directory" in r.err
    r = bench("synth", str(tmp_path), "-o", str(tmp_path / "x.mcap"), cwd=tmp_path, expect=2)
    assert "directory" in r.err
    r = bench("synth", "/dev/zero", "-o", str(tmp_path / "x.mcap"), cwd=tmp_path, timeout=60, expect=2)
    assert "/dev/zero" in r.err and "character device" in r.err


# ------------------------------------------------------------------ the DUT's output
@pytest.mark.parametrize(
    ("kind", "named"),
    [
        ("bad_crc", "INTEGRITY-bad-frames"),
        ("out_of_range", "INTEGRITY-range"),
        ("counter_stuck", "INTEGRITY-counter"),
        ("time_frozen", "INTEGRITY-repeated"),
        ("time_backwards", "INTEGRITY-order"),
        ("time_jump", "INTEGRITY-jump"),
    ],
)
def test_output_bad_in_the_last_40_percent_fails_on_the_named_integrity_criterion(tmp_path, kind, named):
    amount = 'amount = "1e6 s"\n' if kind == "time_jump" else ""
    bad = f'[[dut.synthetic.output]]\nkind = "{kind}"\nstart = "6 s"\n{amount}'
    out = tmp_path / "out"
    r = bench("run", str(case(tmp_path, dut_extra=bad)), "-o", str(out), "-q", "--no-plots", cwd=tmp_path, expect=1)
    results = json.loads((out / "results.json").read_text())["cases"][0]
    failed = {c["id"] for c in results["criteria"] if c["verdict"] == "FAIL"}
    assert named in failed and results["verdict"] == "FAIL", failed
    assert named in r.out
    readable(out / "recordings" / "M10" / "M10-s1.mcap", tmp_path)
    # the same case without the defect passes: the row is about the defect
    clean = tmp_path / "clean"
    bench("run", str(case(clean)), "-o", str(clean / "out"), "-q", "--no-plots", cwd=clean, expect=0)


# ----------------------------------------------------------------------- recordings
@pytest.mark.parametrize("damage", [killed, footer_damaged, chunk_flipped], ids=["killed", "footer", "flipped"])
def test_a_damaged_or_unfinished_recording_is_read_past_the_damage_and_never_judged(recording, tmp_path, damage):
    src = damage(recording, tmp_path / "src.mcap")
    info = bench("info", str(src), cwd=tmp_path, expect=0)  # a reading tool: what it can read, and the damage
    assert ("unfinished" in info.out) if damage is killed else ("DAMAGED" in info.out)
    assert "/truth" in info.out  # the rest is shown
    score = bench("score", str(src), "--json", str(tmp_path / "s.json"), cwd=tmp_path, expect=3)
    assert json.loads((tmp_path / "s.json").read_text())["cases"][0]["verdict"] == "ERROR", score.text
    out = tmp_path / "replay.mcap"
    rep = bench("replay", str(src), "--case", str(SHORT_DR), "-o", str(out), "-q", cwd=tmp_path, expect=3)
    assert "--accept-damaged-source" in rep.text
    start = readable(out, tmp_path)["metadata"]["run_start"]
    assert start["source_complete"] == "false" or json.loads(start["source_damage"]), start
    # the replay's own recording is complete; judged again, it is still ERROR (no laundering)
    bench("score", str(out), cwd=tmp_path, expect=3)


@pytest.mark.parametrize(
    "content", [b"hello world, not a recording\n", b"", b"\x89MCAP0\r\n" + b"\0" * 64], ids=["text", "empty", "magic"]
)
def test_a_file_that_is_not_a_recording_is_refused_by_every_reader(tmp_path, content):
    f = tmp_path / "not.mcap"
    f.write_bytes(content)
    for cmd in (["info", str(f)], ["score", str(f)], ["replay", str(f), "--case", str(SHORT_DR), "-o",
                                                      str(tmp_path / "o.mcap")]):
        r = bench(*cmd, cwd=tmp_path, expect=2)
        assert str(f) in r.err


def test_outputs_are_never_overwritten_silently_nor_written_by_two_benches(tmp_path):
    out = tmp_path / "run.mcap"
    bench("synth", str(SHORT), "-o", str(out), "-q", cwd=tmp_path, expect=0)
    before = out.read_bytes()
    r = bench("synth", str(SHORT), "-o", str(out), "-q", cwd=tmp_path, expect=2)
    assert "--force" in r.err and out.read_bytes() == before
    bench("synth", str(SHORT), "-o", str(out), "-q", "--force", cwd=tmp_path, expect=0)
    # a second bench on the output another bench is writing: refused, naming the writer
    big = tmp_path / "big.mcap"
    first = subprocess.Popen([*BENCH, "synth", "S000", "-o", str(big), "-q"], cwd=tmp_path,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not big.exists() and first.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        if first.poll() is not None:
            pytest.fail(f"the first bench ended before the second started: {first.stderr.read()}")
        r = bench("synth", str(SHORT), "-o", str(big), "-q", "--force", cwd=tmp_path, expect=2)
        assert f"pid {first.pid}" in r.err
    finally:
        assert first.wait(timeout=120) == 0
    readable(big, tmp_path)  # the first writer's recording is whole


def test_outputs_that_cannot_be_written_are_usage_errors_before_the_run(tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    r = bench("run", str(SHORT_DR), "-o", str(a_file), "-q", cwd=tmp_path, expect=2)
    assert str(a_file) in r.err
    ro = tmp_path / "ro"
    ro.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(ro)], check=False, capture_output=True)
    try:
        if os.access(ro, os.W_OK):  # not a read-only mount here (no permission): a mode bit will do if not root
            ro.chmod(0o555)
            if os.access(ro, os.W_OK):
                pytest.skip("cannot make a read-only folder here (root without mount permission)")
        r = bench("synth", str(SHORT), "-o", str(ro / "x.mcap"), "-q", cwd=tmp_path, expect=2)
        assert str(ro) in r.err
    finally:
        subprocess.run(["umount", str(ro)], check=False, capture_output=True)


def test_a_full_disk_ends_the_run_error_with_the_recording_finished_as_far_as_it_got(tmp_path):
    out = tmp_path / "out"
    r = bench("run", str(SHORT_DR), "-o", str(out), "-q", "--no-plots", cwd=tmp_path, fsize=1 << 20, expect=3)
    assert "could not be written" in r.text
    info = readable(out / "recordings" / "SHORT-DR" / "SHORT-DR-s3.mcap", tmp_path)
    assert info["topics"]  # readable as far as it got
