"""The receiver alone on the same run (``receiver.*``, ``versus_receiver.*``) and the along-
and cross-track quantities, on recordings written by hand with errors the tests know
exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.scoring.data import DutDataError, NoDataError, load_run
from bench.scoring.metrics import METRICS, Scorer
from bench.scoring.windows import WindowSpec
from bench.sensors.bds import BDS_DTYPE
from tests.scoring.helpers import drive, nav_of, segments_of, truth_of, write_recording

ALL = WindowSpec("all")
OPEN = WindowSpec("open", gnss=("open",))  # helpers.drive: 0-50 s open, 50-100 s blocked


@pytest.fixture(scope="module")
def traj():
    return drive(speed=10.0, duration=100.0)  # north at 10 m/s


def _receiver(errors: np.ndarray, fix: np.ndarray | None = None) -> np.ndarray:
    """One receiver epoch per second, 0..N-1 s, with the given E N U errors."""
    n = len(errors)
    rec = np.zeros(n, dtype=BDS_DTYPE)
    rec["t_ns"] = np.arange(n, dtype=np.int64) * 1_000_000_000
    rec["fix_quality"] = 1 if fix is None else fix
    rec["error_enu"] = errors
    rec["error_enu"][rec["fix_quality"] == 0] = np.nan
    return rec


def _scorer(tmp_path, traj, *, pos=(0.3, 0.4, 0.0), receiver=None, name="r.mcap", valid=1):
    t = np.arange(0, 100_000_000_001, 10_000_000)
    nav = nav_of(traj, t, pos_enu=pos)
    nav["valid"] = valid
    path = write_recording(tmp_path / name, truth=truth_of(traj), nav=nav, segments=segments_of(traj),
                           receiver=receiver)
    return Scorer(load_run(path))


def test_catalogue():
    assert METRICS["receiver.position.rms"].dimension == "length" and METRICS["receiver.position.rms"].unit == "m"
    assert METRICS["versus_receiver.position.rms"].dimension == "dimensionless"
    assert "receiver.horizontal.cep95" in METRICS and "versus_receiver.horizontal.cep95" in METRICS
    assert "versus_receiver.vertical.mean" not in METRICS and "receiver.position.growth" not in METRICS
    assert METRICS["accuracy.along_track.mean"].dimension == "length"
    assert "accuracy.cross_track.p95" in METRICS


def test_receiver_statistics_over_its_fixes_in_the_window(tmp_path, traj):
    err = np.tile([1.0, 2.0, 2.0], (101, 1))  # 3 m in 3-D in the open stretch
    err[50:] = [30.0, 40.0, 0.0]  # 50 m in the tunnel from 50 s (the open window, [0, 50 s), leaves them out)
    fix = np.ones(101, np.uint8)
    fix[10:20] = 0  # ten epochs without a fix: not part of the receiver's figures
    s = _scorer(tmp_path, traj, receiver=_receiver(err, fix))
    v = s.metric("receiver.position.rms", OPEN)
    assert v.value == pytest.approx(3.0) and v.details["fixes"] == 50 - 10
    assert s.metric("receiver.horizontal.cep95", OPEN).value == pytest.approx(math.sqrt(5.0))
    assert s.metric("receiver.vertical.mean", OPEN).value == pytest.approx(2.0)
    assert s.metric("receiver.north.max", OPEN).value == pytest.approx(2.0)
    everything = s.metric("receiver.position.max", ALL).value
    assert everything == pytest.approx(50.0)


def test_the_dut_over_the_receiver_on_the_same_window(tmp_path, traj):
    err = np.tile([1.0, 2.0, 2.0], (101, 1))
    s = _scorer(tmp_path, traj, pos=(0.3, 0.4, 0.0), receiver=_receiver(err))
    v = s.metric("versus_receiver.position.rms", OPEN)
    assert v.value == pytest.approx(0.5 / 3.0, rel=1e-6)
    assert v.details["dut"] == pytest.approx(0.5) and v.details["receiver"] == pytest.approx(3.0)
    worse = _scorer(tmp_path, traj, pos=(6.0, 0.0, 0.0), receiver=_receiver(err), name="w.mcap")
    assert worse.metric("versus_receiver.horizontal.rms", OPEN).value == pytest.approx(6.0 / math.sqrt(5.0))


def test_without_a_receiver_or_a_fix_the_bench_cannot_judge(tmp_path, traj):
    none = _scorer(tmp_path, traj, receiver=None)
    with pytest.raises(NoDataError, match="no receiver truth"):
        none.metric("receiver.position.rms", ALL)
    with pytest.raises(NoDataError, match="no receiver truth"):
        none.metric("versus_receiver.position.rms", ALL)
    blind = _scorer(tmp_path, traj, receiver=_receiver(np.ones((101, 3)), np.zeros(101, np.uint8)), name="b.mcap")
    with pytest.raises(NoDataError, match="no fix in window"):
        blind.metric("receiver.position.rms", ALL)
    perfect = _scorer(tmp_path, traj, receiver=_receiver(np.zeros((101, 3))), name="p.mcap")
    assert perfect.metric("receiver.position.rms", ALL).value == 0.0
    with pytest.raises(NoDataError, match="ratio to it is undefined"):
        perfect.metric("versus_receiver.position.rms", ALL)


def test_a_dut_that_flags_the_window_invalid_fails_the_ratio_not_passes_it(tmp_path, traj):
    """No valid epoch: the DUT's own failure (FAIL), never a ratio that looks small."""
    s = _scorer(tmp_path, traj, receiver=_receiver(np.tile([1.0, 2.0, 2.0], (101, 1))), name="i.mcap", valid=0)
    with pytest.raises(DutDataError, match="invalid"):
        s.metric("versus_receiver.position.rms", OPEN)


def test_the_overview_shows_the_receiver_only_for_a_run_with_one(tmp_path, traj):
    err = np.tile([1.0, 2.0, 2.0], (101, 1))
    with_rx = _scorer(tmp_path, traj, receiver=_receiver(err)).overview()["all"]
    assert with_rx["receiver.position.rms"] == pytest.approx(3.0)
    assert with_rx["versus_receiver.position.rms"] == pytest.approx(0.5 / 3.0, rel=1e-6)
    assert "receiver.position.rms" not in _scorer(tmp_path, traj, name="n.mcap").overview()["all"]


@pytest.mark.parametrize(
    ("heading", "pos", "along", "cross"),
    [
        (0.0, (1.0, -2.0, 0.0), -2.0, 1.0),  # north: behind by 2 m, 1 m to the right (east)
        (90.0, (1.0, -2.0, 0.0), 1.0, 2.0),  # east: 1 m ahead, 2 m to the right (south)
        (180.0, (0.0, 3.0, 5.0), -3.0, 0.0),  # south: a northward error is behind; height plays no part
    ],
)
def test_along_and_cross_track_follow_the_true_heading(tmp_path, heading, pos, along, cross):
    tr = drive(speed=10.0, duration=100.0, heading_deg=heading)
    s = _scorer(tmp_path, tr, pos=pos)
    assert s.metric("accuracy.along_track.mean", ALL).value == pytest.approx(along, abs=1e-6)
    assert s.metric("accuracy.cross_track.mean", ALL).value == pytest.approx(cross, abs=1e-6)
    assert s.metric("accuracy.cross_track.max", ALL).value == pytest.approx(abs(cross), abs=1e-6)
