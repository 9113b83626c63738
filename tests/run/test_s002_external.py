"""S002-external (tests/run/S002_external.toml): the S002 estimator as an external process.

The case file (a test's: S002's acceptance compares four variants, this file runs one),
shortened to its first 250 s (at rest to 180 s, the alignment ending at 170 s, then
70 s of driving: the drive-off and the straight at 8 m/s with the first fault window,
240-245 s, odometer idling), is run with ``bench run`` as a user runs it, in a network
namespace (``ns``): the estimator behind ``{python} -m bench.dut.harness`` on a pty (IMU)
and CAN over udp_multicast (ODOMETER, DRIVER_INPUT, BENCH_TIME, BENCH_EPOCH), in lockstep
1 s steps. Its in-process twin is the S002 case's with_detection variant, shortened the
same way, on the same seed. The converged window (from 180 s) is the shipped one: it
lies inside the 250 s. The fault file is the shipped one, its later windows (540 s on)
included: the bench injects what falls inside the run and judges the windows that start
inside it, so the shortened runs judge the first window alone (checked below).

Checked: the external run completes; both runs had the same inputs (the IMU line's
bytes, the ODOMETER and DRIVER_INPUT frames) and gave the same solution epoch for epoch:
every field of NAV_SOLUTION and NAV_QUALITY as decoded off the bus, the odometer fault
bytes (detected, excluded, class) included, so within the output quantization (ICD 2.2)
-- here to the bit; the fault at 240 s is detected in both; their shared criteria came
out the same.
"""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bench.record.mcap_io import RecordingReader
from bench.scoring.faults import target_bit
from bench.wire.can import codec
from tests.run.s000_twins import CASES, bench_run, criteria, differences, nav, recording, shortened

EXTERNAL = Path(__file__).with_name("S002_external.toml")
UP = "../../test_cases/"
IN_PROCESS = CASES / "S002_sins_odometer_faults.toml"
SHORT_S = 250.0
EPOCHS = round(SHORT_S * 100) + 1  # 100 Hz from 0 s to the end, both included
FAULT = (240.0, 245.0)  # the first window of test_cases/faults/S002_odometer.toml, inside the 250 s
INPUT_IDS = (codec("ODOMETER").frame_id, codec("DRIVER_INPUT").frame_id)
ODO_BIT = 1 << target_bit("odometer")


def _inputs(path: Path) -> tuple[np.ndarray, bytes]:
    """The ODOMETER and DRIVER_INPUT frames and the IMU line's bytes a run sent."""
    r = RecordingReader(path)
    can = r.read_columnar("/wire/can/tx")
    frames = can[np.isin(can["can_id"], INPUT_IDS)][["t_ns", "can_id", "data"]]
    return frames, r.read_chunks("/wire/imu/tx")[2].tobytes()


def _shortened(src: Path, folder: Path) -> Path:
    """:func:`shortened` of a case file, its fault file's path made absolute (and the
    external one's scenario path made as test_cases' are)."""
    (folder / "src").mkdir()
    text = src.read_text().replace(f'script = "{UP}scenarios/', 'script = "scenarios/')
    pattern = rf'^fault_files = \["(?:{re.escape(UP)})?faults/'
    text, n = re.subn(pattern, f'fault_files = ["{CASES}/faults/', text, count=1, flags=re.M)
    assert n == 1, f"{src.name} names no fault file in test_cases/faults/"
    (folder / "src" / src.name).write_text(text)
    return shortened(folder / "src" / src.name, folder, duration_s=SHORT_S)


@pytest.fixture(scope="module")
def runs(ns, tmp_path_factory):
    """The shortened S002-external run (in the namespace) and its in-process twin:
    ``{"external": (exit code, output, results, recording), "in_process": ...}``."""
    folder = tmp_path_factory.mktemp("s002ext")
    (folder / "ext").mkdir()
    ext_case = _shortened(EXTERNAL, folder / "ext")
    code, text, res = bench_run(ext_case, folder / "ext" / "out", ns=ns)
    out = {"external": (code, text, res, recording(folder / "ext" / "out"))}
    (folder / "in").mkdir()
    twin = _shortened(IN_PROCESS, folder / "in")
    code, text, res = bench_run(twin, folder / "in" / "out", "--variant", "with_detection", "--seed", "1")
    out["in_process"] = (code, text, res, recording(folder / "in" / "out"))
    return out


def _detected(quality: np.ndarray) -> np.ndarray:
    """Times (s) of the epochs that flag an odometer fault."""
    return quality["t_ns"][(quality["fault_detected"] & ODO_BIT) != 0] * 1e-9


@pytest.mark.slow
def test_s002_external_runs_end_to_end_over_pty_and_udp_multicast(runs):
    code, text, results, rec = runs["external"]
    assert code in (0, 1), text  # judged (PASS or FAIL), not ERROR: the bench could judge it
    md = RecordingReader(rec).metadata()
    assert md["run_end"]["status"] == "complete", md["run_end"]
    dut_exit = md["dut_exit"]
    assert int(dut_exit["exit_code"]) == 0 and dut_exit["terminated_in_time"] in (True, "true"), dut_exit
    link = json.loads(dut_exit["can_link"])
    assert link["drops"] == 0 and link["untagged"] == 0 and link["senders"] == 1, link
    assert md["dut_output"]["bad_frames"] == "{}"
    sol = nav(rec)["/dut/nav_solution"]
    assert len(sol) == EPOCHS and np.all(np.diff(sol["t_ns"]) == 10_000_000)
    assert sol["mode"][-1] != sol["mode"][0]  # aligned, then navigating with the odometer
    verdicts = criteria(results)
    assert len(verdicts) == 19, verdicts  # the case's 9 and the 10 integrity defaults
    for cid, (verdict, _) in verdicts.items():
        assert verdict in ("PASS", "MARGINAL", "FAIL"), (cid, verdict, text)  # judged on its data
        if cid.startswith(("OUT-", "INTEGRITY-")):
            assert verdict == "PASS", (cid, text)
    # the fault file's later windows start after the end: only the first one is judged
    (case,) = results["cases"]
    (run,) = case["runs"]
    windows = run["criteria"]["DETECT"]["details"]["windows"]
    assert [(round(w["start_s"], 6), round(w["end_s"], 6)) for w in windows] == [FAULT], windows
    log = [d["text"] for _, d in RecordingReader(rec).iter_json("/dut/log")]
    assert any("listening on udp_multicast" in line for line in log)


@pytest.mark.slow
def test_in_process_and_external_give_the_same_solution_epoch_for_epoch(runs):
    """The same recording's inputs both ways, and the same solution at every epoch: every
    field of NAV_SOLUTION and NAV_QUALITY as decoded off the bus, the odometer fault
    bytes included (within the output quantization: here to the bit). The fault at
    240 s is detected and classed in both. The criteria agree (the in-process run is one
    variant of four, so its case is ERROR on the comparison and the controls)."""
    *_, ext_rec = runs["external"]
    _, in_text, in_results, in_rec = runs["in_process"]
    can_a, imu_a = _inputs(in_rec)
    can_b, imu_b = _inputs(ext_rec)
    for fid in INPUT_IDS:
        assert np.count_nonzero(can_a["can_id"] == fid), hex(fid)  # the odometer and the driver input did send
    assert np.array_equal(can_a, can_b) and imu_a == imu_b  # one seed, one recording's inputs
    a, b = nav(in_rec), nav(ext_rec)
    sol_a, sol_b = a["/dut/nav_solution"], b["/dut/nav_solution"]
    assert len(sol_a) == EPOCHS
    assert np.array_equal(sol_a, sol_b), differences(sol_a, sol_b)
    q_a, q_b = a["/dut/nav_quality"], b["/dut/nav_quality"]
    for name in ("fault_detected", "excluded", "odo_fault_class"):
        assert np.array_equal(q_a[name], q_b[name]), name
    assert np.array_equal(q_a, q_b), differences(q_a, q_b)
    for q in (q_a, q_b):  # the fault detected within its window (and its grace), nowhere else
        det = _detected(q)
        assert len(det) and FAULT[0] <= det[0] <= FAULT[0] + 0.5 and det[-1] < FAULT[1] + 1.0, det[[0, -1]]
        assert set(np.unique(q["odo_fault_class"][(q["fault_detected"] & ODO_BIT) != 0])) == {1}  # longitudinal
    ours, theirs = criteria(runs["external"][2]), criteria(in_results)
    assert ours == {cid: theirs[cid] for cid in ours}, in_text
    assert ours["DETECT"] == ("PASS", 100.0) and ours["CLASS"][0] == "PASS", ours


def test_the_external_case_is_the_in_process_with_detection_variant_behind_the_links():
    """S002-external runs and judges what S002's with_detection variant does: the same
    drive, sensors, fault file, estimator and configuration, clock mode, scoring and
    absolute criteria, on a seed of S002's; a link for the same IMU line."""
    ext = tomllib.loads(EXTERNAL.read_text())
    inp = tomllib.loads(IN_PROCESS.read_text())
    assert inp["dut"]["kind"] == "in_process" and ext["dut"]["kind"] == "external"
    assert f"--estimator {inp['dut']['name']} " in ext["dut"]["command"]
    assert ext["dut"]["config"] == {**inp["dut"]["config"], **inp["dut"]["variants"]["with_detection"]["config"]}
    assert (EXTERNAL.parent / ext["scenario"]["script"]).resolve() == IN_PROCESS.parent / inp["scenario"]["script"]
    assert ext["scenario"] == {**inp["scenario"], "script": ext["scenario"]["script"]}
    assert [(EXTERNAL.parent / f).resolve() for f in ext["fault_files"]] == \
        [IN_PROCESS.parent / f for f in inp["fault_files"]]
    assert ext["sensors"] == inp["sensors"]
    assert ext["scoring"] == inp["scoring"]
    assert set(ext["run"]["seeds"]) <= set(inp["run"]["seeds"])
    assert ext["clock"]["mode"] == inp["clock"]["mode"] == "lockstep"
    # the external case runs no other variant: no comparison, no negative control
    wd = [{k: v for k, v in c.items() if k not in ("variant", "must_fail_on")} for c in inp["criterion"]
          if c.get("variant", "with_detection") == "with_detection" and "relative_to" not in c]
    assert ext["criterion"] == wd
    judged = {c["requirement"] for c in wd}
    assert ext["case"]["requirements"] == [r for r in inp["case"]["requirements"] if r in judged]
    assert ext["dut"]["links"]["imu"] == inp["dut"]["links"]["imu"]
