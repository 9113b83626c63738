"""HMM map matcher on a small synthetic network: a route with an L turn, a parallel street
20 m away and a side road at the corner; noisy positions are put back on the route."""

import json
import math

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.estimators.mapmatch import OnlineMatcher, RoadNetwork, match

LAT0, LON0 = math.radians(29.72), math.radians(106.63)


def _lonlat(e, n):
    lat = LAT0 + n / 6378137.0
    lon = LON0 + e / (6378137.0 * math.cos(LAT0))
    return [math.degrees(lon), math.degrees(lat)]


def _write(tmp_path, feats):
    doc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": props, "geometry": {"type": "LineString", "coordinates": coords}}
        for props, coords in feats]}
    p = tmp_path / "roads.geojson"
    p.write_text(json.dumps(doc))
    return p


@pytest.fixture
def network(tmp_path):
    route = [_lonlat(0, 0), _lonlat(500, 0), _lonlat(500, 500)]
    parallel = [_lonlat(0, 20), _lonlat(480, 20)]
    side = [_lonlat(500, 0), _lonlat(700, 0)]
    p = _write(tmp_path, [({"id": "r", "role": "route"}, route), ({"id": "p"}, parallel), ({"id": "s"}, side)])
    return RoadNetwork.from_geojson(p, origin=(LAT0, LON0))


def _drive(rng, sigma=4.0, v=10.0):
    t = np.arange(0, 100, 1.0)
    s = v * t
    e = np.where(s < 500, s, 500.0)
    n = np.where(s < 500, 0.0, s - 500)
    hdg = np.where(s < 500, math.pi / 2, 0.0)
    e_m, n_m = e + rng.normal(0, sigma, t.size), n + rng.normal(0, sigma, t.size)
    lat = LAT0 + n_m / 6378137.0
    lon = LON0 + e_m / (6378137.0 * math.cos(LAT0))
    return (t * 1e9).astype(np.int64), lat, lon, hdg + rng.normal(0, 0.05, t.size), np.full(t.size, v), e, n


def test_noisy_track_is_matched_to_the_route(network):
    t, lat, lon, hdg, spd, e, n = _drive(np.random.default_rng(1))
    out = match(OnlineMatcher(network, sigma_distance=5.0, lag=2), t, lat, lon, hdg, spd)
    assert [m.t_ns for m in out] == list(t)
    on_route = np.mean([m.feature_id == "r" for m in out])
    assert on_route == 1.0
    en = np.array([network.to_enu(m.lat, m.lon) for m in out])
    assert np.max(np.hypot(en[:, 0] - e, en[:, 1] - n)) < 15.0


def test_no_candidate_is_unmatched_and_restarts(network):
    m = OnlineMatcher(network, radius=30.0, lag=0)
    far = LAT0 + 1000 / 6378137.0
    r = m.update(0, far, LON0, 0.0, 0.0)
    assert r is not None and not r.matched and r.lat == far
    r = m.update(1_000_000_000, LAT0, LON0 + 100 / (6378137.0 * math.cos(LAT0)), math.pi / 2, 10.0)
    assert r is not None and r.matched and r.feature_id == "r" and r.distance < 1e-6


def test_heading_wraps(network):
    m = OnlineMatcher(network, lag=0)
    lat = LAT0 + 10 / 6378137.0  # between the route (0 m) and the parallel (20 m): heading decides nothing
    lon = LON0 + 100 / (6378137.0 * math.cos(LAT0))
    a = m.update(0, lat, lon, math.pi / 2 + 2 * math.pi, 10.0)
    b = OnlineMatcher(network, lag=0).update(0, lat, lon, -3 * math.pi / 2, 10.0)
    assert a.segment == b.segment


@pytest.mark.parametrize(("feats", "key"), [
    ([({"id": "x"}, [[106.0, 29.0]])], "features[0].geometry.coordinates"),
    ([({"id": "x"}, [[106.0, 95.0], [106.0, 29.0]])], "features[0].geometry.coordinates"),
    ([({"role": "route"}, [[106.0, 29.0], [106.1, 29.0]])], "features[0].properties.id"),
])
def test_bad_files_name_the_feature(tmp_path, feats, key):
    p = _write(tmp_path, feats)
    with pytest.raises(ConfigError) as err:
        RoadNetwork.from_geojson(p)
    assert err.value.key == key and str(p) in str(err.value)


def test_malformed_json_and_point_geometry(tmp_path):
    p = tmp_path / "bad.geojson"
    p.write_text("{not json")
    with pytest.raises(ConfigError, match="malformed"):
        RoadNetwork.from_geojson(p)
    p.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"id": 1}, "geometry": {"type": "Point", "coordinates": [1, 2]}}]}))
    with pytest.raises(ConfigError, match="LineString"):
        RoadNetwork.from_geojson(p)
