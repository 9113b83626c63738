"""The i2Nav text formats: time base, frames, and malformed results named by file, line, field."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.exchange.gpstime import WEEK_S, GpsClock, leap_seconds
from bench.exchange.i2nav_text import enu_to_ned, rfu_to_frd
from bench.exchange.nav_import import NavFileError, read_nav_result


def _utc_ns(*args) -> int:
    return int(dt.datetime(*args, tzinfo=dt.UTC).timestamp()) * 10**9


def test_gps_time_of_a_known_epoch():
    # 2025-06-01 00:00:00 UTC is a Sunday: GPS week 2369 begins 18 s (the leap seconds) earlier
    clock = GpsClock.of_epoch(_utc_ns(2025, 6, 1))
    assert (clock.week, clock.leap_s, clock.zero_ns) == (2369, 18, 18 * 10**9)
    assert clock.sow_text(np.array([0, 1_500_000_001])) == ["18.000000000", "19.500000001"]
    t = np.array([0, 5_000_000, 3_600_000_000_000, 7 * 86400 * 10**9 + 123])
    week = clock.week
    sow = clock.sow_ns(t) * 1e-9
    assert np.array_equal(clock.bench_ns(week, sow), t)  # seconds of week keep counting past 604800
    assert clock.bench_ns(week + 1, sow - WEEK_S)[-1] == t[-1]
    assert leap_seconds(_utc_ns(2016, 12, 31)) == 17 and leap_seconds(_utc_ns(2017, 1, 1)) == 18
    with pytest.raises(ConfigError, match="before GPS time zero"):
        GpsClock.of_epoch(_utc_ns(1979, 1, 1))


def test_frames():
    # right-forward-up (1, 2, 3) is forward 2, right 1, down -3; east-north-up likewise
    assert rfu_to_frd(np.array([1.0, 2.0, 3.0])).tolist() == [2.0, 1.0, -3.0]
    assert enu_to_ned(np.array([[1.0, 2.0, 3.0]])).tolist() == [[2.0, 1.0, -3.0]]
    v = np.random.default_rng(1).normal(size=(5, 3))
    assert np.array_equal(enu_to_ned(enu_to_ned(v)), v)


CLOCK = GpsClock.of_epoch(_utc_ns(2025, 6, 1))
GOOD = "2369 18.010000000 34.24605 108.90965 380.0 1.0 2.0 -0.1 0.5 -0.25 30.0\n"


def test_a_good_line(tmp_path):
    p = tmp_path / "r.nav"
    p.write_text("# KF-GINS result\n\n" + GOOD + GOOD.replace("18.010000000", "18.020000000").replace("30.0", "-10.0"))
    res = read_nav_result(p, CLOCK, duration_ns=60 * 10**9)
    s = res.solutions
    assert s["t_ns"].tolist() == [10_000_000, 20_000_000] and s["rx_ns"].tolist() == s["t_ns"].tolist()
    assert np.allclose(s["vel_n"][0], [2.0, 1.0, 0.1])  # north 1, east 2, down -0.1 -> ENU
    assert np.allclose(np.degrees([s["roll"][0], s["pitch"][0], s["heading"][0]]), [0.5, -0.25, 30.0])
    assert np.isclose(np.degrees(s["heading"][1]), 350.0)
    assert s["valid"].tolist() == [1, 1] and s["epoch"].tolist() == [0, 1] and len(res.qualities) == 0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("2369 18.01 34.2 108.9 380.0 1 2 3 0 0\n", r"r.nav: line 1: expected 11 columns \(week, sow, .*\), found 10"),
        ("# c\n" + GOOD + "2369 18.02 34.2 108.9 abc 1 2 3 0 0 0\n",
         r"r.nav: line 3, column 5 \(h\): expected a number, found 'abc'"),
        ("2369 18.01 nan 108.9 380 1 2 3 0 0 0\n", r"r.nav: line 1, column 3 \(lat\): expected a finite number"),
        ("2369 17.00 34.2 108.9 380 1 2 3 0 0 0\n",
         r"r.nav: line 1, field sow: time 17.000000 s of week is outside the run"),
        ("2369 18.01 34.2 108.9 380 1 2 3 0 0 0\n# comment\n2369 99.0 34.2 108.9 380 1 2 3 0 0 0\n",
         r"line 3, field sow: time 99.000000 s of week is outside the run"),
        ("2369 18.01 340.2 108.9 380 1 2 3 0 0 0\n", r"r.nav: line 1, column 3 \(lat\): 340.2 is beyond what the ICD"),
        ("# only a comment\n", r"r.nav: no data line in the .nav result"),
    ],
)
def test_malformed_results_name_file_line_and_field(tmp_path, text, message):
    p = tmp_path / "r.nav"
    p.write_text(text)
    with pytest.raises(NavFileError, match=message):
        read_nav_result(p, CLOCK, duration_ns=60 * 10**9)


def test_std_file(tmp_path):
    nav = tmp_path / "r.nav"
    nav.write_text(GOOD)
    std = tmp_path / "s.txt"
    std.write_text("18.010000000 1 2 3 0.1 0.2 0.3 0.5 0.6 0.7 99 99\n18.5 1 1 1 1 1 1 1 1 1\n")
    q = read_nav_result(nav, CLOCK, std=std).qualities
    assert len(q) == 1 and q["t_ns"][0] == 10_000_000  # the line at no epoch is left out
    assert np.allclose(q["sigma_pos"][0], [2, 1, 3]) and np.allclose(q["sigma_vel"][0], [0.2, 0.1, 0.3])
    assert np.allclose(np.degrees(q["sigma_att"][0]), [0.7, 0.6, 0.5])  # heading, pitch, roll
    std.write_text("18.010000000 1 2 -3 0.1 0.2 0.3 0.5 0.6 0.7\n")
    with pytest.raises(NavFileError, match=r"s.txt: line 1, column 4 \(sigma_pos_d\): a standard deviation is neg"):
        read_nav_result(nav, CLOCK, std=std)
    with pytest.raises(NavFileError, match=r"missing.txt: STD file not found"):
        read_nav_result(nav, CLOCK, std=tmp_path / "missing.txt")
    with pytest.raises(NavFileError, match=r"/dev/zero: is a character device, not an STD file \(a regular file of at "
                       r"most 256 MiB\)"):
        read_nav_result(nav, CLOCK, std="/dev/zero")
