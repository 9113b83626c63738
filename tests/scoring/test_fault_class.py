"""The odometer fault-class metrics (faults.class_correct, faults.class_wrong): declared
class of each window and event, reported class from NAV_QUALITY byte 28, by hand."""

from __future__ import annotations

import numpy as np
import pytest

from bench.faults.schedule import FaultWindow
from bench.faults.sensor_kinds import ODOMETER_KINDS
from bench.scoring.data import NoDataError, load_run
from bench.scoring.faults import (
    ODOMETER_FAULT_CLASSES,
    FaultAnalysis,
    FaultSettings,
    analyse_faults,
    declared_classes,
    reported_class,
)
from bench.scoring.metrics import METRICS, Scorer
from bench.scoring.windows import WindowSpec, resolve_window
from bench.topics import NAV_QUALITY_DTYPE
from bench.wire import icd
from tests.scoring.helpers import drive, nav_of, quality_of, segments_of, truth_of, write_recording

S = 1_000_000_000
ALL = WindowSpec("all")
END_S = 100


def _w(i: int, kind: str, start_s: float, end_s: float, target: str = "odometer", layer: str = "sensor"):
    return FaultWindow(i, layer, target, kind, round(start_s * S), round(end_s * S))


def _quality() -> tuple[np.ndarray, np.ndarray]:
    """Quality records at 10 Hz over 0..100 s, no flag set; and their times in s."""
    t = np.arange(0, END_S * S + 1, 100_000_000, dtype=np.int64)
    q = np.zeros(len(t), dtype=NAV_QUALITY_DTYPE)
    q["t_ns"] = q["rx_ns"] = t
    return q, t / S


def _report(q: np.ndarray, ts: np.ndarray, a: float, b: float, cls: int, bit: int = 1, *, excluded: bool = False):
    """The DUT flags sensor ``bit`` (detected, or excluded) through [a, b) s with class ``cls``."""
    on = (ts >= a) & (ts < b)
    q["excluded" if excluded else "fault_detected"][on] |= bit
    q["odo_fault_class"][on] = cls


def _analyse(faults, q, *, flag=None, targets=(), grace_s: float = 0.0) -> FaultAnalysis:
    window = resolve_window(ALL, (0, END_S * S))
    return analyse_faults(
        faults, q, None, window, FaultSettings(grace_ns=round(grace_s * S)), flag=flag, targets=targets
    )


def _by_id(fa: FaultAnalysis) -> dict[int, tuple[int | None, int | None, bool | None]]:
    return {w.id: (w.declared_class, w.reported_class, w.class_ok) for w in fa.outcomes}


# -- the class table ---------------------------------------------------------------------
def test_class_table_is_the_icds_and_covers_every_odometer_kind():
    assert set(ODOMETER_FAULT_CLASSES) == set(ODOMETER_KINDS)
    assert ODOMETER_FAULT_CLASSES["idling"] == icd.ODO_FAULT_LONGITUDINAL
    assert ODOMETER_FAULT_CLASSES["sliding"] == icd.ODO_FAULT_LONGITUDINAL
    assert ODOMETER_FAULT_CLASSES["no_output"] == icd.ODO_FAULT_LONGITUDINAL
    assert ODOMETER_FAULT_CLASSES["sideslip"] == icd.ODO_FAULT_LATERAL
    assert ODOMETER_FAULT_CLASSES["bump"] == icd.ODO_FAULT_VERTICAL


def test_metrics_registered_like_the_other_fault_aggregates():
    m = METRICS["faults.class_correct"]
    assert (m.family, m.dimension, m.unit) == ("faults", "dimensionless", "%")
    assert m.options == METRICS["faults.detection_rate"].options
    m = METRICS["faults.class_wrong"]
    assert (m.family, m.dimension, m.unit) == ("faults", "count", "1")


# -- declared class ----------------------------------------------------------------------
def test_declared_class_of_single_windows_from_their_kind():
    faults = [_w(0, "idling", 10, 15), _w(1, "sliding", 20, 25), _w(2, "no_output", 30, 35)]
    faults += [_w(3, "sideslip", 40, 45), _w(4, "bump", 50, 51)]
    got = {w.id: c for w, c in declared_classes(faults).items()}
    assert got == {0: 1, 1: 1, 2: 1, 3: 2, 4: 3}


def test_overlapping_windows_are_one_event_of_the_strongest_class():
    faults = [
        # S002's 540-550 s: sideslip and idling on the same window -> both lateral
        _w(0, "sideslip", 10, 20),
        _w(1, "idling", 10, 20),
        # idling overlapping a later bump -> both vertical
        _w(2, "idling", 30, 36),
        _w(3, "bump", 35, 37),
        # a chain: sliding 50-55 overlaps sideslip 54-58 which overlaps idling 57-60
        _w(4, "sliding", 50, 55),
        _w(5, "sideslip", 54, 58),
        _w(6, "idling", 57, 60),
        # touching is not overlapping ([start, end) windows): 60-62 is its own event
        _w(7, "idling", 60, 62),
        # only longitudinal windows overlapping stay longitudinal
        _w(8, "idling", 70, 75),
        _w(9, "no_output", 72, 78),
    ]
    got = {w.id: c for w, c in declared_classes(faults).items()}
    assert got == {0: 2, 1: 2, 2: 3, 3: 3, 4: 2, 5: 2, 6: 2, 7: 1, 8: 1, 9: 1}


def test_lateral_and_vertical_in_one_event_take_the_first_to_start_lateral_on_a_tie():
    bump_first = [_w(0, "bump", 10, 20), _w(1, "sideslip", 12, 18), _w(2, "idling", 5, 15)]
    assert {w.id: c for w, c in declared_classes(bump_first).items()} == {0: 3, 1: 3, 2: 3}
    slip_first = [_w(0, "bump", 12, 20), _w(1, "sideslip", 10, 18), _w(2, "idling", 5, 15)]
    assert {w.id: c for w, c in declared_classes(slip_first).items()} == {0: 2, 1: 2, 2: 2}
    together = [_w(0, "bump", 10, 20), _w(1, "sideslip", 10, 12)]
    assert {w.id: c for w, c in declared_classes(together).items()} == {0: 2, 1: 2}


def test_only_odometer_sensor_windows_have_a_class():
    faults = [
        _w(0, "dropout", 10, 20, target="doppler"),
        _w(1, "bias_step", 10, 20, target="imu"),
        _w(2, "drop", 10, 20, target="can:ODOMETER", layer="wire"),
        _w(3, "idling", 10, 20, target="odometer_left"),
    ]
    assert {w.id: c for w, c in declared_classes(faults).items()} == {3: 1}


# -- reported class ----------------------------------------------------------------------
def test_reported_class_most_frequent_nonzero_first_on_a_tie():
    assert reported_class(np.array([], dtype=np.uint8)) == 0
    assert reported_class(np.array([0, 0, 0], dtype=np.uint8)) == 0
    assert reported_class(np.array([0, 0, 0, 2, 2, 1], dtype=np.uint8)) == 2  # zeros do not count
    assert reported_class(np.array([1, 3, 3, 1], dtype=np.uint8)) == 1  # tie: 1 came first
    assert reported_class(np.array([3, 1, 1, 3, 2], dtype=np.uint8)) == 3  # tie: 3 came first
    assert reported_class(np.array([2, 1, 1], dtype=np.uint8)) == 1


# -- per window and aggregates -----------------------------------------------------------
def test_correct_wrong_and_missed_windows():
    q, ts = _quality()
    faults = [
        _w(0, "idling", 10, 15),  # right: class 1 reported
        _w(1, "sideslip", 30, 35),  # wrong: class 1 reported for a lateral fault
        _w(2, "bump", 50, 52),  # missed: class wrong (reported 0)
        _w(3, "sliding", 70, 75),  # detected but no class given: 0, wrong
    ]
    _report(q, ts, 10.5, 15.0, 1)
    _report(q, ts, 30.2, 35.0, 1)
    q["odo_fault_class"][(ts >= 50) & (ts < 52)] = 3  # a class without the flag does not count
    _report(q, ts, 70.3, 75.0, 0)
    fa = _analyse(faults, q)
    assert _by_id(fa) == {0: (1, 1, True), 1: (2, 1, False), 2: (3, 0, False), 3: (1, 0, False)}
    assert fa.value("class_correct") == pytest.approx(1 / 4)
    assert fa.value("class_wrong") == 3.0
    assert fa.value("missed") == 1.0  # the other aggregates are unchanged


def test_reported_class_majority_and_tie_within_a_window():
    q, ts = _quality()
    faults = [_w(0, "sideslip", 10, 20), _w(1, "idling", 30, 40), _w(2, "bump", 50, 54)]
    # window 0: 1 for 2 s, then 2 for 6 s: majority lateral, right
    _report(q, ts, 10.0, 12.0, 1)
    _report(q, ts, 12.0, 18.0, 2)
    # window 1: 3 for 2 s then 1 for 2 s: a tie, 3 came first: wrong
    _report(q, ts, 30.0, 32.0, 3)
    _report(q, ts, 32.0, 34.0, 1)
    # window 2: 1 for 1 s then 3 for 1 s: a tie, 1 came first: wrong
    _report(q, ts, 50.0, 51.0, 1)
    _report(q, ts, 51.0, 52.0, 3)
    fa = _analyse(faults, q)
    assert _by_id(fa) == {0: (2, 2, True), 1: (1, 3, False), 2: (3, 1, False)}
    assert fa.value("class_correct") == pytest.approx(1 / 3)
    assert fa.value("class_wrong") == 2.0


def test_overlapping_sideslip_and_idling_both_declared_lateral():
    q, ts = _quality()
    faults = [_w(0, "sideslip", 40, 50), _w(1, "idling", 40, 50), _w(2, "bump", 70, 71), _w(3, "idling", 70.5, 73)]
    _report(q, ts, 40.3, 50.0, 2)
    _report(q, ts, 70.1, 71.0, 3)
    _report(q, ts, 71.0, 71.5, 1)  # the idling window sees 3 for 0.5 s, then 1 for 0.5 s: 3 first
    fa = _analyse(faults, q)
    assert _by_id(fa) == {0: (2, 2, True), 1: (2, 2, True), 2: (3, 3, True), 3: (3, 3, True)}
    assert fa.value("class_correct") == 1.0
    assert fa.value("class_wrong") == 0.0
    # a DUT that calls the S002 event longitudinal is wrong on both of its windows
    q2, _ = _quality()
    _report(q2, ts, 40.3, 50.0, 1)
    _report(q2, ts, 70.1, 73.0, 3)
    fa = _analyse(faults, q2)
    assert _by_id(fa)[0] == (2, 1, False) and _by_id(fa)[1] == (2, 1, False)
    assert fa.value("class_correct") == pytest.approx(2 / 4)


def test_class_follows_the_chosen_flag_and_the_grace():
    q, ts = _quality()
    faults = [_w(0, "bump", 10, 12)]
    _report(q, ts, 12.5, 13.0, 3)  # after the window, within a 1 s grace
    assert _by_id(_analyse(faults, q))[0] == (3, 0, False)
    assert _by_id(_analyse(faults, q, grace_s=1.0))[0] == (3, 3, True)
    q2, _ = _quality()
    _report(q2, ts, 10.2, 12.0, 3, excluded=True)  # excluded, never flagged detected
    assert _by_id(_analyse(faults, q2))[0] == (3, 0, False)
    assert _by_id(_analyse(faults, q2, flag="excluded"))[0] == (3, 3, True)
    assert _by_id(_analyse(faults, q2, flag="either"))[0] == (3, 3, True)
    # another sensor's bit does not carry the odometer's class
    q3, _ = _quality()
    _report(q3, ts, 10.2, 12.0, 3, bit=2)
    assert _by_id(_analyse(faults, q3))[0] == (3, 0, False)


def test_non_odometer_windows_are_left_out():
    q, ts = _quality()
    faults = [
        _w(0, "idling", 10, 15),
        _w(1, "dropout", 30, 35, target="doppler"),  # detected, no class byte
        _w(2, "outage", 50, 60, target="bds"),  # missed
    ]
    _report(q, ts, 10.2, 15.0, 1)
    _report(q, ts, 30.2, 35.0, 0, bit=2)
    fa = _analyse(faults, q)
    assert _by_id(fa) == {0: (1, 1, True), 1: (None, None, None), 2: (None, None, None)}
    assert fa.value("windows") == 3.0
    assert fa.value("class_correct") == 1.0  # not 1/3: the Doppler and BDS windows do not count
    assert fa.value("class_wrong") == 0.0
    json = {w["id"]: w for w in fa.details()["windows"]}
    assert json[0]["declared_class"] == 1 and json[0]["reported_class"] == 1 and json[0]["class_ok"] is True
    assert json[1]["declared_class"] is None and json[1]["reported_class"] is None and json[1]["class_ok"] is None


def test_no_odometer_window_is_no_data():
    q, ts = _quality()
    faults = [_w(0, "idling", 10, 15), _w(1, "dropout", 30, 35, target="doppler")]
    _report(q, ts, 30.2, 35.0, 0, bit=2)
    fa = _analyse(faults, q, targets=("doppler",))
    assert fa.value("detection_rate") == 1.0
    for name in ("class_correct", "class_wrong"):
        with pytest.raises(NoDataError, match="odometer"):
            fa.value(name)
    with pytest.raises(NoDataError, match="odometer"):
        _analyse([], q).value("class_correct")


# -- through the scorer and a recording --------------------------------------------------
def test_class_metrics_from_a_recording(tmp_path):
    traj = drive(speed=10.0, duration=100.0)
    t = np.arange(0, END_S * S + 1, 10_000_000)
    ts = t / S
    nav = nav_of(traj, t)
    q = quality_of(nav)
    faults = [
        _w(0, "idling", 20, 25),
        _w(1, "sideslip", 40, 50),
        _w(2, "idling", 40, 50),
        _w(3, "bump", 70, 71),
        _w(4, "dropout", 80, 82, target="doppler"),
    ]
    _report(q, ts, 20.3, 25.0, 1)
    _report(q, ts, 40.3, 50.0, 2)
    _report(q, ts, 80.0, 82.0, 0, bit=2)  # the bump is missed
    path = write_recording(
        tmp_path / "r.mcap", truth=truth_of(traj), nav=nav, quality=q, faults=faults, segments=segments_of(traj)
    )
    s = Scorer(load_run(path))
    v = s.metric("faults.class_correct", ALL)
    assert v.value == pytest.approx(3 / 4)
    assert s.metric("faults.class_wrong", ALL).value == 1.0
    rows = {w["id"]: (w["declared_class"], w["reported_class"], w["class_ok"]) for w in v.details["windows"]}
    assert rows == {0: (1, 1, True), 1: (2, 2, True), 2: (2, 2, True), 3: (3, 0, False), 4: (None, None, None)}
    with pytest.raises(NoDataError, match="odometer"):
        s.metric("faults.class_correct", ALL, {"target": ("doppler",)})


def _quality_flags(times_s, flagged):
    from bench.topics import NAV_QUALITY_DTYPE

    q = np.zeros(len(times_s), NAV_QUALITY_DTYPE)
    q["t_ns"] = np.round(np.asarray(times_s) * 1e9).astype(np.int64)
    q["fault_detected"] = np.where(flagged, 1, 0)
    return q


@pytest.mark.parametrize(
    ("flag_from", "flag_to", "expected"),
    [
        (10.0, 12.0, 0),  # detected inside the window, dropped within the grace
        (10.0, 30.0, 1),  # latched: held on long after the window and its grace
        (0.0, 30.0, 2),  # set before the criterion window begins, held into it and past the fault
        (20.0, 21.0, 1),  # raised outside every window
    ],
)
def test_false_alarms_count_latched_and_inherited_flags(flag_from, flag_to, expected):
    from bench.faults.schedule import FaultWindow
    from bench.scoring.faults import FaultSettings, analyse_faults
    from bench.scoring.windows import Window, WindowSpec

    t = np.arange(0.0, 40.0, 0.1)
    q = _quality_flags(t, (t >= flag_from) & (t < flag_to))
    w = FaultWindow(id=0, layer="sensor", target="odometer", kind="idling", start_ns=10_000_000_000,
                    end_ns=11_000_000_000)
    crit = Window(WindowSpec(name="from 5 s", start_ns=5_000_000_000), np.array([[5_000_000_000, 40_000_000_000]]),
                  40_000_000_000)
    out = analyse_faults([w], q, None, crit, FaultSettings(grace_ns=1_000_000_000))
    assert len(out.false_alarms) == expected, out.false_alarms
