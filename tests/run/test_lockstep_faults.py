"""Wire faults and the bench's own lockstep frame (bench.faults.lockstep.refuse_lockstep_faults).

In lockstep the bench sends BENCH_TIME(T) and waits for DUT_READY(T): a fault on
BENCH_TIME leaves a conforming DUT nothing to answer, and the run used to end ERROR
blaming the DUT. A window aimed at ``can:BENCH_TIME`` is refused up front (exit 2, the
fault's file and index named, nothing run); ``can:*`` and ``can`` windows leave
BENCH_TIME alone in lockstep and act on every other message as before.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.cli.app import run as cli
from bench.faults.schedule import parse_schedule
from bench.faults.wire import WireFaultInjector
from bench.run.traffic import BENCH_TIME_ID
from bench.wire.can import CanEncoder, codec

DATA = Path(__file__).parent / "data"
DRIVE = (DATA.parent.parent / "data" / "short_drive.toml").as_posix()
CASE = (DATA / "short_dr.toml").read_text().replace('"../../data/short_drive.toml"', f'"{DRIVE}"')
FAULT = '\n[[fault]]\nlayer = "wire"\ntarget = "{target}"\nkind = "{kind}"\nstart = "2 s"\nduration = "1 s"\n'


def _refused(capsys, argv: list[str], *needles: str) -> str:
    code = cli(argv)
    err = capsys.readouterr().err
    assert code == 2, f"exit {code}, expected 2; stderr: {err}"
    assert "Traceback" not in err
    for n in needles:
        assert n in err, f"{n!r} not in the message: {err}"
    return err


@pytest.mark.parametrize("kind", ["corrupt_crc", "drop", "delay", "counter_skip"])
def test_a_fault_on_bench_time_in_lockstep_is_refused_naming_the_case_and_the_fault(tmp_path, capsys, kind):
    case = tmp_path / "case.toml"
    case.write_text(CASE + FAULT.format(target="can:ODOMETER", kind="drop") + FAULT.format(target="can:BENCH_TIME",
                                                                                           kind=kind))
    out = tmp_path / "out"
    err = _refused(capsys, ["run", str(case), "-o", str(out), "-q", "--no-plots"],
                   str(case), "fault[1].target", "can:BENCH_TIME", "lockstep")
    assert err.count("\n") <= 2, err
    assert not list(out.rglob("*.mcap")), "nothing may run: a recording was written"


def test_the_refusal_names_the_fault_file_and_its_index(tmp_path, capsys):
    faults = tmp_path / "timing_faults.toml"
    faults.write_text(FAULT.format(target="serial:imu", kind="drop") + FAULT.format(target="can:BENCH_TIME",
                                                                                    kind="corrupt_crc"))
    case = tmp_path / "case.toml"
    case.write_text(CASE.replace("[case]", f'fault_files = ["{faults.name}"]\n\n[case]', 1))
    out = tmp_path / "out"
    _refused(capsys, ["run", str(case), "-o", str(out), "-q", "--no-plots"], str(faults), "fault[1].target")
    assert not list(out.rglob("*.mcap"))


def test_bench_accept_reports_the_case_as_malformed_and_runs_nothing(tmp_path, capsys):
    case = tmp_path / "case.toml"
    case.write_text(CASE + FAULT.format(target="can:BENCH_TIME", kind="corrupt_crc"))
    out = tmp_path / "out"
    assert cli(["accept", str(case), "-o", str(out), "-q", "--no-plots"]) == 2
    assert "fault[0].target" in capsys.readouterr().out
    assert not list(out.rglob("*.mcap"))
    # in real time (the case's or the command line's) it is a legitimate test of the DUT's time sync
    from bench.acceptance.case import load_case
    from bench.acceptance.suite import SuiteOptions, refuse_impossible_faults

    refuse_impossible_faults(load_case(case), SuiteOptions(out, clock="realtime"))


def _bus(n: int) -> tuple[np.ndarray, object]:
    enc = CanEncoder()
    t = np.arange(n, dtype=np.int64) * 10_000_000
    bt = enc.encode("BENCH_TIME", t, time_ns=t, lockstep=np.ones(n, np.int64))
    odo = enc.encode("ODOMETER", t, pulse_count=np.arange(n), speed=np.ones(n), reverse=np.zeros(n, np.int64),
                     valid=np.ones(n, np.int64))
    from bench.frames import CanBatch

    return t, CanBatch.concat([odo, bt]).sorted()


@pytest.mark.parametrize("target", ["can:*", "can"])
def test_can_wide_faults_leave_bench_time_alone_in_lockstep_and_hit_it_in_real_time(target):
    kind = "silence" if target == "can" else "corrupt_crc"
    sched = parse_schedule([{"layer": "wire", "target": target, "kind": kind, "start": 0.1, "end": 0.2}])
    _, frames = _bus(30)
    got = {}
    for lockstep in (True, False):
        out, ev = WireFaultInjector(sched, 7, lockstep=lockstep).can(frames)
        bt = out.take(np.flatnonzero(out.can_id == BENCH_TIME_ID))
        _, status = codec("BENCH_TIME").decode(bt)
        got[lockstep] = (len(bt), int(np.count_nonzero(status)), int(np.count_nonzero(ev["can_id"] == BENCH_TIME_ID)))
        odo_events = int(np.count_nonzero(ev["can_id"] != BENCH_TIME_ID))
        assert odo_events == 10 or (kind == "silence" and odo_events >= 1), (lockstep, odo_events)
    assert got[True] == (30, 0, 0)  # lockstep: every BENCH_TIME out, intact, no event on it
    assert got[False] != (30, 0, 0)  # real time: the fault acts on BENCH_TIME as on every message


def test_the_injector_refuses_bench_time_windows_only_in_lockstep():
    sched = parse_schedule([{"layer": "wire", "target": "can:BENCH_TIME", "kind": "corrupt_crc", "start": 0.1,
                             "end": 0.2}], file="f.toml")
    WireFaultInjector(sched, 1)  # real time: a legitimate test of the DUT's time sync
    from bench.errors import ConfigError

    with pytest.raises(ConfigError, match=r"f\.toml: fault\[0\]\.target: .*lockstep"):
        WireFaultInjector(sched, 1, lockstep=True)


def test_a_can_wide_crc_fault_in_lockstep_runs_to_the_end_with_a_conforming_dut(tmp_path):
    """A DUT that discards frames with a bad CRC (ICD 1) still gets every BENCH_TIME: the
    run ends OK with the fault's frames counted, instead of ERROR blaming the DUT."""
    from bench.record.mcap_io import RecordingReader
    from tests.run.test_startup import _hardware_run

    sched = parse_schedule([{"layer": "wire", "target": "can:*", "kind": "corrupt_crc", "start": 1.01, "end": 1.2}])
    res, dut = _hardware_run(tmp_path, "crc.mcap", deaf_for=0, schedule=sched)
    assert res.ok, res.reason
    assert dut.problems() == [] and dut.bad_crc == 0  # no BENCH_TIME touched (no BENCH_EPOCH in the window)
    ev = RecordingReader(res.path).read_columnar("/faults/wire")
    assert len(ev) > 0 and not np.any(ev["can_id"] == BENCH_TIME_ID)
