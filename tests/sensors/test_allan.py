"""The Allan deviation and the IEEE noise-term fit: against allantools, on the bench's own
grades (static logs through the bench's IMU model, figures within 10 % of the grade
files), on vibration the terms cannot make, and on what is not resolved."""

import math

import allantools
import numpy as np
import pytest

from bench.sensors.allan import allan_deviation, fit_noise_terms
from bench.sensors.allan_humps import find_humps
from bench.sensors.imu.analysis import ImuLog, analyse
from bench.sensors.imu.grade import load_grade
from bench.sensors.imu.logs import static_log


def test_overlapping_allan_deviation_matches_allantools():
    rng = np.random.default_rng(0)
    rate = rng.normal(size=20_000) * 1e-3 + np.cumsum(rng.normal(size=20_000)) * 1e-6
    dt = 0.01
    ours = allan_deviation(rate * dt, dt)
    taus, adev, _, _ = allantools.oadev(rate, rate=1 / dt, data_type="freq", taus=ours.tau)
    common, i_ours, i_theirs = np.intersect1d(ours.tau, taus, return_indices=True)
    assert len(common) > 20
    assert ours.adev[i_ours] == pytest.approx(adev[i_theirs], rel=1e-9)


def test_white_noise_slope():
    rng = np.random.default_rng(1)
    N = 2e-4
    dt = 0.01
    x = rng.normal(size=200_000) * N * np.sqrt(dt)
    r = allan_deviation(x, dt)
    sel = r.tau < 10
    assert np.median(r.adev[sel] * np.sqrt(r.tau[sel])) == pytest.approx(N, rel=0.02)


def _configured(sensor, term, grade):
    e = getattr(grade, "gyro" if sensor == "gyro" else "accel")
    return {
        "quantization": e.quantization / math.sqrt(12.0),  # IEEE Q of pulses of size S: S / sqrt(12)
        "random_walk": float(e.noise[0]),
        "bias_instability": float(e.bias_instability[0]),
        "rate_random_walk": float(e.bias_random_walk[0]),
        "rate_ramp": 0.0,
    }[term]


def test_navigation_grade_at_200_hz_reads_pulses_and_random_walk_apart():
    """The output pulses dominate below 0.7 s: fitted as quantization, not as random walk
    (the old fit read 2.1-2.4 times the angle random walk); in 1000 s the bias instability
    is not resolved and is not reported as a figure (the old fit said 0)."""
    nav = load_grade("navigation")
    rep = analyse(static_log("navigation", 200.0, 1000.0, seed=3))
    assert not [w for w in rep.warnings if "hump" in w or "moved" in w]
    for ax in range(3):
        q = rep.value("gyro", ax, "quantization")
        assert q is not None and q == pytest.approx(_configured("gyro", "quantization", nav), rel=0.10)
        for sensor in ("gyro", "accel"):
            n = rep.value(sensor, ax, "random_walk")
            assert n is not None and n == pytest.approx(_configured(sensor, "random_walk", nav), rel=0.10)
            assert rep.value(sensor, ax, "bias_instability") is None
            assert rep.axis(sensor, ax).fit.rms_log10 < 0.1
        # the accelerometer pulses (1e-5 m/s) are below its noise at 5 ms: not resolved, and
        # the bound the curve gives holds the configured value
        acc = rep.axis("accel", ax)
        assert not acc.resolved["quantization"]
        assert acc.fit.terms["quantization"].bound >= _configured("accel", "quantization", nav)
    text = rep.text()
    assert "pulse-equivalent" in text and "rms log10 misfit" in text and "dominates 0.005-" in text
    assert "bias instability: not resolvable in 1000 s" in text


# (grade, duration at 1 Hz): long enough that the fitted figures scatter by 3-4 % over
# seeds (benchmarks/bench_allan.py), short enough for ~5-15 s per grade
LONG = [("navigation", 3_000_000.0), ("tactical", 500_000.0), ("mems", 3_000_000.0)]


@pytest.mark.slow
@pytest.mark.parametrize(("grade", "duration"), LONG, ids=[g for g, _ in LONG])
def test_figures_of_the_bench_grades_match_the_grade_files(grade, duration):
    g = load_grade(grade)
    rep = analyse(static_log(grade, 1.0, duration, seed=7))
    assert rep.static and not [w for w in rep.warnings if "hump" in w]
    for sensor in ("gyro", "accel"):
        for term in ("random_walk", "bias_instability", "rate_random_walk", "rate_ramp"):
            want = _configured(sensor, term, g)
            got = [rep.value(sensor, ax, term) for ax in range(3)]
            if want == 0.0:
                assert got == [None] * 3, f"{sensor} {term} reported although the grade has none"
            elif term == "rate_random_walk":
                # only MEMS has one; it dominates beyond 5000 s, where a 35-day log still has
                # few clusters: each axis within 20 %, their mean within 10 %
                assert all(v is not None and v == pytest.approx(want, rel=0.20) for v in got)
                assert np.mean(got) == pytest.approx(want, rel=0.10)
            else:
                assert all(v is not None and v == pytest.approx(want, rel=0.10) for v in got), (sensor, term, got)
    if g.gyro.bias_instability[0] > 0:
        tc = rep.axis("gyro", 0).fit.tau_c
        assert tc == pytest.approx(float(g.gyro.bias_instability_tau[0]), rel=0.3)


def test_unresolved_terms_are_bounds_that_hold_the_truth():
    """A short MEMS log: its rate random walk and bias instability are not resolved, and
    the bounds the curve allows are above the configured values (never a 0)."""
    mems = load_grade("mems")
    rep = analyse(static_log("mems", 100.0, 300.0, seed=2))
    for ax in range(3):
        gyro = rep.axis("gyro", ax)
        assert not gyro.resolved["rate_random_walk"]
        assert gyro.fit.terms["rate_random_walk"].bound >= _configured("gyro", "rate_random_walk", mems)
        assert gyro.fit.terms["random_walk"].bound >= _configured("gyro", "random_walk", mems)
    assert "rate random walk: not resolvable in 300 s (< " in rep.text()


def test_a_vibration_hump_is_found_and_left_out_of_the_fit():
    """White angle noise plus a 2 Hz angular vibration: the hump at ~0.2 s is no noise
    term, is named, and the random walk is read from the rest of the curve."""
    rng = np.random.default_rng(4)
    dt, n, N = 0.01, 360_000, 1e-5
    t = np.arange(n) * dt
    rate = N / math.sqrt(dt) * rng.standard_normal(n) + 2e-4 * np.sin(2 * math.pi * 2.0 * t)
    r = allan_deviation(rate * dt, dt)
    humps = find_humps(r)
    assert len(humps) == 1 and 0.1 < humps[0].tau_peak < 0.4
    naive = fit_noise_terms(r)
    fit = fit_noise_terms(r, exclude=[h.tau_range for h in humps])
    assert fit.terms["random_walk"].resolved
    assert fit.terms["random_walk"].value == pytest.approx(N, rel=0.10)
    assert not fit.terms["bias_instability"].resolved
    # without the exclusion the hump is read as a bias instability
    assert naive.terms["bias_instability"].value > 10 * N


def test_bench_grades_show_no_hump():
    """The Gauss-Markov peak of the bench's bias instability is broad: never a hump."""
    for grade in ("navigation", "tactical", "mems"):
        log = static_log(grade, 10.0, 20_000.0, seed=5)
        for x in (*log.dtheta.T, *log.dvel.T):
            assert find_humps(allan_deviation(x, log.dt)) == []


def test_tilting_unit_is_not_static():
    """Sway about the x axis: the accelerometers see the gravity direction turn as the
    gyros say; the report withdraws its figures and says why."""
    log = static_log("tactical", 100.0, 600.0, seed=1)
    t = np.arange(len(log.dtheta)) * log.dt
    tilt = 2e-4 * np.sin(2 * math.pi * t / 40.0)  # 40 arcsec, 40 s period
    dtilt = np.diff(tilt, prepend=0.0)
    moved = ImuLog(log.dtheta.copy(), log.dvel.copy(), log.dt, log.lat, "swaying")
    moved.dtheta[:, 0] += dtilt
    moved.dvel[:, 1] += 9.8 * tilt * log.dt  # pitching up turns gravity toward +y
    rep = analyse(moved)
    assert not rep.static
    assert any("gravity direction turn as the gyros say" in w for w in rep.warnings)
    assert all(not any(a.resolved.values()) for a in rep.axes)
    assert analyse(log).static
