"""What an external DUT writes where the bench only used to write or to show:

* bytes on its serial lines: drained (the DUT never blocks on a full pty) and recorded
  exactly on ``/wire/imu/rx`` and ``/wire/gnss/rx``;
* hostile text on stderr (terminal escapes, ``<script>``, ``]]>``, NUL, ``|``): recorded
  raw on ``/dut/log``, shown escaped by ``bench run`` on the terminal, in summary.md and
  junit.xml (which stays parseable).

The DUT is tests/run/duts/talker.py on pty pairs and python-can udp_multicast inside a
network namespace (fixture ``ns``).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from bench.faults.schedule import FaultSchedule
from bench.record.mcap_io import RecordingReader
from bench.record.wire_topics import SERIAL_RX, read_serial
from bench.run.engine import run
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.scenario.loader import load_scenario
from tests.run.duts.talker import HOSTILE, pattern
from tests.run.robust_util import SHORT, TABLES, TALKER, dut_command, external_case, group_members, log_texts
from tests.transport import netns

RAW_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u202a-\u202e]")  # newline and tab are the output's own


def _command(ns: str | None, port: int | None) -> str:
    return dut_command(ns, port, TALKER)


def _run(ns: str, tmp_path: Path, port: int, clock: ClockSpec, **config):
    links = LinkSpec(can={"interface": "udp_multicast", "channel": f"239.74.164.{port % 250}", "port": port})
    dut = DutSpec("external", command=_command(ns, port), config=config, startup_timeout_s=60.0,
                  shutdown_timeout_s=60.0)  # hang guards, not speed bounds
    spec = RunSpec(scenario=load_scenario(SHORT), tables=TABLES, schedule=FaultSchedule(), dut=dut,
                   out=tmp_path / "talk.mcap", links=links, clock=clock, duration_ns=2_000_000_000)
    return netns.call_in(ns, lambda: run(spec))


@pytest.mark.slow
@pytest.mark.parametrize(
    ("clock", "port"),
    [(ClockSpec(timeout_s=60.0), 43461), (ClockSpec(mode="realtime", speed=1.0), 43462)],
    ids=["lockstep", "realtime"],
)
def test_a_dut_writing_1_mib_on_its_imu_line_does_not_block_and_every_byte_is_recorded(ns, tmp_path, clock, port):
    imu_n, gnss_n = 1 << 20, 100_000
    res = _run(ns, tmp_path, port, clock, mode="serial", at_s=0.5, imu_bytes=imu_n, gnss_bytes=gnss_n)
    assert res.status == "complete", res.reason
    reader = RecordingReader(res.path)
    imu = read_serial(reader, SERIAL_RX["imu"])
    gnss = read_serial(reader, SERIAL_RX["gnss"])
    assert imu.tobytes() == pattern(imu_n, 3)  # exactly the bytes it wrote, in order
    assert gnss.tobytes() == pattern(gnss_n, 5)
    # stamped with the bench time they were read at: after the DUT wrote them (0.5 s), in
    # order, by the end of the run (in real time the close comes a moment after the end)
    end_ns = 2.0e9 if clock.lockstep else 3.0e9
    assert int(imu.t_ns.min()) >= 0.5e9 and np.all(np.diff(imu.t_ns) >= 0) and int(imu.t_ns.max()) <= end_ns
    dut_exit = json.loads(reader.metadata()["dut_exit"]["serial_rx_bytes"])
    assert dut_exit == {"imu": imu_n, "gnss": gnss_n}
    assert ("stdout", f"talker: wrote {imu_n} + {gnss_n} bytes") in log_texts(res.path)
    sol = reader.read_columnar("/dut/nav_solution")
    # it went on after writing: in lockstep to the last step; in real time it answered the
    # steps after the write (how many before the run ended depends on the machine's load)
    assert sol["t_ns"].max() >= (1.99e9 if clock.lockstep else 0.51e9)
    assert not group_members(json.loads(reader.metadata()["dut_exit"]["pid"]))


def _case(tmp_path: Path, port: int) -> Path:
    return external_case(tmp_path / "hostile.toml", case_id="HOSTILE", command=_command(None, None),
                         config='{ mode = "hostile_text", at_s = 1.0 }', channel=f"239.74.165.{port % 250}")


@pytest.mark.slow
def test_hostile_dut_text_is_escaped_on_the_terminal_and_in_the_reports(ns, tmp_path):
    out = tmp_path / "out"
    cli = [sys.executable, "-c", "import sys; from bench.cli import main; sys.exit(main())"]
    p = subprocess.run(["ip", "netns", "exec", ns, *cli, "run", str(_case(tmp_path, 43463)), "-o", str(out), "-q",
                        "--no-plots"], capture_output=True, text=True, timeout=180)
    assert p.returncode == 1, p.stderr  # the DUT crashed: its FAIL
    terminal = p.stdout + p.stderr
    assert "talker: " in terminal and "\\x1b[31mRED" in terminal  # the reason is shown, made visible
    assert not RAW_CONTROL.search(terminal), repr(terminal)
    assert "Traceback" not in terminal
    junit = ET.parse(out / "junit.xml").getroot()  # parses: no NUL or ESC written raw
    shown = "".join(junit.itertext())
    assert "<script>alert(1)</script>" in shown and not RAW_CONTROL.search(shown)
    md = (out / "summary.md").read_text()
    assert "<script>" not in md and "&lt;script&gt;" in md and not RAW_CONTROL.search(md)
    assert not RAW_CONTROL.search((out / "summary.txt").read_text())
    rec = out / "recordings" / "HOSTILE" / "HOSTILE-s1.mcap"
    assert ("stderr", f"talker: {HOSTILE}") in log_texts(rec)  # the recording keeps it raw
    results = json.loads((out / "results.json").read_text())
    assert results["cases"][0]["verdict"] == "FAIL"
