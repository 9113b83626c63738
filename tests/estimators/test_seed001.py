"""The seed-001 estimator on a short synthetic drive: what each compensation buys, the
time-offset state, the odometer through an outage, consistency, configuration errors."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from bench.dut.estimator import create_estimator
from bench.errors import ConfigError
from tests.estimators.seed001_drive import POS, errors, fixes, make_drive, run

BASE = {"initial_position": POS, "lever_arm": [0.5, 1.2, 1.8], "bds_markov_sigma": [0.0, 0.0, 0.0]}


@pytest.fixture(scope="module")
def drive():
    return make_drive(300.0, 1)


def _horizontal(drive, sol, after: float = 150.0) -> tuple[np.ndarray, np.ndarray]:
    t, e = errors(drive, sol)
    m = t > after
    return t[m], e[m]


def test_lever_arm_compensation_removes_the_bias_of_an_uncompensated_filter(drive):
    g = fixes(drive, 1)
    sol, _ = run(create_estimator("seed001", BASE), drive, g)
    _, e = _horizontal(drive, sol)
    sol_off, _ = run(create_estimator("seed001", {**BASE, "lever_arm_compensation": False}), drive, g)
    _, e_off = _horizontal(drive, sol_off)
    assert np.linalg.norm(e.mean(axis=0)) < 0.3
    assert np.linalg.norm(e_off.mean(axis=0)) > 1.0  # about |C l| = 2.2 m, mostly vertical
    assert abs(e_off[:, 2].mean()) > 1.0 > 5 * abs(e[:, 2].mean())


def test_time_offset_state_converges_to_the_injected_offset(drive):
    g = fixes(drive, 2, tag_ns=80_000_000)
    est = create_estimator("seed001", BASE)
    sol, _ = run(est, drive, g)
    dt, sigma = est.time_offset
    assert abs(dt - 0.080) < 0.010 and sigma < 0.010
    assert abs(dt - 0.080) < 3 * sigma + 0.002
    off = create_estimator("seed001", {**BASE, "time_offset_estimation": False})
    sol_off, _ = run(off, drive, g)
    assert off.time_offset == (0.0, 0.0)
    rms = np.sqrt((_horizontal(drive, sol)[1][:, :2] ** 2).sum(axis=1).mean())
    rms_off = np.sqrt((_horizontal(drive, sol_off)[1][:, :2] ** 2).sum(axis=1).mean())
    assert rms_off > 2 * rms  # ~0.9 m along track at 12 m/s uncompensated


def test_odometer_bounds_the_drift_of_an_outage_better_than_without():
    # a tactical-grade IMU (1 deg/h, 1 mg), so that the unaided drift of 60 s shows
    drive = make_drive(300.0, 3, gyro_bias=1.0, accel_bias=1000.0)
    g = fixes(drive, 3, outage=(230.0, 290.0))
    worst = {}
    imu = {"gyro_bias": "1 deg/h", "accel_bias": "1000 ug"}
    for odo in (True, False):
        est = create_estimator("seed001", {**BASE, **imu, "odometer": odo})
        sol, qual = run(est, drive, g, odometer=odo)
        t, e = errors(drive, sol)
        m = (t > 230.0) & (t < 291.0)
        worst[odo] = float(np.hypot(e[m, 0], e[m, 1]).max())
        modes = sol["mode"][(t > 235.0) & (t < 289.0)]
        assert np.all(modes == (3 if odo else 1))  # odometer-aided / inertial only in the outage
        assert np.all(qual["excluded"][(t > 232.0) & (t < 289.0)] & 4)  # BDS excluded: no fix
        assert np.all(sol["mode"][(t > 150.0) & (t < 229.0)] == (5 if odo else 4))
    assert worst[True] < 0.6 * worst[False]  # 0.68 m against 1.30 m on this drive
    assert worst[True] < 1.0  # 60 s at up to 16 m/s: well under 0.2 % of ~800 m


def test_position_nees_is_consistent_over_seeds():
    nees = []
    for seed in (11, 12, 13):
        d = make_drive(200.0, seed)
        g = fixes(d, seed, sigma=(0.8, 0.8, 1.2), markov=(1.0, 1.0, 1.5), tau=40.0)
        est = create_estimator("seed001", {**BASE, "bds_markov_sigma": [1.0, 1.0, 1.5], "bds_markov_tau": "40 s"})
        sol, qual = run(est, d, g)
        t, e = errors(d, sol)
        m = t > 100.0
        nees.append(((e[m] / qual["sigma_pos"][m]) ** 2).sum(axis=1))
    mean = float(np.concatenate(nees).mean())
    assert 1.0 < mean < 6.0  # 3 dof; correlated over a run, so a loose band on 3 runs


def test_a_gross_fix_is_gated_out_and_flagged(drive):
    g = fixes(drive, 4)
    k = int(np.searchsorted(g["t_ns"], 200_000_000_000))
    g["lat"][k] += 200.0 / 6.4e6  # 200 m north
    est = create_estimator("seed001", BASE)
    sol, qual = run(est, drive, g)
    assert est.diagnostics()["fixes_gated"] >= 1
    t, e = errors(drive, sol)
    near = (t > 200.1) & (t < 201.0)
    assert np.all(qual["fault_detected"][near] & 4)
    assert np.abs(e[t > 199.0, :2]).max() < 1.0  # the bad fix did not pull the solution


def test_each_step_returns_records_of_its_own(drive):
    """The output records come from blocks allocated ahead: no two steps' outputs share a
    row, over several blocks, and no later step writes into what an earlier one returned."""
    est = create_estimator("seed001", BASE)
    outs = []
    step = est.step

    def keep(inputs):
        out = step(inputs)
        outs.append((out.solutions, out.qualities, out.solutions.tobytes(), out.qualities.tobytes()))
        return out

    est.step = keep  # type: ignore[method-assign]
    run(est, drive, fixes(drive, 1))
    parts = [o for o in outs if len(o[0])]
    assert sum(len(o[0]) for o in parts) > 3 * 4096  # several blocks
    for (s0, q0, _, _), (s1, q1, _, _) in itertools.pairwise(parts):
        assert not np.shares_memory(s0, s1) and not np.shares_memory(q0, q1)
    assert all(s.tobytes() == sb and q.tobytes() == qb for s, q, sb, qb in parts)


def test_configuration_errors_name_the_key():
    cases = [
        ({"lever_arm": [0.5, 1.2]}, "dut.config.lever_arm"),
        ({"lever_arm": ["0.5 m", "1 s", 0.0]}, "dut.config.lever_arm"),
        ({"odometer": "yes"}, "dut.config.odometer"),
        ({"bds_gate": 1.5}, "dut.config.bds_gate"),
        ({"time_offset_sigma": "-1 s"}, "dut.config.time_offset_sigma"),
        ({"map_matching": True}, "dut.config.road_network"),
        ({"map_matching": True, "road_network": "/nonexistent.geojson"}, "dut.config.road_network"),
        ({"alignment": "5 s"}, "dut.config.coarse_alignment"),
    ]
    for cfg, key in cases:
        with pytest.raises(ConfigError) as e:
            create_estimator("seed001", {**BASE, **cfg})
        assert e.value.key == key, cfg
    with pytest.raises(ConfigError) as e:
        create_estimator("seed001", {**BASE, "lever_arn": [0, 0, 0]})
    assert "lever_arn" in str(e.value)
    with pytest.raises(ConfigError) as e:
        create_estimator("seed001", {"lever_arm": [0, 0, 0]})
    assert e.value.key == "dut.config.initial_position"


def test_map_matching_hook_puts_the_matched_position_on_the_output(drive):
    """The wiring, with a stand-in matcher that decides two epochs late as
    bench.estimators.mapmatch.OnlineMatcher does: called at the 10 Hz valid epochs, the
    offset of the matched position from the filter's position *at the decided epoch*
    applied from the decision on."""

    class Match:
        def __init__(self, t_ns, lat, lon):
            self.t_ns, self.lat, self.lon, self.matched = t_ns, lat, lon, True

    class Matcher:
        def __init__(self):
            self.calls: list[int] = []
            self.seen: list[tuple[int, float, float]] = []

        def update(self, t_ns, lat, lon, heading, speed):
            self.calls.append(t_ns)
            self.seen.append((t_ns, lat, lon))
            if len(self.seen) < 3:
                return None
            t0, la, lo = self.seen[-3]
            return Match(t0, la + 1e-6, lo - 2e-6)

    g = fixes(drive, 5)
    plain, _ = run(create_estimator("seed001", BASE), drive, g)
    est = create_estimator("seed001", BASE)
    matcher = Matcher()
    est._matcher = matcher
    sol, _ = run(est, drive, g)
    valid = sol["valid"] == 1
    on = valid & (sol["t_ns"] >= matcher.calls[2])  # from the first decision
    assert on.sum() > 100
    assert np.allclose(sol["lat"][on] - plain["lat"][on], 1e-6, atol=1e-12)
    assert np.allclose(sol["lon"][on] - plain["lon"][on], -2e-6, atol=1e-12)
    assert np.all(sol["lat"][~on] == plain["lat"][~on])
    calls = np.array(matcher.calls)
    assert len(calls) and np.all(calls % 100_000_000 == 0)


def _network(tmp_path, drive) -> str:
    """The drive's own road (its truth track every second) and a parallel distractor 20 m
    to its left, as a GeoJSON file."""
    import json
    import math

    k = np.arange(0, len(drive.t), 200)
    lat, lon = np.degrees(drive.pos[k, 0]), np.degrees(drive.pos[k, 1])
    moving = np.hypot(drive.vel[k, 0], drive.vel[k, 1]) > 0.5
    lat, lon = lat[moving], lon[moving]
    route = [[float(a), float(b)] for a, b in zip(lon, lat, strict=True)]
    # the distractor: the first straight stretch shifted 20 m to the left of the travel
    v = drive.vel[k][moving][:10]
    u = v[:, :2].mean(axis=0) / np.linalg.norm(v[:, :2].mean(axis=0))
    left_e, left_n = -u[1] * 20.0, u[0] * 20.0
    m_lat, m_lon = 1.0 / 6378137.0, 1.0 / (6378137.0 * math.cos(math.radians(lat[0])))
    par = [[lo + math.degrees(left_e * m_lon), la + math.degrees(left_n * m_lat)] for lo, la in route[:10]]
    feats = [("route", "route", route), ("parallel", "distractor", par)]
    doc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"id": i, "role": r}, "geometry": {"type": "LineString", "coordinates": c}}
        for i, r, c in feats]}
    path = tmp_path / "roads.geojson"
    path.write_text(json.dumps(doc))
    return str(path)


def test_the_real_matcher_inside_seed001_puts_the_output_on_the_road(drive, tmp_path):
    """map_matching = true with a road network file: bench.estimators.mapmatch inside the
    estimator, on a drive whose fixes carry a correlated error that pulls the filter off the
    road; the matched output is on the road and never on the distractor."""
    from bench.scoring.roadmap import RoadNetwork

    path = _network(tmp_path, drive)
    g = fixes(drive, 7, markov=(1.5, 1.5, 0.5), tau=30.0)
    cfg = {**BASE, "bds_markov_sigma": [1.5, 1.5, 0.5], "bds_markov_tau": 30.0}
    plain, _ = run(create_estimator("seed001", cfg), drive, g)
    sol, _ = run(create_estimator("seed001", {**cfg, "map_matching": True, "road_network": path}), drive, g)
    net = RoadNetwork.from_geojson(path)
    ok = (sol["valid"] == 1) & (sol["t_ns"] > 80e9)  # moving, the matcher started
    assert ok.sum() > 1000

    def lateral(s):
        en = net.to_enu(s["lat"][ok], s["lon"][ok])  # rad
        _, d = net.nearest(en[:, 0], en[:, 1], mask=net.is_route)
        _, d_dis = net.nearest(en[:, 0], en[:, 1], mask=~net.is_route)
        return d, d_dis

    d_plain, _ = lateral(plain)
    d_mm, d_dis = lateral(sol)
    print(f"lateral to the road: plain p95 {np.percentile(d_plain, 95):.2f} m, matched p95 "
          f"{np.percentile(d_mm, 95):.2f} m")
    assert np.percentile(d_plain, 95) > 0.5  # the correlated fixes pull the filter off the road
    assert np.mean(d_mm < 0.5) >= 0.99
    assert np.percentile(d_mm, 95) < 0.5 * np.percentile(d_plain, 95)
    assert not np.any(d_dis < d_mm)  # never nearer the distractor than the road
    # the filter itself is untouched: the velocity and attitude are the plain run's
    assert np.array_equal(sol["vel_n"], plain["vel_n"])
