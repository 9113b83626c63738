"""``map.*`` metrics through the Scorer, and the per-interval accuracy figures, on
recordings written by hand with errors the tests know exactly."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bench.scoring.data import DutDataError, NoDataError, load_run
from bench.scoring.mapscore import MapSettings
from bench.scoring.metrics import METRICS, Scorer, ScoringSettings
from bench.scoring.roadmap import R_EARTH
from bench.scoring.windows import WindowSpec
from tests.scoring.helpers import drive, nav_of, segments_of, truth_of, write_recording

ALL = WindowSpec("all")
LAT0, LON0 = 30.0, 100.0  # helpers.drive starts here, heading north


def _roads(distractor_east: float = 20.0) -> bytes:
    """The drive's road (north from the start, 3 km) and a parallel street east of it."""
    dlon = math.degrees(distractor_east / (R_EARTH * math.cos(math.radians(LAT0))))
    north = math.degrees(3000.0 / R_EARTH)
    feats = [
        {"type": "Feature", "properties": {"id": "main", "role": "route"},
         "geometry": {"type": "LineString", "coordinates": [[LON0, LAT0 - 1e-3], [LON0, LAT0 + north]]}},
        {"type": "Feature", "properties": {"id": "side", "role": "distractor"},
         "geometry": {"type": "LineString", "coordinates": [[LON0 + dlon, LAT0 - 1e-3], [LON0 + dlon, LAT0 + north]]}},
    ]
    return json.dumps({"type": "FeatureCollection", "features": feats}).encode()


@pytest.fixture(scope="module")
def traj():
    return drive(speed=10.0, duration=100.0)


@pytest.fixture(scope="module")
def truth(traj):
    return truth_of(traj)


T10 = np.arange(0, 100_000_000_001, 100_000_000)  # the DUT at 10 Hz


def _scorer(tmp_path, traj, truth, nav, *, tolerance=5.0, attach=True, path=None):
    att = {"map/roads.geojson": _roads()} if attach else {}
    rec = write_recording(tmp_path / "r.mcap", truth=truth, nav=nav, segments=segments_of(traj), attachments=att)
    settings = ScoringSettings(map=MapSettings("roads.geojson", path, tolerance))
    return Scorer(load_run(rec), settings)


def test_catalogue_units():
    assert METRICS["map.on_road"].unit == "%" and METRICS["map.on_road"].dimension == "dimensionless"
    assert METRICS["map.lateral.p95"].dimension == "length" and METRICS["map.distractor_max"].dimension == "time"
    assert METRICS["accuracy.horizontal.interval_of_distance"].unit == "%"
    assert METRICS["accuracy.horizontal.interval_max"].unit == "m"


def test_on_the_road_with_a_small_offset(tmp_path, traj, truth):
    s = _scorer(tmp_path, traj, truth, nav_of(traj, T10, pos_enu=(1.5, 7.0, 0.0)))
    assert s.metric("map.on_road", ALL).value == 1.0
    for stat in ("rms", "mean", "p95", "max"):  # along-track error is no lateral error
        assert s.metric(f"map.lateral.{stat}", ALL).value == pytest.approx(1.5, abs=0.01)
    assert s.metric("map.distractor_max", ALL).value == 0.0
    mv = s.metric("map.on_road", ALL)
    assert mv.details["epochs"] == len(T10) and mv.details["tolerance_m"] == 5.0


def test_on_road_falls_when_the_dut_is_offset_beyond_the_tolerance(tmp_path, traj, truth):
    east = np.where(np.arange(len(T10)) < 300, 6.0, 4.0)  # 300 of 1001 epochs 6 m off the road
    nav = nav_of(traj, T10, pos_enu=np.column_stack([east, np.zeros_like(east), np.zeros_like(east)]))
    s = _scorer(tmp_path, traj, truth, nav)
    assert s.metric("map.on_road", ALL).value == pytest.approx(701 / 1001, abs=1e-12)
    assert s.metric("map.lateral.max", ALL).value == pytest.approx(6.0, abs=0.01)
    # a wider tolerance takes them back, a narrower one loses every epoch
    assert _scorer(tmp_path, traj, truth, nav, tolerance=7.0).metric("map.on_road", ALL).value == 1.0
    assert _scorer(tmp_path, traj, truth, nav, tolerance=3.0).metric("map.on_road", ALL).value == 0.0


def test_distractor_episodes_are_measured(tmp_path, traj, truth):
    east = np.zeros(len(T10))
    east[100:130] = 19.0  # 3 s on the street 20 m east (30 epochs at 10 Hz)
    east[500:512] = 21.0  # 1.2 s
    east[700:710] = 12.0  # 1 s nearer the street but 8 m from it: off road, not on the distractor
    nav = nav_of(traj, T10, pos_enu=np.column_stack([east, np.zeros_like(east), np.zeros_like(east)]))
    s = _scorer(tmp_path, traj, truth, nav)
    assert s.metric("map.distractor_max", ALL).value == pytest.approx(3.0, abs=1e-9)
    assert s.metric("map.on_road", ALL).value == pytest.approx((1001 - 52) / 1001, abs=1e-12)
    # the window decides: after the first episode only the 1.2 s one is left
    later = WindowSpec("later", start_ns=20_000_000_000)
    assert s.metric("map.distractor_max", later).value == pytest.approx(1.2, abs=1e-9)


def test_invalid_epochs_are_the_duts_failure(tmp_path, traj, truth):
    nav = nav_of(traj, T10)
    nav["valid"] = 0
    with pytest.raises(DutDataError, match="invalid"):
        _scorer(tmp_path, traj, truth, nav).metric("map.on_road", ALL)
    nav = nav_of(traj, T10)
    nav["lat"][40] = np.nan  # flagged valid, no position
    with pytest.raises(DutDataError, match="non-finite"):
        _scorer(tmp_path, traj, truth, nav).metric("map.lateral.rms", ALL)


def test_the_network_from_the_recording_or_the_case(tmp_path, traj, truth):
    nav = nav_of(traj, T10, pos_enu=(2.0, 0.0, 0.0))
    # no attachment: the case's file
    f = tmp_path / "roads.geojson"
    f.write_bytes(_roads())
    s = _scorer(tmp_path, traj, truth, nav, attach=False, path=f)
    assert s.metric("map.lateral.mean", ALL).value == pytest.approx(2.0, abs=0.01)
    # neither: the bench cannot judge
    with pytest.raises(NoDataError, match="no road network"):
        _scorer(tmp_path, traj, truth, nav, attach=False).metric("map.on_road", ALL)
    with pytest.raises(NoDataError, match="road network"):
        _scorer(tmp_path, traj, truth, nav, attach=False, path=tmp_path / "gone.geojson").metric("map.on_road", ALL)
    # a case without [scoring.map]
    rec = write_recording(tmp_path / "n.mcap", truth=truth, nav=nav, segments=segments_of(traj))
    with pytest.raises(NoDataError, match=r"\[scoring.map\]"):
        Scorer(load_run(rec)).metric("map.on_road", ALL)


# -- per-interval figures (i2Nav OutageStatistic) ----------------------------------------------
def test_interval_figures_by_hand(tmp_path):
    # segments: 0-50 s straight, 50-65 s a turn, 65-100 s straight (GNSS blocked); 10 m/s
    traj = drive(speed=10.0, duration=100.0, turn=True)
    truth = truth_of(traj)
    t = T10
    east = np.where(t < 50e9, 3.0, np.where(t < 65e9, 9.0, 2.8))
    east[t < 10e9] = 1.0
    nav = nav_of(traj, t, pos_enu=np.column_stack([east, np.zeros_like(east), np.zeros_like(east)]))
    rec = write_recording(tmp_path / "r.mcap", truth=truth, nav=nav, segments=segments_of(traj))
    s = Scorer(load_run(rec))
    two = WindowSpec("outages", indices=(0, 2))  # two intervals: 0-50 s (500 m) and 65-100 s (350 m)
    mx = s.metric("accuracy.horizontal.interval_max", two)
    assert mx.value == pytest.approx(3.0, abs=1e-6)  # the first interval's
    pct = s.metric("accuracy.horizontal.interval_of_distance", two)
    assert pct.value == pytest.approx(2.8 / 350.0, rel=1e-4)  # the second's: 0.8 %, not 3 m / 850 m
    rows = pct.details["intervals"]
    assert [(r["start_s"], r["end_s"]) for r in rows] == [(0.0, 50.0), (65.0, 100.0)]
    assert rows[0]["max_error"] == pytest.approx(3.0, abs=1e-6) and rows[1]["max_error"] == pytest.approx(2.8, abs=1e-6)
    assert rows[0]["distance_m"] == pytest.approx(500.0, rel=1e-4)
    assert rows[1]["distance_m"] == pytest.approx(350.0, rel=1e-4)
    assert rows[0]["of_distance_pct"] == pytest.approx(0.6, rel=1e-4)
    assert rows[1]["of_distance_pct"] == pytest.approx(0.8, rel=1e-4)
    # of_distance keeps its meaning: max over the window / distance in the whole window
    assert s.metric("accuracy.horizontal.of_distance", two).value == pytest.approx(3.0 / 850.0, rel=1e-4)
    assert s.metric("accuracy.horizontal.max", two).value == pytest.approx(3.0, abs=1e-6)


def test_interval_figures_of_a_vehicle_that_does_not_move(tmp_path):
    traj = drive(speed=0.0, duration=100.0)
    truth = truth_of(traj)
    rec = write_recording(tmp_path / "r.mcap", truth=truth, nav=nav_of(traj, T10, pos_enu=(1.0, 0.0, 0.0)),
                          segments=segments_of(traj))
    s = Scorer(load_run(rec))
    with pytest.raises(NoDataError, match="no distance"):
        s.metric("accuracy.horizontal.interval_of_distance", ALL)
    mv = s.metric("accuracy.horizontal.interval_max", ALL)
    assert mv.value == pytest.approx(1.0, abs=1e-6) and mv.details["intervals"][0]["of_distance_pct"] is None


def test_overview_shows_the_map_figures_of_a_case_with_a_network(tmp_path, traj, truth):
    s = _scorer(tmp_path, traj, truth, nav_of(traj, T10, pos_enu=(6.0, 0.0, 0.0)))
    block = s.overview()["all"]
    assert block["map.on_road"] == 0.0 and block["map.lateral.rms"] == pytest.approx(6.0, abs=0.01)
    rec = write_recording(tmp_path / "n.mcap", truth=truth, nav=nav_of(traj, T10), segments=segments_of(traj))
    assert "map.on_road" not in Scorer(load_run(rec)).overview()["all"]
