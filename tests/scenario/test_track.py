"""Trajectories from recorded tracks (real smartLoc car drives) and from CSV."""

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.nav import earth
from bench.nav.rotation import quat_conj, quat_mul, quat_to_rotvec
from bench.nav.strapdown import NavState, mechanize
from bench.scenario.loader import load_scenario
from bench.scenario.track import SampledTrajectory, Track, read_csv_track, read_smartloc
from bench.scenario.trajectory import truth_at
from bench.sensors.imu import ideal_increments


@pytest.fixture(scope="module")
def berlin(data_dir):
    return read_smartloc(data_dir / "smartloc_berlin_potsdamer_platz_gt.txt")


def test_smartloc_reader(berlin):
    tr = berlin.cleaned()
    assert len(tr.t) > 1300
    assert tr.t[-1] - tr.t[0] == pytest.approx(283.0, abs=2.0)
    lat, lon, _h = earth.ecef_to_geodetic(tr.xyz_e[0])
    assert np.degrees(lat) == pytest.approx(52.51, abs=0.05)  # Berlin, Potsdamer Platz
    assert np.degrees(lon) == pytest.approx(13.37, abs=0.05)


def test_smoothed_track_follows_the_samples(berlin):
    traj = SampledTrajectory(berlin, smoothing=0.05)
    tr = berlin.cleaned()
    k = traj.kinematics(tr.t - tr.t[0])
    xyz = earth.geodetic_to_ecef(k.lat, k.lon, k.h)
    resid = np.linalg.norm(xyz - tr.xyz_e, axis=1)
    assert np.sqrt(np.mean(resid**2)) < 0.15
    speed = np.linalg.norm(k.vel_n, axis=1)
    assert speed.max() < 25.0  # an urban drive, not a spline blown up between samples
    # the derived heading follows the direction of travel where the car moves
    moving = speed > 3.0
    course = np.arctan2(k.vel_n[moving, 0], k.vel_n[moving, 1])
    d = np.angle(np.exp(1j * (course - k.euler[moving, 0])))
    assert np.percentile(np.abs(np.degrees(d)), 95) < 3.0


def test_imu_synthesized_from_a_real_drive_closes(berlin):
    # exact increments from the smoothed real drive, mechanized, reproduce the track
    traj = SampledTrajectory(berlin, smoothing=0.05)
    blocks = list(ideal_increments(traj, 200.0))
    t = np.concatenate([b.t_ns for b in blocks])
    dth = np.concatenate([b.dtheta for b in blocks])
    dv = np.concatenate([b.dvel for b in blocks])
    tru = truth_at(traj, t)
    t0 = truth_at(traj, np.array([0]))
    init = NavState(t0.lat[0], t0.lon[0], t0.h[0], t0.vel_n[0], t0.q_bn[0])
    res = mechanize(dth, dv, 0.005, init, h_ref=tru.h, vu_ref=tru.vel_n[:, 2])
    R_M, R_N = earth.radii(tru.lat)
    hor = np.hypot((res.lat - tru.lat) * R_M, (res.lon - tru.lon) * R_N * np.cos(tru.lat))
    assert hor.max() < 0.05
    att = quat_to_rotvec(quat_mul(res.q_bn, quat_conj(tru.q_bn)))
    assert np.degrees(np.abs(att).max()) * 3600 < 1.0


def test_csv_track_with_attitude(tmp_path):
    t = np.arange(0, 60.0, 0.1)
    lat = 31.939 + 1e-5 * t
    lon = 118.790 + 0.0 * t
    h = 20 + 0.01 * t
    hdg = 10 + 0.5 * t
    rows = ["time,lat,lon,h,heading,pitch,roll"] + [
        f"{a},{b:.9f},{c:.9f},{d:.4f},{e:.4f},0.5,-0.25" for a, b, c, d, e in zip(t, lat, lon, h, hdg, strict=True)
    ]
    p = tmp_path / "track.csv"
    p.write_text("\n".join(rows))
    tr = read_csv_track(p)
    traj = SampledTrajectory(tr)
    k = traj.kinematics(np.array([30.0]))
    assert np.degrees(k.euler[0]) == pytest.approx([25.0, 0.5, -0.25], abs=1e-6)
    assert np.degrees(k.euler_rate[0, 0]) == pytest.approx(0.5, abs=1e-6)
    assert k.vel_n[0, 1] == pytest.approx(1e-5 * np.radians(1) * earth.radii(k.lat)[0][0], rel=1e-3)


def test_csv_track_errors(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("time,foo\n1,2\n")
    with pytest.raises(ConfigError, match="lat, lon, h"):
        read_csv_track(p)
    p.write_text("lat,lon,h\n1,2,3\n")
    with pytest.raises(ConfigError, match="no time column"):
        read_csv_track(p)
    p.write_text("t,lat,lon,h\n" + "\n".join(f"{i},1,x,3" for i in range(10)))
    with pytest.raises(ConfigError, match="line 2"):
        read_csv_track(p)


def test_track_that_never_moves_needs_attitude():
    t = np.arange(10.0)
    xyz = np.tile(earth.geodetic_to_ecef(0.5, 0.5, 0.0), (10, 1))
    with pytest.raises(ConfigError, match="attitude"):
        SampledTrajectory(Track(t, xyz))


def test_track_scenario_file(tmp_path, data_dir):
    p = tmp_path / "berlin.toml"
    p.write_text(f"""
[scenario]
id = "BERLIN"
title = "smartLoc Berlin Potsdamer Platz drive"
[track]
file = "{data_dir / "smartloc_berlin_potsdamer_platz_gt.txt"}"
format = "smartloc"
smoothing = "5 cm"
start = "10 s"
end = "200 s"
[defaults]
gnss = "urban"
""")
    sc = load_scenario(p)
    traj = sc.trajectory()
    assert traj.duration_s == pytest.approx(190.0, abs=0.5)
    assert traj.segments()[0].gnss == "urban"


def test_the_three_splines_evaluated_as_one_give_the_scalar_splines_bits():
    """_Triple: one vector B-spline where the knots agree (interpolation), the scalar
    splines where they do not (smoothing fits choose their own knots); the values the same
    to the bit either way."""
    from bench.scenario.track import _fit, _Triple

    rng = np.random.default_rng(7)
    t = np.cumsum(rng.uniform(0.005, 0.015, 400))
    y = np.cumsum(rng.standard_normal((400, 3)), axis=0)
    tq = np.sort(rng.uniform(t[0], t[-1], 5000))
    for sigma, shared in ((0.0, True), (0.3, False)):
        splines = [_fit(t, y[:, i], sigma) for i in range(3)]
        for group in (splines, [s.derivative(1) for s in splines], [s.derivative(2) for s in splines]):
            triple = _Triple(group)
            assert (triple._one is not None) == shared
            assert np.array_equal(triple(tq), np.stack([s(tq) for s in group], axis=-1))
