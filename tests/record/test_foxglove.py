"""The Foxglove views of a hand-made recording: a straight drive north or east, a DUT
whose invalid epochs say lat 0, lon 0 and whose NAV_QUALITY is missing for a second, a
fault window, a frame command and switch, two log lines. Every view decodes with
mcap_protobuf; invalid epochs are not on the map; the covariance is the NAV_QUALITY
sigmas squared; the pose arrows point along the drive; the plotted errors are scoring's."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.faults.schedule import FAULT_JSON_SCHEMA, FAULT_TOPIC, FaultWindow
from bench.nav import earth
from bench.nav.rotation import euler_to_quat
from bench.record.foxglove import COVARIANCE_DIAGONAL_KNOWN, COVARIANCE_KNOWN, COVARIANCE_UNKNOWN, LOG_LEVELS
from bench.record.mcap_io import RecordingWriter
from bench.scenario.records import TRUTH_TOPIC
from bench.scoring.accuracy import QUANTITIES
from bench.scoring.align import nav_errors
from bench.scoring.data import COMMANDS, load_run
from bench.scoring.views import derive_views
from bench.scoring.viewwrite import add_views
from bench.topics import NAV_QUALITY_TOPIC, NAV_SOLUTION_TOPIC
from tests.record.views_util import bench_ns, decode_views, rotate_x

EPOCH = 1_772_352_000 * 10**9
LAT0, LON0, H0 = math.radians(34.2), math.radians(108.9), 400.0
SPEED = 10.0
INVALID_EVERY = 7
NO_QUALITY = (5_000_000_000, 6_000_000_000)


def _drive(heading: float, n: int = 1001) -> np.ndarray:
    """Truth at 100 Hz of a straight drive at SPEED along ``heading``."""
    t = np.arange(n, dtype=np.int64) * 10_000_000
    v = SPEED * np.array([math.sin(heading), math.cos(heading), 0.0])
    enu = np.outer(t * 1e-9, v)
    xyz = earth.enu_to_ecef(enu, LAT0, LON0, H0)
    lat, lon, h = earth.ecef_to_geodetic(xyz)
    tr = np.zeros(n, TRUTH_TOPIC.dtype)
    tr["t_ns"], tr["lat"], tr["lon"], tr["h"] = t, lat, lon, h
    tr["vel_n"] = v
    tr["q_bn"] = euler_to_quat(heading, 0.0, 0.0)
    tr["euler"][:, 0] = heading
    return tr


def _record(path, heading: float) -> np.ndarray:
    truth = _drive(heading)
    n = len(truth)
    nav = np.zeros(n, NAV_SOLUTION_TOPIC.dtype)
    nav["t_ns"], nav["rx_ns"] = truth["t_ns"], truth["t_ns"] + 3_000_000
    nav["lat"], nav["lon"], nav["h"] = truth["lat"] + 1e-7, truth["lon"], truth["h"] + 0.5
    nav["vel_n"], nav["heading"] = truth["vel_n"], heading
    nav["valid"] = 1
    nav["epoch"] = np.arange(n) % 256
    bad = np.arange(n) % INVALID_EVERY == 3
    nav["valid"][bad] = 0
    nav["lat"][bad], nav["lon"][bad], nav["h"][bad] = 0.0, 0.0, 0.0
    nav["frame"][truth["t_ns"] >= 7_000_000_000] = 1
    q = np.zeros(n, NAV_QUALITY_TOPIC.dtype)
    q["t_ns"], q["rx_ns"] = nav["t_ns"], nav["rx_ns"]
    q["sigma_pos"] = [1.5, 2.0, 3.0]
    q["sigma_att"] = [1e-3, 2e-4, 2e-4]
    q["fault_detected"][(truth["t_ns"] >= 2_000_000_000) & (truth["t_ns"] < 4_000_000_000)] = 0b0010
    q = q[(q["t_ns"] < NO_QUALITY[0]) | (q["t_ns"] >= NO_QUALITY[1])]
    with RecordingWriter(path, epoch_ns=EPOCH) as rec:
        rec.metadata("run_start", {"kind": "test", "epoch_utc_ns": str(EPOCH)})
        for spec, records in ((TRUTH_TOPIC, truth), (NAV_SOLUTION_TOPIC, nav), (NAV_QUALITY_TOPIC, q)):
            rec.columnar_topic(spec.topic, spec.schema, spec.dtype)
            rec.write_block(spec.topic, records)
        rec.json_topic(FAULT_TOPIC, "bench.FaultWindow", FAULT_JSON_SCHEMA)
        w = FaultWindow(1, "sensor", "doppler", "outage", 2_000_000_000, 4_000_000_000)
        rec.write_json(FAULT_TOPIC, w.start_ns, w.to_json())
        rec.json_topic(COMMANDS, "bench.Command", {"type": "object"})
        rec.write_json(COMMANDS, 6_900_000_000, {"t_ns": 6_900_000_000, "command": "grid", "code": 1})
        rec.json_topic("/dut/log", "bench.DutLog", {"type": "object"})
        rec.write_json("/dut/log", 0, {"t_ns": 0, "stream": "stdout", "text": "hello"})
        rec.write_json("/dut/log", 100, {"t_ns": 100, "stream": "stderr", "text": "careful"})
        assert add_views(rec) > 0
    return nav


@pytest.fixture(scope="module")
def north(tmp_path_factory):
    path = tmp_path_factory.mktemp("fox") / "north.mcap"
    nav = _record(path, 0.0)
    return path, nav, decode_views(path)


def test_every_view_decodes_and_is_there(north):
    _, _, views = north
    assert set(views) == {
        "/foxglove/truth/location", "/foxglove/truth/pose", "/foxglove/tf/truth", "/foxglove/plot/truth",
        "/foxglove/dut/location", "/foxglove/dut/pose", "/foxglove/tf/dut", "/foxglove/plot/dut",
        "/foxglove/plot/errors", "/foxglove/plot/bench", "/foxglove/events", "/foxglove/dut/log",
    }
    assert len(views["/foxglove/truth/location"]) == 51  # 10 s at 5 Hz (half the display rate), both ends
    assert len(views["/foxglove/plot/truth"]) == 101  # at the display rate, 10 Hz
    for _, m in views["/foxglove/plot/truth"]:
        assert m.speed_mps == pytest.approx(SPEED)


def test_invalid_epochs_are_not_on_the_map_and_covariance_is_the_sigmas(north):
    _, nav, views = north
    valid_t = set(nav["t_ns"][nav["valid"] != 0].tolist())
    fixes = views["/foxglove/dut/location"]
    assert len(fixes) > 45  # 10 s at 5 Hz
    for log_time, fix in fixes:
        t = bench_ns(EPOCH, fix.timestamp)
        assert t == log_time - EPOCH and t in valid_t
        assert abs(fix.latitude) > 1 and abs(fix.longitude) > 1  # never 0, 0
        cov = np.array(fix.position_covariance).reshape(3, 3)
        if NO_QUALITY[0] <= t < NO_QUALITY[1]:
            assert fix.position_covariance_type == COVARIANCE_UNKNOWN and not cov.any()
        else:
            assert fix.position_covariance_type == COVARIANCE_DIAGONAL_KNOWN
            assert np.array_equal(cov, np.diag([1.5**2, 2.0**2, 3.0**2]))
    # the truth is exact: covariance zero, of type KNOWN
    for _, fix in views["/foxglove/truth/location"]:
        assert fix.position_covariance_type == COVARIANCE_KNOWN and not any(fix.position_covariance)
    # the dut plot keeps the invalid epochs, flagged
    assert {m.valid for _, m in views["/foxglove/plot/dut"]} == {0, 1}


@pytest.mark.parametrize(("heading_deg", "axis"), [(0.0, (0, 1, 0)), (90.0, (1, 0, 0)), (225.0, (-1, -1, 0))])
def test_pose_arrow_points_along_the_drive(tmp_path, heading_deg, axis):
    _record(tmp_path / "d.mcap", math.radians(heading_deg))
    views = decode_views(tmp_path / "d.mcap")
    want = np.array(axis, float) / np.linalg.norm(axis)
    for topic in ("/foxglove/truth/pose", "/foxglove/dut/pose"):
        for _, m in views[topic]:
            assert m.frame_id == "enu_start"
            x = rotate_x(m.pose.orientation)
            assert math.degrees(math.acos(min(1.0, float(x @ want)))) < 0.01, topic
    for topic, child in (("/foxglove/tf/truth", "truth_flu"), ("/foxglove/tf/dut", "dut_flu")):
        for _, m in views[topic]:
            assert (m.parent_frame_id, m.child_frame_id) == ("enu_start", child)
            assert math.degrees(math.acos(min(1.0, float(rotate_x(m.rotation) @ want)))) < 0.01
    # the positions move along the same axis in the ENU frame at the start point
    _, last = views["/foxglove/truth/pose"][-1]
    p = last.pose.position
    assert np.allclose([p.x, p.y, p.z], SPEED * 10.0 * want, atol=0.01)


def test_plotted_errors_are_the_scorings(north):
    path, _, views = north
    err = nav_errors(load_run(path).truth, load_run(path).nav)
    horizontal = dict(zip(err.t_ns.tolist(), QUANTITIES["horizontal"][2](err).tolist(), strict=True))
    heading = dict(zip(err.t_ns.tolist(), QUANTITIES["heading"][2](err).tolist(), strict=True))
    usable = set(err.t_ns[err.usable].tolist())
    plotted = views["/foxglove/plot/errors"]
    assert len(plotted) > 90  # 10 s at 10 Hz
    for log_time, m in plotted:
        t = log_time - EPOCH
        assert t in usable and m.t_s == t * 1e-9
        assert m.horizontal_m == horizontal[t] and m.horizontal_m > 0.5
        assert m.heading_arcmin == pytest.approx(math.degrees(heading[t]) * 60, abs=1e-12)


def test_flags_events_and_log(north):
    _, _, views = north
    dut = views["/foxglove/plot/dut"]
    doppler = {round(m.t_s, 3): m.fault_doppler for _, m in dut if m.has_quality}
    assert doppler[3.0] == 1 and doppler[1.0] == 0 and doppler[4.5] == 0
    bench = {round(m.t_s, 3): m for _, m in views["/foxglove/plot/bench"]}
    assert bench[2.5].faults_active == 1 and bench[4.0].faults_active == 0
    assert bench[6.0].commanded_frame == -1 and bench[7.0].commanded_frame == 1
    events = [(round(m.t_s, 3), m.kind, m.name, m.value) for _, m in views["/foxglove/events"]]
    assert events == [(2.0, "fault_start", "fault_1", 1.0), (4.0, "fault_end", "fault_1", 0.0),
                      (6.9, "command", "grid", 1.0), (7.0, "frame_switch", "grid", 1.0)]
    logs = [(m.level, m.name, m.message) for _, m in views["/foxglove/dut/log"]]
    assert logs == [(LOG_LEVELS["INFO"], "dut.stdout", "hello"), (LOG_LEVELS["WARNING"], "dut.stderr", "careful")]


def test_display_rate_is_bounded(north):
    run = load_run(north[0])
    for rate in (5.0, 60.0):
        with pytest.raises(ConfigError, match=r"display rate of 10\.\.50 Hz"):
            derive_views(run, rate_hz=rate)
    views = {v.topic: v for v in derive_views(run, rate_hz=50.0)}
    assert len(views["/foxglove/plot/truth"].content.t_ns) == 501
    assert len(views["/foxglove/truth/location"].content.t_ns) == 251


def _strings(node) -> list[str]:
    if isinstance(node, dict):
        return [s for k, v in node.items() for s in _strings(k) + _strings(v)]
    if isinstance(node, list):
        return [s for v in node for s in _strings(v)]
    return [node] if isinstance(node, str) else []


def test_the_shipped_layout_names_topics_and_fields_that_exist(north):
    _, _, views = north
    layout_file = Path(__file__).resolve().parents[2] / "docs" / "foxglove" / "bench_run_layout.json"
    layout = json.loads(layout_file.read_text())

    def panels(node) -> list[str]:
        return [node] if isinstance(node, str) else panels(node["first"]) + panels(node["second"])

    assert sorted(panels(layout["layout"])) == sorted(layout["configById"])
    named = [s for s in _strings(layout["configById"]) if s.startswith("/foxglove/")]
    assert len(named) > 20
    for s in named:
        topic, _, field = s.partition(".")
        assert topic in views, s
        if field:
            assert field in views[topic][0][1].DESCRIPTOR.fields_by_name, s
