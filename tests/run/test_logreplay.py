"""Replay of field logs: a bench run's traffic exported as a vehicle logger would keep it
(CAN as ASC and BLF, the serial lines as raw byte files), replayed into the same DUT.

The source run (tests/run/data/logreplay_drive.toml) has every ICD input and wire faults
that leave garbage in both byte streams and a counter skip on the bus, so the logs are
not clean; the replay must reproduce its traffic frame for frame and the DUT's output
bit for bit.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from bench.acceptance.case import load_case
from bench.cli.app import run as cli
from bench.errors import ConfigError
from bench.faults.schedule import parse_schedule
from bench.frames import CanBatch, SerialBatch
from bench.nav import earth
from bench.record.mcap_io import RecordingReader, RecordingWriter
from bench.record.wire_topics import CAN_RX, CAN_TX, SERIAL_TX, read_can, read_serial
from bench.run.bytelogs import imu_log_chunks
from bench.run.case_runner import spec_from_case
from bench.run.engine import execute, run
from bench.run.logreplay import FieldLogs, LogReplay, TruthTrack
from bench.run.spec import ClockSpec, DutSpec, LinkSpec
from bench.run.traffic import BENCH_TIME_ID
from bench.scoring.align import nav_errors
from bench.scoring.data import load_run
from bench.sensors.suite import load_fault_kinds
from bench.transport.export import export_can_log
from bench.wire.can import CanEncoder, codec
from bench.wire.imu import FRAME_SIZE, check_frames, decode_frames

HERE = Path(__file__).parent
CASE = HERE / "data" / "logreplay_drive.toml"
BERLIN = HERE.parent / "data" / "smartloc_berlin_potsdamer_platz_gt.txt"
DR = {"initial_position": [34.246, 108.909, 380.0], "alignment": "4 s"}
DUT = DutSpec("in_process", name="dead_reckoning", config=DR)
LATENCY_NS = 80_000_000  # the source run's receiver latency
BENCH_IDS = [codec(n).frame_id for n in ("BENCH_TIME", "BENCH_EPOCH")]


@dataclass
class Drive:
    """The source run and its traffic exported as field logs."""

    recording: Path
    epoch_ns: int
    tx: CanBatch
    imu: SerialBatch
    gnss: SerialBatch
    dir: Path

    def logs(self, can: str = "drive.asc", **kw) -> FieldLogs:
        kw.setdefault("gnss_latency_ns", LATENCY_NS)
        return FieldLogs(can=self.dir / can, imu=self.dir / "imu.bin", gnss=self.dir / "gnss.nmea", **kw)


@pytest.fixture(scope="module")
def drive(tmp_path_factory) -> Drive:
    d = tmp_path_factory.mktemp("logreplay")
    spec = spec_from_case(load_case(CASE), 5, d)
    result = run(spec)
    assert result.ok, result.reason
    r = RecordingReader(result.path)
    epoch = int(r.metadata()["run_start"]["epoch_utc_ns"])
    tx, rx = read_can(r, CAN_TX), read_can(r, CAN_RX)
    for suffix in ("asc", "blf"):
        export_can_log(d / f"drive.{suffix}", tx, rx, start_utc_ns=epoch)
    # a vehicle's log: the sensor messages only, no BENCH_* frames, no DUT
    export_can_log(d / "field.asc", tx.take(~np.isin(tx.can_id, BENCH_IDS)), start_utc_ns=epoch)
    imu, gnss = read_serial(r, SERIAL_TX["imu"]), read_serial(r, SERIAL_TX["gnss"])
    (d / "imu.bin").write_bytes(imu.tobytes())
    (d / "gnss.nmea").write_bytes(gnss.tobytes())
    return Drive(result.path, epoch, tx, imu, gnss, d)


def _replay(provider: LogReplay, out: Path, clock: ClockSpec | None = None) -> RecordingReader:
    result = execute(provider, DUT, LinkSpec(), clock or ClockSpec(), out)
    assert result.ok, result.reason
    return RecordingReader(out)


def _byte_times(b: SerialBatch) -> np.ndarray:
    return np.repeat(b.t_ns, b.lengths)


def _same_serial(orig: SerialBatch, new: SerialBatch, *, frame: np.ndarray) -> None:
    """Identical bytes; each byte of a frame (``frame``: per original chunk) at its original
    time, other bytes (garbage) with the frame that follows them, within 100 ms."""
    assert new.tobytes() == orig.tobytes()
    t0, t1 = _byte_times(orig), _byte_times(new)
    in_frame = np.repeat(frame, orig.lengths)
    assert np.array_equal(t1[in_frame], t0[in_frame])
    late = t1[~in_frame] - t0[~in_frame]
    assert late.size == 0 or (late.min() >= 0 and late.max() <= 100_000_000)


def _traffic(provider: LogReplay, path: Path):
    """All the traffic of a provider in one window (no DUT)."""
    with RecordingWriter(path, epoch_ns=provider.epoch_ns) as rec:
        provider.declare(rec)
        return provider.window(rec, provider.start_ns, provider.duration_ns)


# ---------------------------------------------------------------------------- frame for frame
@pytest.mark.parametrize("log", ["drive.asc", "drive.blf"])
def test_replay_reproduces_the_run_frame_for_frame(drive, tmp_path, log):
    provider = LogReplay(drive.logs(log), lockstep=True)
    assert provider.epoch_ns == drive.epoch_ns and provider.duration_ns == 90_000_000_000
    r2 = _replay(provider, tmp_path / "replay.mcap")
    r1 = RecordingReader(drive.recording)
    a, b = drive.tx, read_can(r2, CAN_TX)
    assert len(a) == len(b) == 27092
    assert np.array_equal(a.can_id, b.can_id) and np.array_equal(a.length, b.length)
    assert np.array_equal(a.data, b.data)
    assert np.abs(a.t_ns - b.t_ns).max() <= 1000  # the logs' resolution: 1 us
    _same_serial(drive.imu, read_serial(r2, SERIAL_TX["imu"]), frame=drive.imu.lengths == FRAME_SIZE)
    gnss_frames = drive.gnss.buf[drive.gnss.offsets[:-1]] == ord("$")
    _same_serial(drive.gnss, read_serial(r2, SERIAL_TX["gnss"]), frame=gnss_frames)
    for topic in ("/dut/nav_solution", "/dut/nav_quality"):
        assert np.array_equal(r1.read_columnar(topic), r2.read_columnar(topic))
    assert r2.metadata()["dut_input_tally"] == r1.metadata()["dut_input_tally"]  # same garbage, same skip
    start = r2.metadata()["run_start"]
    assert start["replay_mode"] == "field logs" and start["bench_frames"] == "logged"
    assert start["epoch_source"] == "BENCH_EPOCH frames of the CAN log"
    assert start["truth"].startswith("none")
    assert load_run(r2.path).truth is None


def test_field_log_without_bench_frames_gets_them_generated(drive, tmp_path):
    """A vehicle's log has no BENCH_TIME or BENCH_EPOCH: the replay makes them, and with the
    right placement the bus carries exactly what the bench sent."""
    first = int(drive.tx.t_ns[~np.isin(drive.tx.can_id, BENCH_IDS)][0])
    provider = LogReplay(drive.logs("field.asc", epoch_ns=drive.epoch_ns, can_offset_ns=first), lockstep=True)
    r2 = _replay(provider, tmp_path / "field.mcap")
    b = read_can(r2, CAN_TX)
    a, b = drive.tx.take(np.lexsort((drive.tx.can_id, drive.tx.t_ns))), b.take(np.lexsort((b.can_id, b.t_ns)))
    assert np.array_equal(a.t_ns, b.t_ns) and np.array_equal(a.data, b.data)  # frames of a time in ID order
    values, status = codec("BENCH_TIME").decode(b.take(b.can_id == BENCH_TIME_ID))
    assert np.all(status == 0) and np.all(values["lockstep"] == 1)
    assert np.array_equal(np.diff(values["time_ns"]), np.full(9000, 10_000_000))
    r1 = RecordingReader(drive.recording)
    assert np.array_equal(r1.read_columnar("/dut/nav_solution"), r2.read_columnar("/dut/nav_solution"))
    start = r2.metadata()["run_start"]
    assert start["bench_frames"] == "generated BENCH_EPOCH, BENCH_TIME"
    assert start["epoch_source"] == "given (--epoch)"


def test_field_log_defaults_first_frame_is_bench_zero_and_nmea_sets_the_epoch(drive, tmp_path):
    """No offset: the first frame is bench time zero. No epoch: the first NMEA epoch is placed
    at the CAN log's first frame."""
    provider = LogReplay(drive.logs("field.asc"), lockstep=True)
    sensors = drive.tx.take(~np.isin(drive.tx.can_id, BENCH_IDS))
    traffic = _traffic(provider, tmp_path / "t.mcap")
    can = traffic.can.take(~np.isin(traffic.can.can_id, BENCH_IDS))
    assert np.array_equal(can.t_ns, sensors.t_ns - sensors.t_ns[0]) and np.array_equal(can.data, sensors.data)
    first_nmea_utc = drive.epoch_ns + int(drive.gnss.t_ns[0]) - LATENCY_NS
    assert provider.epoch_ns == first_nmea_utc  # measurement of the first fix at bench time 0
    assert provider.epoch_source.startswith("first NMEA epoch placed at the CAN log's first frame")
    assert traffic.gnss.t_ns[0] == LATENCY_NS
    ep, status = codec("BENCH_EPOCH").decode(traffic.can.take(traffic.can.can_id == BENCH_IDS[1]))
    assert np.all(status == 0) and np.all(ep["epoch_utc_ns"] == first_nmea_utc)
    assert traffic.imu.tobytes() == drive.imu.tobytes()  # IMU frames keep their own times


# ---------------------------------------------------------------------------- seeking, clocks, faults
def test_seek_replays_from_the_start_time(drive, tmp_path):
    provider = LogReplay(drive.logs(), lockstep=True, start_ns=30_000_000_000)
    r2 = _replay(provider, tmp_path / "seek.mcap")
    b = read_can(r2, CAN_TX)
    tail = drive.tx.take(drive.tx.t_ns >= 30_000_000_000)
    assert np.array_equal(b.t_ns, tail.t_ns) and np.array_equal(b.data, tail.data)
    imu = read_serial(r2, SERIAL_TX["imu"])
    assert imu.t_ns[0] == 30_000_000_000 and np.all(decode_frames(imu.buf[-42:])[0]["t_ns"] == 90_000_000_000)
    assert read_serial(r2, SERIAL_TX["gnss"]).t_ns[0] == 30_000_000_000 + LATENCY_NS


def test_real_time_scaled_replay_clears_the_lockstep_bit(drive, tmp_path):
    """Real time at 40x from 86 s: the logged BENCH_TIME frames go out with the lockstep bit
    cleared, their time and alive counter kept; every other frame as logged."""
    provider = LogReplay(drive.logs("drive.blf"), lockstep=False, start_ns=86_000_000_000)
    r2 = _replay(provider, tmp_path / "rt.mcap", ClockSpec(mode="realtime", speed=40.0))
    b = read_can(r2, CAN_TX)
    a = drive.tx.take(drive.tx.t_ns >= 86_000_000_000)
    assert np.array_equal(a.t_ns, b.t_ns)
    c = codec("BENCH_TIME")
    bt = a.can_id == BENCH_TIME_ID
    va, _ = c.decode(a.take(bt))
    vb, sb = c.decode(b.take(bt))
    assert np.all(sb == 0) and np.all(vb["lockstep"] == 0) and np.all(va["lockstep"] == 1)
    assert np.array_equal(va["time_ns"], vb["time_ns"]) and np.array_equal(va["alive"], vb["alive"])
    assert np.array_equal(a.data[~bt], b.data[~bt])
    assert len(r2.read_columnar("/dut/nav_solution")) > 300


def test_wire_faults_apply_to_the_logged_traffic(drive, tmp_path):
    load_fault_kinds()
    faults = parse_schedule(
        [{"layer": "wire", "target": "can:DOPPLER", "kind": "drop", "start": "40 s", "end": "41 s"},
         {"layer": "wire", "target": "serial:imu", "kind": "corrupt_crc", "start": "60 s", "end": "60.05 s"}],
        file="faults")
    provider = LogReplay(drive.logs(), lockstep=True, faults=faults, seed=9)
    r2 = _replay(provider, tmp_path / "faults.mcap")
    b = read_can(r2, CAN_TX)
    doppler = b.t_ns[b.can_id == codec("DOPPLER").frame_id]
    assert not np.any((doppler >= 40_000_000_000) & (doppler < 41_000_000_000))
    assert np.count_nonzero(drive.tx.can_id == codec("DOPPLER").frame_id) - doppler.size == 50
    events = r2.read_columnar("/faults/wire")
    assert np.count_nonzero(events["fault_id"] == 0) == 50 and np.count_nonzero(events["fault_id"] == 1) == 10
    assert [d["kind"] for _, d in r2.iter_json("/faults")] == ["drop", "corrupt_crc"]
    imu = read_serial(r2, SERIAL_TX["imu"])
    frames = imu.buf[imu.offsets[:-1][imu.lengths == FRAME_SIZE][:, None] + np.arange(FRAME_SIZE)]
    assert np.count_nonzero(check_frames(frames) == 3) == 10  # ten bad CRCs
    assert r2.metadata()["dut_input_tally"]["crc"] == "10"
    sensor = parse_schedule([{"target": "doppler", "kind": "dropout", "start": "1 s", "end": "2 s"}], file="f")
    with pytest.raises(ConfigError, match="acts on a sensor"):
        LogReplay(drive.logs(), lockstep=True, faults=sensor)


# ---------------------------------------------------------------------------- truth
def test_smartloc_ground_truth_makes_the_replay_scoreable(drive, tmp_path):
    provider = LogReplay(drive.logs(), lockstep=True, truth=TruthTrack(BERLIN, format="smartloc"))
    r2 = _replay(provider, tmp_path / "berlin.mcap")
    run_data = load_run(r2.path)
    tr = run_data.require_truth()
    assert len(tr) == 9001 and tr["t_ns"][0] == 0 and tr["t_ns"][-1] == 90_000_000_000
    assert np.all(np.diff(tr["t_ns"]) == 10_000_000)
    first = np.loadtxt(BERLIN, usecols=(1, 2, 3, 4))[0]
    x0 = earth.geodetic_to_ecef(tr["lat"][:1], tr["lon"][:1], tr["h"][:1])[0]
    assert first[0] == 0.0 and np.linalg.norm(x0 - first[1:]) < 1e-3  # the track's first point at bench 0
    assert abs(math.degrees(tr["lat"][0]) - 52.51) < 0.02 and np.linalg.norm(tr["vel_n"], axis=1).max() < 30
    err = nav_errors(tr, run_data.require_nav())
    assert err.covered.all()
    assert np.hypot(err.pos[:, 0], err.pos[:, 1]).min() > 5e6  # a Xi'an drive judged against Berlin truth
    assert run_data.run_start["truth"].startswith(str(BERLIN))
    seg = run_data.segments
    assert len(seg) == 1 and seg[0]["start_s"] == 0 and seg[0]["end_s"] == pytest.approx(provider.truth.end_ns / 1e9)
    assert 280 < seg[0]["end_s"] < 290  # the whole Berlin track (283 s), in bench time


def test_truth_offset_places_the_track(drive, tmp_path):
    """``offset = -100 s``: bench time 0 is the track's 100th second."""
    truth = TruthTrack(BERLIN, offset_ns=-100_000_000_000)
    provider = LogReplay(drive.logs(), lockstep=True, truth=truth)
    path = tmp_path / "off.mcap"
    _traffic(provider, path)
    tr = RecordingReader(path).read_columnar("/truth")
    k = provider.truth.traj.kinematics(np.array([100.0]))
    assert tr["t_ns"][0] == 0 and tr["lat"][0] == pytest.approx(k.lat[0], abs=1e-12)
    with pytest.raises(ConfigError, match="do not overlap"):
        LogReplay(drive.logs(), lockstep=True, truth=TruthTrack(BERLIN, offset_ns=-400_000_000_000))


def test_csv_truth_of_the_drive_scores_the_replay_like_the_original(drive, tmp_path):
    r1 = RecordingReader(drive.recording)
    truth = r1.read_columnar("/truth")
    path = tmp_path / "truth.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "lat", "lon", "h", "heading", "pitch", "roll"])
        for row in truth:
            w.writerow([f"{row['t_ns'] / 1e9:.3f}", *(f"{math.degrees(row[k]):.12f}" for k in ("lat", "lon")),
                        f"{row['h']:.6f}", *(f"{math.degrees(v):.10f}" for v in row["euler"])])
    r2 = _replay(LogReplay(drive.logs(), lockstep=True, truth=TruthTrack(path, format="csv")), tmp_path / "c.mcap")
    one, two = load_run(drive.recording), load_run(r2.path)
    e1 = nav_errors(one.require_truth(), one.require_nav())
    e2 = nav_errors(two.require_truth(), two.require_nav())
    assert np.array_equal(e1.usable, e2.usable)
    h1, h2 = np.hypot(*e1.pos[:, :2].T), np.hypot(*e2.pos[:, :2].T)
    assert np.abs(h1 - h2).max() < 1e-3 and h1.max() > 0.1
    assert np.abs(e1.att - e2.att).max() < 1e-6


def _canoe_asc(path: Path) -> CanBatch:
    """A CANoe-style ASC: ODOMETER on channel 1, another ECU's 0x3A5 on channel 2, an error
    frame and a NAV_SOLUTION-ID frame; returns the ODOMETER frames."""
    odo = CanEncoder().encode("ODOMETER", np.array([0, 10_000_000, 20_000_000]), pulse_count=np.array([1, 2, 3]),
                              speed=np.full(3, 1.0), reverse=0, valid=1)
    lines = ["date Sun Mar 1 09:00:00.000 am 2026", "base hex  timestamps absolute", "internal events logged",
             "// version 13.0.0", "Begin Triggerblock Sun Mar 1 09:00:00.000 am 2026",
             "   0.000000 Start of measurement"]
    for i, t in enumerate((0.51234, 0.52234, 0.53234)):
        payload = " ".join(f"{x:02X}" for x in odo.data[i])
        lines.append(f"   {t:.6f} 1  120             Rx   d 8 {payload}  Length = 240000 BitCount = 124 ID = 288")
        lines.append(f"   {t + 0.0003:.6f} 2  3A5             Rx   d 4 11 22 33 44  Length = 140000 BitCount = 74")
    lines += ["   0.540000 1  ErrorFrame", "   0.550000 1  300             Rx   d 8 00 00 00 00 00 00 00 00",
              "End TriggerBlock"]
    path.write_text("\n".join(lines) + "\n")
    return odo


def test_canoe_asc_with_other_traffic_and_channels(tmp_path):
    asc = tmp_path / "canoe.asc"
    odo = _canoe_asc(asc)
    epoch = {"epoch_ns": 1_772_355_600_000_000_000}
    icd = _traffic(LogReplay(FieldLogs(can=asc, **epoch), lockstep=True), tmp_path / "a.mcap").can
    sent = icd.take(icd.can_id == 0x120)
    assert np.array_equal(sent.t_ns, odo.t_ns) and np.array_equal(sent.data, odo.data)  # first frame at zero
    assert set(np.unique(icd.can_id).tolist()) == {0x010, 0x011, 0x120}
    provider = LogReplay(FieldLogs(can=asc, can_ids="all", **epoch), lockstep=True)
    other = _traffic(provider, tmp_path / "b.mcap").can
    ecu = other.take(other.can_id == 0x3A5)
    assert np.array_equal(ecu.t_ns, odo.t_ns + 300_000) and np.all(ecu.length == 4)
    assert not np.any(other.can_id == 0x300)  # the DUT's identifiers are never re-emitted
    assert provider.facts["can"]["skipped"] == {"error_frame": 1} and provider.facts["can"]["left_out"] == 1
    only2 = _traffic(LogReplay(FieldLogs(can=asc, can_ids="all", can_channel=2, **epoch), lockstep=True),
                     tmp_path / "c.mcap").can
    assert set(np.unique(only2.can_id).tolist()) == {0x010, 0x011, 0x3A5} and only2.t_ns[only2.can_id == 0x3A5][0] == 0
    with pytest.raises(ConfigError, match="no frame on channel 3; the log has channels 1, 2"):
        LogReplay(FieldLogs(can=asc, can_channel=3), lockstep=True)


# ---------------------------------------------------------------------------- byte logs
def test_imu_shift_restamps_the_frames(drive, tmp_path):
    batch, info = imu_log_chunks(drive.imu.tobytes(), file="imu.bin", shift_ns=1_000_000_000)
    assert info["frames"] == 18000 and info["garbage_bytes"] == drive.imu.buf.size - 18000 * FRAME_SIZE
    starts = batch.offsets[1:] - FRAME_SIZE
    frames = batch.buf[starts[:, None] + np.arange(FRAME_SIZE)]
    assert np.all(check_frames(frames) == 0)
    new, _ = decode_frames(frames)
    old, _ = decode_frames(drive.imu.buf[drive.imu.offsets[:-1][drive.imu.lengths == 42][:, None] + np.arange(42)])
    assert np.array_equal(new["t_ns"], old["t_ns"] + 1_000_000_000) and np.array_equal(batch.t_ns, new["t_ns"])
    assert np.array_equal(new["dtheta"], old["dtheta"]) and np.array_equal(new["counter"], old["counter"])
    back, info = imu_log_chunks(drive.imu.tobytes(), file="imu.bin", shift_ns=-20_000_000_000)
    assert info["dropped_before_zero"] == 20 * 200 - 1 and back.t_ns[0] == 0


# ---------------------------------------------------------------------------- missing and foreign logs
def test_missing_and_foreign_logs(drive, tmp_path):
    with pytest.raises(ConfigError, match="not found") as err:
        LogReplay(FieldLogs(can=tmp_path / "none.blf"), lockstep=True)
    assert "none.blf" in str(err.value)
    with pytest.raises(ConfigError, match="at least one log"):
        LogReplay(FieldLogs(), lockstep=True)
    nav = tmp_path / "nav.asc"  # the DUT's frames only: nothing to re-emit
    r = RecordingReader(drive.recording)
    export_can_log(nav, rx=read_can(r, CAN_RX).take(np.arange(100)), start_utc_ns=drive.epoch_ns)
    with pytest.raises(ConfigError, match=r"none of the 100 frames.*0x300") as err:
        LogReplay(FieldLogs(can=nav), lockstep=True)
    assert str(nav) in str(err.value)
    with pytest.raises(ConfigError, match="BENCH_TIME frames, which fix"):
        LogReplay(drive.logs(can_offset_ns=0), lockstep=True)
    with pytest.raises(ConfigError, match="BENCH_EPOCH says"):
        LogReplay(drive.logs(epoch_ns=drive.epoch_ns + 3_600_000_000_000), lockstep=True)


# ---------------------------------------------------------------------------- command line
def test_cli_replays_field_logs_and_recordings(drive, tmp_path):
    cfg = tmp_path / "dr.toml"
    cfg.write_text('initial_position = [34.246, 108.909, 380.0]\nalignment = "4 s"\n')
    out = tmp_path / "cli.mcap"
    d = drive.dir
    argv = ["replay", "--can-log", str(d / "field.asc"), "--imu-log", str(d / "imu.bin"), "--gnss-log",
            str(d / "gnss.nmea"), "--gnss-latency", "80 ms", "--epoch", "2026-03-01T08:00:00Z", "--can-offset",
            "10 ms", "--truth", str(BERLIN), "--estimator", "dead_reckoning", "--dut-config", str(cfg), "-q",
            "-o", str(out)]
    assert cli(argv) == 0
    r1, r2 = RecordingReader(drive.recording), RecordingReader(out)
    assert np.array_equal(r1.read_columnar("/dut/nav_solution"), r2.read_columnar("/dut/nav_solution"))
    assert len(r2.read_columnar("/truth")) == 9001
    assert cli(["replay", str(drive.recording), "--estimator", "dead_reckoning", "--dut-config", str(cfg), "-q",
                "-o", str(tmp_path / "rec.mcap")]) == 0
    assert cli(["replay", str(drive.recording), "--can-log", str(d / "field.asc"), "--estimator",
                "dead_reckoning", "-o", str(tmp_path / "x.mcap")]) == 2
    assert cli(["replay", "--imu-log", str(d / "gnss.nmea"), "--estimator", "dead_reckoning", "-o",
                str(tmp_path / "y.mcap")]) == 2
