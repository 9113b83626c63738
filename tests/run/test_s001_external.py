"""S001-external (tests/run/S001_external.toml): the S001 estimator as an external process.

The case file (a test's: its 10 ms lockstep steps run at about real time, too slow for
the acceptance suite), shortened to its first 80 s (60 s at rest, the alignment ending at 55 s,
then 20 s of driving with BDS fixes and the odometer; the converged window moved to 70 s),
is run with ``bench run`` as a user runs it, in a network namespace (``ns``): the
estimator behind ``{python} -m bench.dut.harness`` on two ptys (IMU, BDS) and CAN over
udp_multicast, in lockstep 10 ms steps. Its in-process twin is the S001 case's full
variant, shortened the same way, on the same seed. Checked: the external run completes;
both runs had the same inputs (IMU and BDS line bytes, CAN sensor frames) and gave the
same solution epoch for epoch: every field of NAV_SOLUTION and NAV_QUALITY as decoded
off the bus, so within the output quantization (ICD 2.2: 1e-7 deg, 1 mm, 0.1 mm/s;
sigmas 0.01 m, 1 mm/s, 0.01 arcmin) -- here to the quantum; their shared criteria came out
the same.
"""

from __future__ import annotations

import json
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bench.record.mcap_io import RecordingReader
from tests.run.s000_twins import CASES, bench_run, criteria, differences, nav, recording, shortened

EXTERNAL = Path(__file__).with_name("S001_external.toml")
SCENARIO = "../../test_cases/scenarios/"
IN_PROCESS = CASES / "S001_bds_sins.toml"
SHORT_S = 80.0
CONVERGED_S = 70.0
EPOCHS = round(SHORT_S * 100) + 1  # 100 Hz from 0 s to the end, both included
ODOMETER_ID = 0x120


def _inputs(path: Path) -> tuple[np.ndarray, bytes, bytes]:
    """The ODOMETER frames, the IMU line's and the BDS line's bytes a run sent."""
    r = RecordingReader(path)
    can = r.read_columnar("/wire/can/tx")
    odo = can[can["can_id"] == ODOMETER_ID][["t_ns", "data"]]
    return odo, r.read_chunks("/wire/imu/tx")[2].tobytes(), r.read_chunks("/wire/gnss/tx")[2].tobytes()


def _shortened(src: Path, folder: Path) -> Path:
    """:func:`shortened` of a case file, this one's scenario path made as test_cases' are."""
    if src == EXTERNAL:
        (folder / "src").mkdir()
        text = src.read_text().replace(f'script = "{SCENARIO}', 'script = "scenarios/')
        (folder / "src" / src.name).write_text(text)
        src = folder / "src" / src.name
    out = shortened(src, folder, duration_s=SHORT_S, convergence_s=CONVERGED_S)
    roads = Path(__file__).parents[2] / "test_cases" / "scenarios" / "S001_roads.geojson"
    (out.parent / "scenarios").mkdir(exist_ok=True)
    shutil.copyfile(roads, out.parent / "scenarios" / roads.name)  # the case's [scoring.map] network
    return out


@pytest.fixture(scope="module")
def runs(ns, tmp_path_factory):
    """The shortened S001-external run (in the namespace) and its in-process twin:
    ``{"external": (exit code, output, results, recording), "in_process": ...}``."""
    folder = tmp_path_factory.mktemp("s001ext")
    (folder / "ext").mkdir()
    ext_case = _shortened(EXTERNAL, folder / "ext")
    code, text, res = bench_run(ext_case, folder / "ext" / "out", ns=ns)
    out = {"external": (code, text, res, recording(folder / "ext" / "out"))}
    (folder / "in").mkdir()
    twin = _shortened(IN_PROCESS, folder / "in")
    code, text, res = bench_run(twin, folder / "in" / "out", "--variant", "full", "--seed", "1")
    out["in_process"] = (code, text, res, recording(folder / "in" / "out"))
    return out


@pytest.mark.slow
def test_s001_external_runs_end_to_end_over_two_ptys_and_udp_multicast(runs):
    _, text, results, rec = runs["external"]
    md = RecordingReader(rec).metadata()
    assert md["run_end"]["status"] == "complete", md["run_end"]
    dut_exit = md["dut_exit"]
    assert int(dut_exit["exit_code"]) == 0 and dut_exit["terminated_in_time"] in (True, "true"), dut_exit
    link = json.loads(dut_exit["can_link"])
    assert link["drops"] == 0 and link["untagged"] == 0 and link["senders"] == 1, link
    assert md["dut_output"]["bad_frames"] == "{}"
    sol = nav(rec)["/dut/nav_solution"]
    assert len(sol) == EPOCHS and np.all(np.diff(sol["t_ns"]) == 10_000_000)
    assert sol["mode"][-1] != sol["mode"][0]  # aligned, then navigating with the aids
    verdicts = criteria(results)
    for cid in ("H95", "V95", "VEL95", "BEAT-BDS", "NEES-POS", "LEVER-ARM", "TIME-SYNC"):  # no outage in 80 s
        assert verdicts[cid][0] in ("PASS", "MARGINAL", "FAIL"), (cid, verdicts[cid], text)  # judged on its data
    assert all(v == "PASS" for cid, (v, _) in verdicts.items() if cid.startswith("INTEGRITY-")), verdicts
    log = [d["text"] for _, d in RecordingReader(rec).iter_json("/dut/log")]
    assert any("listening on udp_multicast" in line for line in log)
    assert any(line.startswith("seed001 diagnostics:") for line in log)  # its close() ran, on its stderr


@pytest.mark.slow
def test_in_process_and_external_give_the_same_solution_epoch_for_epoch(runs):
    """The same recording's inputs both ways, and the same solution at every epoch: every
    field of NAV_SOLUTION and NAV_QUALITY as decoded off the bus (within the output
    quantization: here to the quantum). The criteria agree."""
    *_, ext_rec = runs["external"]
    _, in_text, in_results, in_rec = runs["in_process"]
    odo_a, imu_a, gnss_a = _inputs(in_rec)
    odo_b, imu_b, gnss_b = _inputs(ext_rec)
    assert len(odo_a) and len(gnss_a)  # the odometer and the receiver did send
    assert np.array_equal(odo_a, odo_b) and imu_a == imu_b and gnss_a == gnss_b  # one seed, one recording's inputs
    a, b = nav(in_rec), nav(ext_rec)
    sol_a, sol_b = a["/dut/nav_solution"], b["/dut/nav_solution"]
    assert len(sol_a) == EPOCHS
    assert np.array_equal(sol_a, sol_b), differences(sol_a, sol_b)
    assert np.array_equal(a["/dut/nav_quality"], b["/dut/nav_quality"])
    ours, theirs = criteria(runs["external"][2]), criteria(in_results)
    assert ours == {cid: theirs[cid] for cid in ours}, in_text


def test_the_external_case_is_the_in_process_full_variant_behind_the_links():
    """S001-external runs and judges what S001's full variant does: the same drive,
    sensors, estimator and configuration, clock, scoring windows and absolute criteria, on
    a seed of S001's; links for the same lines."""
    ext = tomllib.loads(EXTERNAL.read_text())
    inp = tomllib.loads(IN_PROCESS.read_text())
    assert inp["dut"]["kind"] == "in_process" and ext["dut"]["kind"] == "external"
    command = ext["dut"]["command"]
    assert f"--estimator {inp['dut']['name']} " in command and "--gnss {gnss_port}" in command
    assert ext["dut"]["config"] == {**inp["dut"]["config"], **inp["dut"]["variants"]["full"]["config"]}
    assert (EXTERNAL.parent / ext["scenario"]["script"]).resolve() == IN_PROCESS.parent / inp["scenario"]["script"]
    assert ext["scenario"] == {**inp["scenario"], "script": ext["scenario"]["script"]}
    assert ext["sensors"] == inp["sensors"]
    # [scoring.map] judges only the map_matched variant, which the external case does not run
    assert ext["scoring"] == {k: v for k, v in inp["scoring"].items() if k != "map"}
    assert set(ext["run"]["seeds"]) <= set(inp["run"]["seeds"])
    assert ext["clock"]["mode"] == inp["clock"]["mode"] == "lockstep" and ext["clock"]["step"] == inp["clock"]["step"]
    # the external case runs no other variant: no comparison, no negative control
    full = [{k: v for k, v in c.items() if k not in ("variant", "must_fail_on")} for c in inp["criterion"]
            if c.get("variant", "full") == "full" and "relative_to" not in c]
    assert ext["criterion"] == full
    judged = {c["requirement"] for c in full}
    assert ext["case"]["requirements"] == [r for r in inp["case"]["requirements"] if r in judged]
    for line in ("imu", "gnss"):
        assert ext["dut"]["links"][line] == inp["dut"]["links"][line], line
