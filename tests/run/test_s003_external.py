"""S003-external (tests/run/S003_external.toml): the S003 estimator as an external process.

The case file (a test's: S003b's acceptance compares three variants, this file runs
one), shortened to its first 370 s (at rest to 30 s, the alignment ending at 25 s, the
drive, the straight from 175 s on and the BENCH_CMD "grid" at 300 s, then 70 s in the
grid frame), is run with ``bench run`` as a user runs it, in a network namespace
(``ns``): the estimator behind ``{python} -m bench.dut.harness`` on two ptys (IMU, BDS)
and CAN over udp_multicast (DOPPLER, BENCH_CMD, BENCH_TIME, BENCH_EPOCH), in lockstep 1 s
steps. Its in-process twin is the S003b case's with_conversion variant, shortened the
same way, on the same seed. The frame-switch scoring (reference 180 s and pre 60 s
before the switch, post 60 s after it) lies inside the 370 s, and so do the first 10 s of
the settled window (360 s on): every criterion of the case is judged on its data.

Checked: the external run completes; both runs had the same inputs (the IMU and BDS
lines' bytes, the DOPPLER and BENCH_CMD frames) and gave the same solution epoch for
epoch: every field of NAV_SOLUTION and NAV_QUALITY as decoded off the bus, the frame
bits included, so within the output quantization (ICD 2.2) -- here to the bit; the
frame bits change from geographic to grid once, at the same epoch in both, the output
epoch of the command (300 s) or the next; their shared criteria (the switch, its delay
after the command, the smoothness) came out the same.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bench.record.mcap_io import RecordingReader
from bench.wire.can import codec
from tests.run.s000_twins import CASES, bench_run, criteria, differences, nav, recording, shortened

EXTERNAL = Path(__file__).with_name("S003_external.toml")
SCENARIO = "../../test_cases/scenarios/"
IN_PROCESS = CASES / "S003b_frame_switch_commanded.toml"
SHORT_S = 370.0
EPOCHS = round(SHORT_S * 100) + 1  # 100 Hz from 0 s to the end, both included
CMD_NS = 300_000_000_000  # the case's BENCH_CMD "grid"
EPOCH_NS = 10_000_000  # the 100 Hz output epoch
DOPPLER_ID, CMD_ID = codec("DOPPLER").frame_id, codec("BENCH_CMD").frame_id
SWITCH = ("SWITCHED", "CMD-DELAY", "HDG-SMOOTH", "VEL-SMOOTH", "POS-JUMP")


def _inputs(path: Path) -> tuple[np.ndarray, bytes, bytes]:
    """The DOPPLER and BENCH_CMD frames, the IMU line's and the BDS line's bytes a run sent."""
    r = RecordingReader(path)
    can = r.read_columnar("/wire/can/tx")
    frames = can[np.isin(can["can_id"], (DOPPLER_ID, CMD_ID))][["t_ns", "can_id", "data"]]
    return frames, r.read_chunks("/wire/imu/tx")[2].tobytes(), r.read_chunks("/wire/gnss/tx")[2].tobytes()


def _shortened(src: Path, folder: Path) -> Path:
    """:func:`shortened` of a case file, the external one's scenario path made as test_cases' are."""
    if src == EXTERNAL:
        (folder / "src").mkdir()
        text = src.read_text().replace(f'script = "{SCENARIO}', 'script = "scenarios/')
        (folder / "src" / src.name).write_text(text)
        src = folder / "src" / src.name
    return shortened(src, folder, duration_s=SHORT_S)


@pytest.fixture(scope="module")
def runs(ns, tmp_path_factory):
    """The shortened S003-external run (in the namespace) and its in-process twin:
    ``{"external": (exit code, output, results, recording), "in_process": ...}``."""
    folder = tmp_path_factory.mktemp("s003ext")
    (folder / "ext").mkdir()
    ext_case = _shortened(EXTERNAL, folder / "ext")
    code, text, res = bench_run(ext_case, folder / "ext" / "out", ns=ns)
    out = {"external": (code, text, res, recording(folder / "ext" / "out"))}
    (folder / "in").mkdir()
    twin = _shortened(IN_PROCESS, folder / "in")
    code, text, res = bench_run(twin, folder / "in" / "out", "--variant", "with_conversion", "--seed", "1")
    out["in_process"] = (code, text, res, recording(folder / "in" / "out"))
    return out


def _switch_ns(sol: np.ndarray) -> int:
    """The time of the first epoch in the grid frame; fails unless the frame bits go from
    geographic (0) to grid (1) exactly once and stay there."""
    frame = sol["frame"].astype(int)
    change = np.flatnonzero(np.diff(frame))
    assert len(change) == 1, sol["t_ns"][change + 1] * 1e-9
    i = int(change[0]) + 1
    assert np.all(frame[:i] == 0) and np.all(frame[i:] == 1), np.unique(frame)
    return int(sol["t_ns"][i])


def _switch_details(results: dict) -> list[dict]:
    """The per-switch measures (jump, step, amplitude, band... per quantity) a run's
    frame-switch criteria were judged on."""
    (case,) = results["cases"]
    (run,) = case["runs"]
    per = [run["criteria"][cid]["details"]["switches"] for cid in SWITCH]
    assert all(p == per[0] for p in per), per
    return per[0]


@pytest.mark.slow
def test_s003_external_runs_end_to_end_over_two_ptys_and_udp_multicast(runs):
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
    assert len(sol) == EPOCHS and np.all(np.diff(sol["t_ns"]) == EPOCH_NS)
    assert sol["mode"][-1] != sol["mode"][0]  # aligned, then navigating with the aids
    verdicts = criteria(results)
    n_case = len(tomllib.loads(EXTERNAL.read_text())["criterion"])
    assert n_case == 21 and len(verdicts) == n_case + 10, verdicts  # the case's and the 10 integrity defaults
    for cid, (verdict, _) in verdicts.items():
        assert verdict in ("PASS", "MARGINAL", "FAIL"), (cid, verdict, text)  # judged on its data
    assert verdicts["OUT-MISSING"][0] == "PASS", text
    assert all(v == "PASS" for cid, (v, _) in verdicts.items() if cid.startswith("INTEGRITY-")), verdicts
    log = [d["text"] for _, d in RecordingReader(rec).iter_json("/dut/log")]
    assert any("listening on udp_multicast" in line for line in log)
    diag = [line for line in log if line.startswith("seed003 diagnostics:")]  # its close() ran, on its stderr
    assert len(diag) == 1 and json.loads(diag[0].partition(":")[2])["switches"] == 1, diag


@pytest.mark.slow
def test_in_process_and_external_give_the_same_solution_and_switch_epoch_for_epoch(runs):
    """The same recording's inputs both ways, the command included, and the same solution
    at every epoch: every field of NAV_SOLUTION and NAV_QUALITY as decoded off the bus
    (within the output quantization: here to the bit). The frame bits go to the grid
    frame at the same epoch in both, the command's output epoch or the next. The criteria
    agree (the in-process run is one variant of three, so its case is ERROR on the
    comparison and the controls)."""
    *_, ext_rec = runs["external"]
    _, in_text, in_results, in_rec = runs["in_process"]
    can_a, imu_a, gnss_a = _inputs(in_rec)
    can_b, imu_b, gnss_b = _inputs(ext_rec)
    assert np.count_nonzero(can_a["can_id"] == DOPPLER_ID) and len(gnss_a)  # the radar and the receiver did send
    assert can_a["t_ns"][can_a["can_id"] == CMD_ID].tolist() == [CMD_NS]  # the one command, at 300 s
    assert np.array_equal(can_a, can_b) and imu_a == imu_b and gnss_a == gnss_b  # one seed, one recording's inputs
    a, b = nav(in_rec), nav(ext_rec)
    sol_a, sol_b = a["/dut/nav_solution"], b["/dut/nav_solution"]
    assert len(sol_a) == EPOCHS
    switch_a, switch_b = _switch_ns(sol_a), _switch_ns(sol_b)
    assert switch_a == switch_b, (switch_a, switch_b)
    assert CMD_NS <= switch_b <= CMD_NS + EPOCH_NS, switch_b * 1e-9
    assert np.array_equal(sol_a, sol_b), differences(sol_a, sol_b)
    q_a, q_b = a["/dut/nav_quality"], b["/dut/nav_quality"]
    assert np.array_equal(q_a, q_b), differences(q_a, q_b)
    ours, theirs = criteria(runs["external"][2]), criteria(in_results)
    assert ours == {cid: theirs[cid] for cid in ours}, in_text
    # the switch's measures behind SWITCHED, CMD-DELAY and the smoothness, not only the verdicts' values
    details = [_switch_details(r) for r in (runs["external"][2], in_results)]
    assert details[0] == details[1] and len(details[0]) == 1, details
    assert details[0][0]["t_s"] == pytest.approx(switch_b * 1e-9) and details[0][0]["to"] == "grid", details
    assert ours["SWITCHED"] == ("PASS", 1.0), ours
    assert ours["CMD-DELAY"][0] == "PASS" and ours["CMD-DELAY"][1] == pytest.approx((switch_b - CMD_NS) * 1e-9), ours


def test_the_external_case_is_the_in_process_with_conversion_variant_behind_the_links():
    """S003-external runs and judges what S003b's with_conversion variant does: the same
    drive, sensors, command, estimator and configuration, clock mode, scoring and absolute
    criteria, on a seed of S003b's; links for the same lines."""
    ext = tomllib.loads(EXTERNAL.read_text())
    inp = tomllib.loads(IN_PROCESS.read_text())
    assert inp["dut"]["kind"] == "in_process" and ext["dut"]["kind"] == "external"
    command = ext["dut"]["command"]
    assert f"--estimator {inp['dut']['name']} " in command and "--gnss {gnss_port}" in command
    assert ext["dut"]["config"] == {**inp["dut"]["config"], **inp["dut"]["variants"]["with_conversion"]["config"]}
    assert (EXTERNAL.parent / ext["scenario"]["script"]).resolve() == IN_PROCESS.parent / inp["scenario"]["script"]
    assert ext["scenario"] == {**inp["scenario"], "script": ext["scenario"]["script"]}
    assert ext["sensors"] == inp["sensors"]
    assert ext["command"] == inp["command"]
    assert ext["scoring"] == inp["scoring"]
    assert set(ext["run"]["seeds"]) <= set(inp["run"]["seeds"])
    assert ext["clock"]["mode"] == inp["clock"]["mode"] == "lockstep"
    # the external case runs no other variant: no comparison, no negative control
    wc = [{k: v for k, v in c.items() if k not in ("variant", "must_fail_on")} for c in inp["criterion"]
          if c.get("variant", "with_conversion") == "with_conversion" and "relative_to" not in c]
    assert ext["criterion"] == wc
    judged = {c["requirement"] for c in wc}
    assert ext["case"]["requirements"] == [r for r in inp["case"]["requirements"] if r in judged]
    for line in ("imu", "gnss"):
        assert ext["dut"]["links"][line] == inp["dut"]["links"][line], line
