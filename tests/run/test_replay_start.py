"""`bench replay --start S`: the replay is a run of its own whose bench time starts at S.

The dead-reckoning DUT used to be stepped from 0 s: it emitted every epoch from 0 at its
first step (as many output epochs as the whole drive against the truth after S) and its
coarse alignment took the seek as time at rest, so it failed by hundreds of metres. Now it
sees bench time 0 at the seek point, aligns there and navigates.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from bench.cli import main
from bench.record.mcap_io import RecordingReader
from bench.wire.can import codec

CASE = Path(__file__).parent / "data" / "two_stops_dr.toml"
SEEK_S = 40  # the drive rests from 38 s to 48 s


@pytest.fixture(scope="module")
def drive(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("two_stops")
    assert main(["run", str(CASE), "-o", str(out), "-q", "--no-plots"]) == 0
    return out / "recordings" / "TWO-STOPS-DR" / "TWO-STOPS-DR-s3.mcap"


def test_the_dead_reckoning_dut_aligns_at_the_seek_point_and_passes(drive, tmp_path):
    truth = RecordingReader(drive).read_columnar("/truth")
    at = truth[np.searchsorted(truth["t_ns"], SEEK_S * 10**9)]
    cfg = tmp_path / "dr.json"  # the DUT's surveyed start point is where the replay starts
    cfg.write_text(json.dumps({"initial_position": [float(np.degrees(at["lat"])), float(np.degrees(at["lon"])),
                                                    float(at["h"])], "alignment": "4 s"}))
    out = tmp_path / "seek.mcap"
    assert main(["replay", str(drive), "--estimator", "dead_reckoning", "--dut-config", str(cfg), "--start",
                 str(SEEK_S), "-q", "-o", str(out)]) == 0
    r = RecordingReader(out)
    nav, tr = r.read_columnar("/dut/nav_solution"), r.read_columnar("/truth")
    assert tr["t_ns"][0] == 0 and tr["t_ns"][-1] == (80 - SEEK_S) * 10**9
    assert len(nav) == len(tr) == (80 - SEEK_S) * 100 + 1  # one epoch per truth sample, not 8001 against 4001
    assert nav["t_ns"][0] == 0 and np.all(nav["mode"][nav["t_ns"] < 4e9] == 0)  # aligning for 4 s
    start = r.metadata()["run_start"]
    assert start["replay_start_s"] == str(SEEK_S) and start["duration_s"] == str(80 - SEEK_S)
    src_epoch = int(RecordingReader(drive).metadata()["run_start"]["epoch_utc_ns"])
    assert int(start["epoch_utc_ns"]) == src_epoch + SEEK_S * 10**9
    js = tmp_path / "r.json"
    assert main(["score", str(out), "--case", str(CASE), "--json", str(js)]) == 0
    (crit,) = [c for c in json.loads(js.read_text())["cases"][0]["criteria"] if c["id"] == "c1"]
    assert crit["verdict"] == "PASS" and crit["value"] < 1.0  # m, aligned at rest and dead-reckoned 32 s


def test_the_frames_are_moved_to_the_replays_bench_time(drive, tmp_path):
    out = tmp_path / "seek.mcap"
    assert main(["replay", str(drive), "--case", str(CASE), "--start", str(SEEK_S), "-q", "-o", str(out)]) == 0
    tx = RecordingReader(out).read_columnar("/wire/can/tx")
    bt = codec("BENCH_TIME")
    from bench.frames import CanBatch

    sel = tx[tx["can_id"] == bt.frame_id]
    values, status = bt.decode(CanBatch(sel["t_ns"], sel["can_id"], sel["data"]))
    assert np.all(status == 0) and np.array_equal(values["time_ns"], sel["t_ns"]) and sel["t_ns"][0] == 0
    imu = RecordingReader(out).read_chunks("/wire/imu/tx")
    buf = imu[2]
    first = buf[imu[1][0] : imu[1][0] + 42]
    assert first[0] == 0xAA and first[1] == 0x55
    t_us = int(np.frombuffer(first[4:12].tobytes(), "<u8")[0])
    assert abs(t_us * 1000 - imu[0][0]) <= 10_000_000 and imu[0][0] < 10_000_000  # moved by -S as well


@pytest.mark.parametrize(("start", "found"), [("40.005", "whole number of scheduler steps"),
                                              ("80", "past the end of the recording"),
                                              ("nan", "expected a bench time from 0 s on"),
                                              ("-1", "expected a bench time from 0 s on")])
def test_a_start_outside_the_recording_is_a_usage_error(drive, tmp_path, capsys, start, found):
    assert main(["replay", str(drive), "--case", str(CASE), "--start", start, "-q", "-o",
                 str(tmp_path / "x.mcap")]) == 2
    assert found in capsys.readouterr().err
    assert not (tmp_path / "x.mcap").exists()
