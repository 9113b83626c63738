"""The fault matrix (issue 10), runs: crashes inside the bench, unwritable outputs and full
disks, untrusted FMUs and field logs, hostile external DUTs (what every row checks:
tests/fault_matrix/test_inputs.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import uuid
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests.fault_matrix.matrix import MARK, _marked, bench, case, readable
from tests.run.robust_util import TALKER, dut_command, external_case

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
def _external_case(tmp_path: Path, port: int, config: str) -> Path:
    return external_case(tmp_path / "external.toml", case_id="EXT", command=dut_command(None, None, TALKER),
                         config=config, channel=f"239.74.166.{port % 250}")


def test_hostile_dut_text_is_made_harmless_everywhere_it_is_shown(ns, tmp_path):
    out = tmp_path / "out"
    r = bench("run", str(_external_case(tmp_path, 43471, '{ mode = "hostile_text", at_s = 1.0 }')), "-o", str(out),
              "-q", "--no-plots", cwd=tmp_path, ns=ns, expect=1)  # the DUT crashed: FAIL
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
        # Popen returns once exec has begun, but the kernel fills the new image's
        # environment (what /proc/PID/environ shows) a moment later: wait for the image to
        # be complete (a hang guard, not a timing assertion), then look
        environ = Path(f"/proc/{child.pid}/environ")
        deadline = time.monotonic() + 60.0
        while mark.encode() not in environ.read_bytes() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert _marked(mark) == [child.pid]
    finally:
        child.kill()
        child.wait()
    assert _marked(mark) == []
