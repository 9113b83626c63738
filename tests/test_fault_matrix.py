"""The fault matrix (issue 10): the hostile inputs found by trying the bench from outside,
each given to the ``bench`` command as a user would, and the outcome of each asserted.

Every row runs ``bench`` as its own process and checks, besides what the row is about:

* the exit code is one of the four documented ones (0 pass, 1 DUT FAIL, 2 usage or
  malformed input, 3 ERROR) and the one the row expects;
* no traceback reaches the terminal, and the message names what was wrong;
* where a recording is written, it is readable (``bench info`` exits 0 on it);
* nothing the command started is left running (every process that inherited the row's
  marker in its environment has ended).

The bigger inputs of the issue (a 1,000,000-input fuzz campaign, a 60 s real-time run)
live in benchmarks/; the mechanisms behind each row have their own tests next to their
modules. This file is the one place that says, row by row, what a user sees.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import textwrap
import time
import uuid
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.record.damage import chunk_flipped, footer_damaged, killed

HERE = Path(__file__).parent
BENCH = [sys.executable, "-c", "import sys; from bench.cli import main; sys.exit(main())"]
SHORT = HERE / "data" / "short_drive.toml"
SHORT_DR = HERE / "run" / "data" / "short_dr.toml"
MARK = "BENCH_FAULT_MATRIX_MARK"
EXIT_CODES = (0, 1, 2, 3)


@dataclass
class Outcome:
    code: int
    out: str
    err: str

    @property
    def text(self) -> str:
        return self.out + self.err


def _marked(mark: str) -> list[int]:
    """Processes (other than this one) whose environment carries ``mark``."""
    needle = f"{MARK}={mark}".encode()
    found = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit() or int(d.name) == os.getpid():
            continue
        try:
            env = (d / "environ").read_bytes()
            state = (d / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if needle in env.split(b"\0") and state != "Z":
            found.append(int(d.name))
    return found


def bench(*args: str, cwd: Path, timeout: float = 240, ns: str | None = None, fsize: int | None = None,
          expect: int | None = None) -> Outcome:
    """Run ``bench ARGS`` as a user would and check what every row checks (module docstring)."""
    mark = uuid.uuid4().hex
    env = {**os.environ, MARK: mark, "COLUMNS": "200"}
    env.pop("BENCH_TRACEBACK", None)
    cmd = [*(["ip", "netns", "exec", ns] if ns else []), *BENCH, *args]

    def limits() -> None:
        if fsize is not None:  # every write past the limit fails with EFBIG, as on a full disk
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout,
                       preexec_fn=limits if fsize is not None else None)
    outcome = Outcome(p.returncode, p.stdout, p.stderr)
    assert p.returncode in EXIT_CODES, outcome.text
    assert "Traceback" not in outcome.text, outcome.text
    if expect is not None:
        assert p.returncode == expect, outcome.text
    deadline = time.monotonic() + 60.0  # processes being reaped by the kernel (a hang guard)
    while (left := _marked(mark)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not left, f"left running: {left}"
    return outcome


def readable(recording: Path, cwd: Path) -> dict:
    """``bench info --json`` of a recording that must be readable."""
    info = bench("info", str(recording), "--json", cwd=cwd, expect=0)
    return json.loads(info.out)


# ----------------------------------------------------------------------------- inputs
DRIVE = """
[scenario]
id = "T-10"
title = "ten seconds"

[initial]
latitude = 30.0
longitude = 110.0
height = "50 m"
speed = "10 m/s"
heading = "0 deg"

[[segment]]
kind = "uniform"
duration = "{duration}"
{extra}
"""

CASE = """
[case]
id = "M10"
title = "matrix case"
requirements = ["R"]

[scenario]
script = "{script}"

[dut]
kind = "synthetic"

[dut.synthetic]
rate = "100 Hz"
{dut_extra}
[run]
{run}

{faults}
[[criterion]]
id = "H"
requirement = "R"
metric = "accuracy.horizontal.max"
{limit}
"""


def case(folder: Path, name: str = "case.toml", *, script: str = "drive.toml", duration: str = "10 s",
         limit: str = 'at_most = "1 m"', run: str = "seeds = [1]", faults: str = "", dut_extra: str = "",
         extra: str = "") -> Path:
    """A small synthetic-DUT case (10 s drive) with one part replaced."""
    folder.mkdir(parents=True, exist_ok=True)
    if script == "drive.toml":
        (folder / "drive.toml").write_text(DRIVE.format(duration=duration, extra=extra))
    path = folder / name
    path.write_text(CASE.format(script=script, limit=limit, run=run, faults=faults, dut_extra=dut_extra))
    return path


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    """A finished recording of the bench's own dead-reckoning case (90 s, in process)."""
    out = tmp_path_factory.mktemp("src")
    bench("run", str(SHORT_DR), "-o", str(out), "-q", "--no-plots", cwd=out, expect=0)
    return out / "recordings" / "SHORT-DR" / "SHORT-DR-s3.mcap"


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


# ------------------------------------------------------------- crashes and exit codes
CRASHING = """
import sys
import bench.acceptance.runner as runner
from bench.acceptance.synthetic import SyntheticRunner
from bench.cli import main


class Crashing:
    def run(self, case, seed, out_dir, *, progress=None):
        if case.id == "M2":
            return 1 / 0  # a bug inside the bench, in one case's run
        return SyntheticRunner().run(case, seed, out_dir, progress=progress)


runner._FACTORIES["synthetic"] = Crashing
sys.exit(main(sys.argv[1:]))
"""


def test_a_crashing_case_among_five_is_that_cases_error_and_every_report_is_written(tmp_path):
    cases = tmp_path / "cases"
    for k in range(5):
        p = case(cases, f"c{k}.toml")
        p.write_text(p.read_text().replace('id = "M10"', f'id = "M{k}"'))
    script = tmp_path / "crashing_bench.py"
    script.write_text(CRASHING)
    out = tmp_path / "reports"
    mark = uuid.uuid4().hex
    p = subprocess.run([sys.executable, str(script), "accept", str(cases), "-o", str(out), "-q", "--no-plots"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=240, env={**os.environ, MARK: mark})
    assert p.returncode == 3, p.stdout + p.stderr
    assert "Traceback" not in p.stdout + p.stderr and "ZeroDivisionError" in p.stdout + p.stderr
    results = json.loads((out / "results.json").read_text())
    verdicts = {c["id"]: c["verdict"] for c in results["cases"]}
    assert verdicts == {"M0": "PASS", "M1": "PASS", "M2": "ERROR", "M3": "PASS", "M4": "PASS"}
    ET.parse(out / "junit.xml")
    assert (out / "summary.txt").is_file() and (out / "summary.md").is_file()
    assert "ZeroDivisionError" in (out / "bench-error.log").read_text()  # the traceback, for a developer
    assert not _marked(mark)


def test_a_bad_date_in_a_field_log_is_counted_and_named_not_a_traceback(tmp_path):
    def nmea(body: str) -> str:
        cs = 0
        for ch in body:
            cs ^= ord(ch)
        return f"${body}*{cs:02X}\r\n"

    log = tmp_path / "bad.nmea"
    log.write_text(nmea("GBGGA,080000.00,3414.7630,N,10854.5790,E,1,12,0.8,380.0,M,0.0,M,,")
                   + nmea("GBZDA,080000.00,31,02,2026,00,00"))  # 31 February
    r = bench("replay", "--gnss-log", str(log), "--estimator", "dead_reckoning", "-q", "-o",
              str(tmp_path / "o.mcap"), cwd=tmp_path, expect=2)
    assert "do not decode" in r.err and str(log) in r.err


@pytest.mark.parametrize(
    "content", [b"not an imu log at all\n", b"\0\1\2\3" * 100, b""], ids=["text", "binary", "empty"]
)
def test_a_file_that_is_not_an_imu_log_is_refused_by_allan(tmp_path, content):
    f = tmp_path / "log.imu"
    f.write_bytes(content)
    r = bench("imu", "allan", str(f), cwd=tmp_path, expect=2)
    assert str(f) in r.err


PLANT = """
[scenario]
id = "P"
title = "a plant scenario on a tampered FMU"

[initial]
latitude = 39.84991
longitude = 116.17715
height = "60 m"
heading = "0 deg"

[plant]
vehicle = "tracked_seed002"
fmu = "TrackedVehicle.fmu"
duration = "5 s"

[[command]]
at = "0 s"
left_lever = "former"
right_lever = "former"
throttle = 0.3
"""


def test_a_sha256sums_beside_a_tampered_fmu_is_not_trusted_and_its_code_not_loaded(tmp_path):
    import hashlib

    from bench.paths import fmu_dir

    built = fmu_dir() / "build" / "TrackedVehicle.fmu"
    assert built.is_file(), "the FMUs are built by the install step (make install)"
    data = bytearray(built.read_bytes())
    data[len(data) // 2] ^= 0x01
    fmu = tmp_path / "TrackedVehicle.fmu"
    fmu.write_bytes(bytes(data))
    (tmp_path / "SHA256SUMS").write_text(f"{hashlib.sha256(bytes(data)).hexdigest()}  {fmu.name}\n")
    (tmp_path / "plant.toml").write_text(PLANT)
    r = bench("synth", str(tmp_path / "plant.toml"), "-o", str(tmp_path / "x.mcap"), "-q", cwd=tmp_path, expect=2)
    assert str(fmu) in r.err and "not trusted" in r.err and not (tmp_path / "x.mcap").exists()
    r = bench("fmu", "check", str(fmu), cwd=tmp_path, expect=3)  # a check tool: 3, a check failed (docs/fmu.md)
    assert "not trusted" in r.out


# --------------------------------------------------------- external DUTs (a namespace)
TALKER = HERE / "run" / "duts" / "talker.py"


def _external_case(tmp_path: Path, port: int, config: str) -> Path:
    command = (f"{sys.executable} {TALKER} --estimator talker --can-interface {{can_interface}} "
               "--can-channel {can_channel} --imu {imu_port} --gnss {gnss_port} "
               "--config {config}")
    path = tmp_path / "external.toml"
    path.write_text(textwrap.dedent(f"""
        [case]
        id = "EXT"
        title = "an external DUT"
        requirements = ["R"]

        [scenario]
        script = "{SHORT}"

        [sensors]
        imu = {{ grade = "navigation", rate = "200 Hz" }}

        [dut]
        kind = "external"
        command = "{command}"
        config = {config}
        startup_timeout = "60 s"
        shutdown_timeout = "60 s"

        [dut.links]
        can = {{ interface = "udp_multicast", channel = "239.74.166.{port % 250}" }}

        [clock]
        mode = "lockstep"
        timeout = "60 s"

        [run]
        seeds = [1]

        [[criterion]]
        requirement = "R"
        metric = "accuracy.horizontal.max"
        at_most = "5 m"
        """))
    return path


def test_hostile_dut_text_is_made_harmless_everywhere_it_is_shown(ns, tmp_path):
    out = tmp_path / "out"
    r = bench("run", str(_external_case(tmp_path, 43471, '{ mode = "hostile_text", at_s = 1.0 }')), "-o", str(out),
              "-q", "--no-plots", cwd=tmp_path, ns=ns, expect=3)  # the DUT crashed: ERROR
    assert "\x1b" not in r.text and "\\x1b[31mRED" in r.text
    junit = ET.parse(out / "junit.xml")  # parses: no ESC or NUL written raw
    assert "<script>alert(1)</script>" in "".join(junit.getroot().itertext())
    assert "<script>" not in (out / "summary.md").read_text()
    readable(out / "recordings" / "EXT" / "EXT-s1.mcap", tmp_path)


def test_a_dut_writing_on_its_serial_lines_is_read_and_recorded_not_blocked(ns, tmp_path):
    out = tmp_path / "out"
    config = '{ mode = "serial", at_s = 0.5, imu_bytes = 262144, gnss_bytes = 4096 }'
    bench("run", str(_external_case(tmp_path, 43472, config)), "-o", str(out), "-q", "--no-plots", cwd=tmp_path,
          ns=ns)
    info = readable(out / "recordings" / "EXT" / "EXT-s1.mcap", tmp_path)
    assert info["ended"]["status"] == "complete", info["ended"]
    assert json.loads(info["metadata"]["dut_exit"]["serial_rx_bytes"]) == {"imu": 262144, "gnss": 4096}


def test_the_matrix_helpers_can_see_a_process_left_running(tmp_path):
    """The 'nothing left running' check finds a marked process that outlives its parent."""
    mark = uuid.uuid4().hex
    child = subprocess.Popen(["sleep", "30"], env={**os.environ, MARK: mark})
    try:
        assert _marked(mark) == [child.pid]
    finally:
        child.kill()
        child.wait()
    assert _marked(mark) == []
