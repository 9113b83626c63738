"""The seed-003 estimator: configuration errors, the frame switch both ways, the command
latch, refusals, the drive over the pole, and S003a/S003b shortened through the bench."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from bench.acceptance.case import load_case
from bench.errors import ConfigError
from bench.estimators import seed003_kernel as K  # noqa: N812
from bench.estimators import seed003_state as L  # noqa: N812
from bench.estimators.seed003 import Seed003
from bench.nav import earth
from bench.nav.ecef import from_geographic
from bench.nav.rotation import euler_to_dcm, euler_to_quat
from bench.run.case_runner import spec_from_case
from bench.run.engine import run
from bench.scoring.align import nav_errors
from bench.scoring.data import load_run
from bench.scoring.frameswitch import SwitchSettings, analyse_switches
from bench.scoring.windows import Window, WindowSpec
from tests.estimators.polar_drive import over_the_pole

ROOT = Path(__file__).parents[2] / "test_cases"
START = [87.95, 10.0, 50.0]


@pytest.mark.parametrize(
    ("config", "key"),
    [
        ({"filter_conversion": "yes"}, "dut.config.filter_conversion"),
        ({"unconverted": "zero"}, "dut.config.unconverted"),
        ({"start": "flying"}, "dut.config.start"),
        ({"switch_latitude": "91 deg"}, "dut.config.switch_latitude"),
        ({"geographic_limit": "80 deg"}, "dut.config.geographic_limit"),
        ({"initial_velocity": [0.0, 20.0]}, "dut.config.initial_velocity"),
        ({"position_gate": 1.5}, "dut.config.position_gate"),
        ({"doppler_noise": "0 m/s"}, "dut.config.doppler_noise"),
        ({"wander_angle": 3.0}, "dut.config"),
    ],
)
def test_bad_configuration_names_the_key(config, key):
    with pytest.raises(ConfigError) as err:
        Seed003().configure({"initial_position": START, **config})
    assert key in str(err.value)


def _grid_state(lat_deg: float, conversion: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    est = Seed003()
    est.configure({"initial_position": [lat_deg, 10.0, 50.0], "filter_conversion": conversion})
    sg = np.zeros(20)
    sg[0:3] = math.radians(lat_deg), math.radians(10.0), 50.0
    sg[3:6] = 0.0, 20.0, 0.0
    sg[6:10] = euler_to_quat(0.3, 0.0, 0.0)
    from_geographic(sg, est.st[0:20])
    est.st[L.S_FRAME] = L.FRAME_GRID
    est.P[:, :] = np.diag(np.r_[[1e-6] * 3, [0.01] * 3, [100.0] * 3, [1e-14] * 3, [1e-7] * 3])
    return est.st, est.P, est.prm


def test_the_geographic_frame_is_refused_beyond_its_limit_and_the_state_left_alone():
    st, P, prm = _grid_state(89.8)  # beyond geographic_limit (89.5 deg)
    before, P0 = st.copy(), P.copy()
    assert not K.switch_frame(st, P, prm, False, 1.0)
    assert st[L.S_FRAME] == L.FRAME_GRID and st[L.S_NREFUSED] == 1.0 and st[L.S_NSWITCH] == 0.0
    assert np.array_equal(st[0:20], before[0:20]) and np.array_equal(P, P0)


@pytest.mark.parametrize("conversion", [True, False])
def test_a_switch_there_and_back_returns_the_navigation_state(conversion):
    st, P, prm = _grid_state(88.5, conversion)
    before = st[0:20].copy()
    assert K.switch_frame(st, P, prm, False, 1.0) and st[L.S_FRAME] == L.FRAME_GEOGRAPHIC
    assert st[0] == pytest.approx(math.radians(88.5), abs=1e-12)
    assert np.allclose(st[3:6], [0.0, 20.0, 0.0], atol=1e-9)  # ENU velocity
    assert K.switch_frame(st, P, prm, True, 2.0) and st[L.S_FRAME] == L.FRAME_GRID
    assert np.allclose(st[0:6], before[0:6], rtol=0, atol=1e-7)
    assert np.allclose(st[6:10], before[6:10], atol=1e-12)
    assert st[L.S_NSWITCH] == 2.0
    assert np.all(np.linalg.eigvalsh(P) > 0.0)
    if not conversion:  # restarted from the initial sigmas: 10 m, 0.1 m/s, 1' level, 5' heading
        assert P[2, 2] == pytest.approx(math.radians(5.0 / 60.0) ** 2)
        assert np.trace(P[6:9, 6:9]) == pytest.approx(300.0)


def _dcm_be(lat, lon, heading, pitch, roll):
    return np.swapaxes(earth.C_en(lat, lon), -1, -2) @ euler_to_dcm(heading, pitch, roll)


def test_over_the_pole_the_grid_frame_navigates_and_the_output_stays_geographic():
    """Error-free sensors on a great circle through the pole: the estimator starts in the
    grid frame (beyond 88 deg), stays in it, and its output -- geographic, heading
    true -- follows the truth through latitude 90 deg and the longitude's half-turn."""
    drive = over_the_pole(89.995, 10.0, 50.0, 20.0, 90.0)
    est = Seed003()
    est.configure({"initial_position": [89.995, 10.0, 50.0], "start": "moving", "initial_velocity": [0.0, 20.0, 0.0],
                   "initial_attitude": [0.0, 0.0, 0.0], "initial_position_sigma": "1 m",
                   "position_noise_floor": "0.5 m"})
    sols = []
    for t1 in range(10_000_000, 90_000_000_001, 10_000_000):
        out = est.step(drive.inputs(t1 - 10_000_000, t1, 20.0))
        if len(out.solutions):
            sols.append(out.solutions.copy())
    sol = np.concatenate(sols)
    assert len(sol) == 9000 and est.frame == "grid"
    assert np.all(sol["frame"] == 1) and np.all(sol["valid"] == 1)
    k = np.searchsorted(drive.t, sol["t_ns"])
    assert np.array_equal(drive.t[k], sol["t_ns"])
    # the drive passes within a metre of the pole and ends 1.2 km past it
    dist = (math.pi / 2 - drive.lat) * 6_399_594.0
    assert dist.min() < 1.0 and dist[-1] > 1000.0
    d = earth.geodetic_to_ecef(sol["lat"], sol["lon"], sol["h"]) - earth.geodetic_to_ecef(
        drive.lat[k], drive.lon[k], drive.h[k])
    assert np.all(np.isfinite(d)) and np.max(np.linalg.norm(d, axis=1)) < 0.05
    # the physical attitude: DUT's C_be from its geographic output against the truth's
    Cd = _dcm_be(sol["lat"], sol["lon"], sol["heading"], sol["pitch"], sol["roll"])
    R = np.einsum("nij,nkj->nik", Cd, drive.C_be[k])
    ang = np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0))
    assert np.max(ang) < math.radians(0.1 / 60.0)
    # the true heading turns from north to south across the pole (geographic output)
    hd = np.degrees(sol["heading"])
    before, after = dist[k] > 50.0, dist[k] > 50.0
    before[np.argmin(dist[k]):] = False
    after[: np.argmin(dist[k])] = False
    assert np.all(np.minimum(hd[before], 360.0 - hd[before]) < 0.1)
    assert np.all(np.abs(hd[after] - 180.0) < 0.1)
    assert np.all(np.isfinite(sol["vel_n"])) and np.allclose(np.linalg.norm(sol["vel_n"], axis=1), 20.0, atol=1e-3)


def _run(name: str, variant: str, out: Path, seconds: float) -> Path:
    case = load_case(ROOT / name).for_variant(variant)
    spec = dataclasses.replace(spec_from_case(case, 1, out), duration_ns=round(seconds * 1e9))
    res = run(spec)
    assert res.status == "complete", res.reason
    return Path(res.path)


@pytest.fixture(scope="module")
def polar_runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("s003a")
    return {v: load_run(_run("S003a_frame_switch_polar.toml", v, folder / v, 345.0))
            for v in ("with_conversion", "without_conversion")}


@pytest.mark.slow
def test_s003a_the_frame_bit_changes_once_where_the_estimate_crosses_88_deg(polar_runs):
    for d in polar_runs.values():
        sol = d.nav[np.argsort(d.nav["t_ns"])]
        change = np.flatnonzero(np.diff(sol["frame"].astype(int)))
        assert len(change) == 1  # no flicker: the hysteresis holds
        i = change[0] + 1
        assert sol["frame"][i - 1] == 0 and sol["frame"][i] == 1 and sol["frame"][-1] == 1
        assert np.degrees(sol["lat"][i - 1]) < 88.0 <= np.degrees(sol["lat"][i])
        assert 270.0 < sol["t_ns"][i] * 1e-9 < 290.0  # about 280 s, as the case says


@pytest.mark.slow
def test_s003a_conversion_leaves_no_mark_and_without_it_the_velocity_error_swings(polar_runs):
    settings = SwitchSettings(pre_ns=60_000_000_000, post_ns=60_000_000_000, floor_position=0.2,
                              floor_velocity=0.02, floor_heading=math.radians(0.1 / 60.0))
    out = {}
    for v, d in polar_runs.items():
        e = nav_errors(d.truth, d.nav)
        whole = Window(WindowSpec(), np.array([[0, 400_000_000_000]], np.int64), 400_000_000_000)
        a = analyse_switches(e, d.nav["frame"], whole, settings)
        assert len(a.switches) == 1 and a.switches[0].to == "grid"
        out[v] = a.switches[0].measures
    w, wo = out["with_conversion"], out["without_conversion"]
    assert w["position"]["jump_excess"] < 1.0
    assert w["velocity"]["excess"] <= 0.03 and w["heading"]["excess"] <= math.radians(0.3 / 60)
    assert wo["velocity"]["excess"] > 0.03 and wo["velocity"]["excess"] > 3.0 * w["velocity"]["excess"]


@pytest.fixture(scope="module")
def commanded_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("s003b")
    return load_run(_run("S003b_frame_switch_commanded.toml", "with_conversion", folder, 330.0))


@pytest.mark.slow
def test_s003b_the_commanded_switch_follows_bench_cmd_within_one_epoch_and_latches(commanded_run):
    sol = commanded_run.nav[np.argsort(commanded_run.nav["t_ns"])]
    t = sol["t_ns"]
    first = t[sol["frame"] == 1][0]
    assert 300_000_000_000 <= first <= 300_010_000_000  # the output epoch the command arrived at
    assert np.all(sol["frame"][t >= first] == 1)  # latched: below 88 deg, the latitude rule would go back
    assert np.all(sol["frame"][t < first] == 0)
    e = nav_errors(commanded_run.truth, commanded_run.nav)
    after = e.t_ns >= 300_000_000_000
    assert np.all(np.isfinite(e.pos[after])) and np.max(np.hypot(e.pos[after, 0], e.pos[after, 1])) < 30.0
