"""The run engine end to end: in process and as an external process over pty + CAN,
lockstep and real time, determinism, replay, wire faults seen by the DUT.

Nothing here asserts how fast this machine is: real-time runs are checked for their
mechanism (every emission made, in order, its lateness measured and recorded, the
answers received in order and complete), the timing figures are in
benchmarks/bench_run.py. The time limits given to external DUTs (start-up, the lockstep
wait, the shutdown) are hang guards of :data:`HANG_S`, so a loaded machine is slower,
never failed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from bench.clock.pacing import TimingBudget, TimingLog
from bench.faults.schedule import FaultSchedule, parse_schedule
from bench.record.mcap_io import RecordingReader
from bench.record.wire_topics import CAN_TX_DTYPE, can_batch, can_records
from bench.run.engine import execute, run
from bench.run.replay import RecordingReplay
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.run.startup import drop_handshake_copies
from bench.run.traffic import BENCH_TIME_ID
from bench.scenario.loader import load_scenario
from bench.sensors.suite import load_fault_kinds
from tests.transport import netns

#: Hang guard of the external DUTs here (start-up, lockstep wait, shutdown), s: a DUT that
#: does not answer within a minute hangs. Never a speed bound.
HANG_S = 60.0
DATA = Path(__file__).parent.parent / "data"
SHORT = DATA / "short_drive.toml"
DR = {"initial_position": [34.246, 108.909, 380.0], "alignment": "4 s"}
TABLES = {"imu": {"grade": "navigation", "rate": "200 Hz"}, "doppler": {"model": "seed000"},
          "odometer": {"model": "typical_wheeled"}, "bds": {"model": "seed001", "latency": "80 ms"},
          "driver": {"vehicle": "wheeled"}}


def _spec(out: Path, *, seed: int = 1, dut: DutSpec | None = None, clock: ClockSpec | None = None,
          schedule: FaultSchedule | None = None, duration_s: float | None = None, **kw) -> RunSpec:
    sc = load_scenario(SHORT)
    return RunSpec(scenario=sc, tables=TABLES, schedule=schedule or FaultSchedule(),
                   dut=dut or DutSpec("in_process", name="dead_reckoning", config=DR), out=out, seed=seed,
                   clock=clock or ClockSpec(), duration_ns=None if duration_s is None else round(duration_s * 1e9),
                   **kw)


def _sensor_traffic(path: Path) -> dict[str, object]:
    """What the bench sent, without BENCH_TIME, one round of an external DUT's start-up
    kept (how many rounds it took depends on the DUT)."""
    r = RecordingReader(path)
    can = can_records(drop_handshake_copies(can_batch(r.read_columnar("/wire/can/tx"))), CAN_TX_DTYPE)
    return {"can": can[can["can_id"] != BENCH_TIME_ID], "imu": r.read_chunks("/wire/imu/tx"),
            "gnss": r.read_chunks("/wire/gnss/tx")}


def _same_traffic(a: dict, b: dict) -> bool:
    return (np.array_equal(a["can"], b["can"])
            and all(np.array_equal(x, y) for x, y in zip(a["imu"], b["imu"], strict=True))
            and all(np.array_equal(x, y) for x, y in zip(a["gnss"], b["gnss"], strict=True)))


def _nav(path: Path) -> np.ndarray:
    sol = RecordingReader(path).read_columnar("/dut/nav_solution")
    return sol[[n for n in sol.dtype.names if n != "rx_ns"]]


def test_in_process_run_records_both_directions(tmp_path):
    res = run(_spec(tmp_path / "a.mcap"))
    assert res.ok, res.reason
    r = RecordingReader(res.path)
    md = r.metadata()
    assert md["run_end"]["status"] == "complete" and md["run_start"]["dut"] == "dead_reckoning"
    assert md["dut_input_tally"] == {}  # the DUT-side decoders rejected nothing
    can = r.read_columnar("/wire/can/tx")
    ids, counts = np.unique(can["can_id"], return_counts=True)
    n = dict(zip(ids.tolist(), counts.tolist(), strict=True))
    assert n[0x010] == 9001 and n[0x120] == 9000 and n[0x130] == 4500 and n[0x121] == 4500 and n[0x011] == 91
    t_imu, offsets, _ = r.read_chunks("/wire/imu/tx")
    assert len(t_imu) == 18000 and set(np.diff(offsets).tolist()) == {42}
    t_g, _, buf = r.read_chunks("/wire/gnss/tx")
    # fixes at 1 .. 89 s leave 80 ms later; the one of 90 s would leave after the run ends
    assert buf.tobytes().count(b"$GBRMC") == 89 and np.all(t_g % 1_000_000_000 == 80_000_000)
    sol = r.read_columnar("/dut/nav_solution")
    assert len(sol) == 9001 and np.all(np.diff(sol["t_ns"]) == 10_000_000)
    assert np.all(sol["rx_ns"] >= sol["t_ns"])
    assert len(r.read_columnar("/wire/can/rx")) == len(sol) + len(r.read_columnar("/dut/nav_quality"))
    assert md["dut_output"]["bad_frames"] == "{}"


def test_same_seed_same_payloads_other_seed_other_noise(tmp_path):
    a = _sensor_traffic(run(_spec(tmp_path / "a.mcap", seed=5)).path)
    b = _sensor_traffic(run(_spec(tmp_path / "b.mcap", seed=5)).path)
    c = _sensor_traffic(run(_spec(tmp_path / "c.mcap", seed=6)).path)
    assert _same_traffic(a, b)
    assert not all(np.array_equal(x, y) for x, y in zip(a["imu"], c["imu"], strict=True))


def test_wire_faults_reach_the_dut_and_are_recorded(tmp_path):
    load_fault_kinds()
    sched = parse_schedule([
        {"layer": "wire", "target": "can:ODOMETER", "kind": "corrupt_crc", "start": "20 s", "end": "21 s"},
        {"layer": "wire", "target": "serial:imu", "kind": "garbage", "start": "30 s", "end": "31 s",
         "params": {"length": 20}},
        {"layer": "wire", "target": "can:DOPPLER", "kind": "drop", "start": "40 s", "end": "50 s"},
    ])
    res = run(_spec(tmp_path / "f.mcap", schedule=sched))
    assert res.ok, res.reason
    r = RecordingReader(res.path)
    tally = {k: int(v) for k, v in r.metadata()["dut_input_tally"].items()}
    assert tally["crc"] == 100 and tally["sync"] == 1
    events = r.read_columnar("/faults/wire")
    assert sorted(set(events["fault_id"].tolist())) == [0, 1, 2]
    dop = r.read_columnar("/wire/can/tx")
    dop = dop[dop["can_id"] == 0x130]
    assert not np.any((dop["t_ns"] >= 40e9) & (dop["t_ns"] < 50e9))


def test_replay_reproduces_the_traffic_frame_for_frame(tmp_path):
    orig = run(_spec(tmp_path / "o.mcap", seed=2)).path
    dut = DutSpec("in_process", name="dead_reckoning", config=DR)
    res = execute(RecordingReplay(orig, lockstep=True), dut, LinkSpec(), ClockSpec(), tmp_path / "r.mcap")
    assert res.ok, res.reason
    a, b = RecordingReader(orig), RecordingReader(res.path)
    assert np.array_equal(a.read_columnar("/wire/can/tx"), b.read_columnar("/wire/can/tx"))
    for t in ("/wire/imu/tx", "/wire/gnss/tx"):
        assert all(np.array_equal(x, y) for x, y in zip(a.read_chunks(t), b.read_chunks(t), strict=True))
    assert np.array_equal(_nav(orig), _nav(res.path))
    assert np.array_equal(a.read_columnar("/truth"), b.read_columnar("/truth"))
    # seek: the same frames from 30 s on, in the replay's own bench time (0 at the seek point)
    res = execute(RecordingReplay(orig, lockstep=True, start_ns=30_000_000_000), dut, LinkSpec(), ClockSpec(),
                  tmp_path / "s.mcap")
    x, y = RecordingReader(res.path).read_columnar("/wire/can/tx"), a.read_columnar("/wire/can/tx")
    y = y[y["t_ns"] >= 30_000_000_000]
    assert res.ok and np.array_equal(x["t_ns"], y["t_ns"] - 30_000_000_000)
    same = ~np.isin(x["can_id"], (0x010, 0x011))  # BENCH_TIME and BENCH_EPOCH carry the moved times
    assert np.array_equal(x[same][["can_id", "data"]], y[same][["can_id", "data"]])


def test_replay_with_other_wire_faults_re_encodes_the_samples(tmp_path):
    load_fault_kinds()
    orig = run(_spec(tmp_path / "o.mcap", seed=2)).path
    sched = parse_schedule([{"layer": "wire", "target": "can:ODOMETER", "kind": "drop", "start": "10 s",
                             "end": "12 s"}])
    dut = DutSpec("in_process", name="dead_reckoning", config=DR)
    res = execute(RecordingReplay(orig, lockstep=True, faults=sched), dut, LinkSpec(), ClockSpec(),
                  tmp_path / "r.mcap")
    assert res.ok, res.reason
    a, b = RecordingReader(orig).read_columnar("/wire/can/tx"), RecordingReader(res.path).read_columnar("/wire/can/tx")
    odo_a, odo_b = a[a["can_id"] == 0x120], b[b["can_id"] == 0x120]
    assert len(odo_a) - len(odo_b) == 200
    keep = (odo_a["t_ns"] < 10e9) | (odo_a["t_ns"] >= 12e9)
    assert np.array_equal(odo_a[keep]["t_ns"], odo_b["t_ns"])
    assert [d["kind"] for _, d in RecordingReader(res.path).iter_json("/faults")] == ["drop"]


def test_real_time_run_measures_lateness_and_enforces_its_budget(tmp_path):
    res = run(_spec(tmp_path / "rt.mcap", clock=ClockSpec(mode="realtime", speed=2.0), duration_s=8.0))
    assert res.ok, res.reason
    r = RecordingReader(res.path)
    timing = r.read_columnar("/bench/timing")
    # every step paced and recorded, in order, with the lateness measured (not assumed 0)
    assert np.array_equal(timing["t_ns"], np.arange(801) * 10_000_000)
    assert np.all(timing["lateness_ns"] >= 0) and np.any(timing["lateness_ns"] > 0)
    assert res.timing == TimingLog.summarize(timing["lateness_ns"])  # the summary is of what was recorded
    md = r.metadata()["timing_summary"]
    assert int(md["count"]) == 801 and float(md["max_ns"]) == float(timing["lateness_ns"].max())
    sol = r.read_columnar("/dut/nav_solution")
    assert np.array_equal(sol["t_ns"], timing["t_ns"])  # the DUT stepped at every paced time
    # a budget no run can meet (1 ns) ends it as a timing ERROR, whatever this machine's speed
    late = run(_spec(tmp_path / "late.mcap", duration_s=2.0,
                     clock=ClockSpec(mode="realtime", speed=8.0, budget=TimingBudget(p99_ns=1, max_ns=1))))
    assert late.status == "timing_budget" and "budget missed" in late.reason
    assert RecordingReader(late.path).metadata()["run_end"]["status"] == "timing_budget"


def _external_cmd(ns: str, port: int) -> str:
    return (f"ip netns exec {ns} {sys.executable} -m bench.dut.harness --estimator dead_reckoning "
            f"--can-interface {{can_interface}} --can-channel {{can_channel}} --can-port {port} "
            "--imu {imu_port} --gnss {gnss_port} --config {config}")


def _external_dut(ns: str, port: int, config: dict) -> DutSpec:
    return DutSpec("external", command=_external_cmd(ns, port), config=config, startup_timeout_s=HANG_S,
                   shutdown_timeout_s=HANG_S)


def _external(tmp_path: Path, name: str, *, group: str, port: int, **kw):
    reason = netns.unavailable()
    if reason:
        pytest.skip(f"udp_multicast between processes needs a network namespace: {reason}")
    with netns.multicast_netns() as ns:
        spec = _spec(tmp_path / name, dut=_external_dut(ns, port, DR),
                     links=LinkSpec(can={"interface": "udp_multicast", "channel": group, "port": port}), **kw)
        return netns.call_in(ns, lambda: run(spec))


@pytest.mark.slow
def test_external_process_over_pty_and_can_equals_in_process(tmp_path):
    inproc = run(_spec(tmp_path / "in.mcap", seed=9, duration_s=30.0))
    ext = _external(tmp_path, "ext.mcap", group="239.74.163.41", port=43341, seed=9, duration_s=30.0,
                    clock=ClockSpec(step_ns=100_000_000, timeout_s=HANG_S))
    assert inproc.ok and ext.ok, ext.reason
    assert _same_traffic(_sensor_traffic(inproc.path), _sensor_traffic(ext.path))
    assert np.array_equal(_nav(inproc.path), _nav(ext.path))  # the same estimator, bit for bit
    r = RecordingReader(ext.path)
    assert ext.dut_exit["exit_code"] == 0 and ext.dut_exit["terminated_in_time"]
    assert any("listening" in d["text"] for _, d in r.iter_json("/dut/log"))
    assert r.metadata()["dut_output"]["bad_frames"] == "{}"


@pytest.mark.slow
def test_external_process_in_real_time(tmp_path):
    ext = _external(tmp_path, "rt.mcap", group="239.74.163.42", port=43342, seed=9, duration_s=5.0,
                    clock=ClockSpec(mode="realtime", speed=1.0))
    assert ext.ok, ext.reason
    r = RecordingReader(ext.path)
    timing = r.read_columnar("/bench/timing")
    assert ext.timing == TimingLog.summarize(timing["lateness_ns"]) and ext.timing.count > 1000  # every emission
    assert np.all(np.diff(timing["t_ns"]) > 0) and np.all(timing["lateness_ns"] >= 0)
    sol = r.read_columnar("/dut/nav_solution")
    # the DUT answered the BENCH_TIMEs as they came: in order, none missing up to its last
    # answer, none before its time (no bound on how late: a loaded machine is slower)
    assert len(sol) > 100, "the DUT hardly answered: it hangs?"
    assert np.array_equal(sol["t_ns"], sol["t_ns"][0] + np.arange(len(sol)) * 10_000_000)
    assert np.all(sol["rx_ns"] >= sol["t_ns"])
    assert r.metadata()["dut_output"]["bad_frames"] == "{}"
    assert len(r.read_columnar("/wire/can/rx")) == len(sol) + len(r.read_columnar("/dut/nav_quality"))


@pytest.mark.slow
def test_s000_end_to_end_in_process_and_as_an_external_process(tmp_path):
    """The first 900 s of the S000 drive (alignment, the start and the first turns) in
    lockstep with the dead-reckoning DUT in process and the same DUT as an external process
    over pty + CAN: identical sensor payloads (the two runs are also two runs of one seed),
    and the same navigation output bit for bit. (The whole 3600 s drive runs in the main
    job, `make demo`.)"""
    reason = netns.unavailable()
    if reason:
        pytest.skip(f"udp_multicast between processes needs a network namespace: {reason}")
    sc = load_scenario("S000")
    traj = sc.trajectory()
    cfg = {"initial_position": [34 + 14.763 / 60, 108 + 54.579 / 60, 380.0], "alignment": "250 s"}

    def spec(out: Path, dut: DutSpec, **kw) -> RunSpec:
        return RunSpec(scenario=sc, tables=sc.doc, schedule=FaultSchedule(), dut=dut, out=out, seed=4,
                       trajectory=traj, duration_ns=900_000_000_000, **kw)

    inproc = run(spec(tmp_path / "in.mcap", DutSpec("in_process", name="dead_reckoning", config=cfg)))
    with netns.multicast_netns() as ns:
        ext_spec = spec(tmp_path / "ext.mcap", _external_dut(ns, 43343, cfg),
                        links=LinkSpec(can={"interface": "udp_multicast", "channel": "239.74.163.43", "port": 43343}),
                        clock=ClockSpec(step_ns=1_000_000_000, timeout_s=HANG_S))
        ext = netns.call_in(ns, lambda: run(ext_spec))
    assert inproc.ok and ext.ok, ext.reason
    assert inproc.bench_s == ext.bench_s == 900.0
    a, b = _sensor_traffic(inproc.path), _sensor_traffic(ext.path)
    assert len(a["can"]) == 45_901 and len(a["imu"][0]) == 180_000  # Doppler 50 Hz + BENCH_EPOCH; IMU 200 Hz
    assert _same_traffic(a, b)
    nav_a, nav_b = _nav(inproc.path), _nav(ext.path)
    assert len(nav_a) == 90_001 and np.array_equal(nav_a, nav_b)


@pytest.mark.slow
def test_an_fmu_driven_run_records_the_plant_and_the_icd(tmp_path):
    sc = load_scenario("S002")
    res = run(RunSpec(scenario=sc, tables=sc.doc, schedule=FaultSchedule(), out=tmp_path / "s002.mcap",
                      dut=DutSpec("in_process", name="decode_only"), duration_ns=30_000_000_000))
    assert res.ok, res.reason
    r = RecordingReader(res.path)
    plant = r.metadata()["plant"]
    assert len(plant["fmu_sha256"]) == 64 and plant["model"] == "TrackedVehicle"
    assert "models/can/icd_1_0.dbc" in r.attachments()
    can = r.read_columnar("/wire/can/tx")
    assert np.count_nonzero(can["can_id"] == 0x120) == 3000 and np.count_nonzero(can["can_id"] == 0x121) > 0
