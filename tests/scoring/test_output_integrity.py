"""The output-integrity measures of the DUT's epochs, against streams broken by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.scoring.epochs import EpochBounds
from bench.scoring.output import output_value
from bench.scoring.windows import WindowSpec, resolve_window
from tests.scoring.helpers import drive, nav_of, quality_of

S = 1_000_000_000
P = 10_000_000
END = 10 * S


@pytest.fixture(scope="module")
def traj():
    return drive(speed=10.0, duration=10.0)


@pytest.fixture
def nav(traj):
    """A healthy 100 Hz stream over 0..10 s, 2 ms late."""
    return nav_of(traj, np.arange(0, END + 1, P), latency_ns=2_000_000)


ALL = WindowSpec("all")


def value(name, nav, quality=None, bad=(), spec=ALL, bounds=None):
    window = resolve_window(spec, (0, END))
    return output_value(name, nav, quality, list(bad), window, P, bounds)


INTEGRITY = ("repeated", "out_of_order", "time_jumps", "counter_faults", "out_of_range", "missing_epochs")


def test_a_healthy_stream_has_no_integrity_fault(nav):
    for name in INTEGRITY:
        assert value(name, nav)[0] == 0, name
    assert value("quality_unmatched", nav, quality_of(nav))[0] == 0
    assert value("rate", nav)[0] == pytest.approx(100.0)
    assert value("median_rate", nav)[0] == pytest.approx(100.0)


def test_rate_counts_the_epochs_delivered_not_the_median_interval(nav):
    # the DUT stops at 6 s: the median interval is still 10 ms
    cut = nav[nav["t_ns"] < 6 * S]
    assert value("median_rate", cut)[0] == pytest.approx(100.0)
    assert value("rate", cut)[0] == pytest.approx(60.0)
    # time frozen from 6 s: epochs keep arriving, but no new time of validity
    frozen = nav.copy()
    frozen["t_ns"][frozen["t_ns"] >= 6 * S] = 6 * S
    assert value("rate", frozen)[0] == pytest.approx(60.1)


def test_time_frozen_repeats_times_of_validity(nav):
    nav["t_ns"][600:] = nav["t_ns"][600]
    n, _ = value("repeated", nav)
    assert n == len(nav) - 601
    assert value("out_of_order", nav)[0] == 0


def test_time_running_backwards_is_out_of_order(nav):
    t0 = nav["t_ns"][600]
    nav["t_ns"][600:] = 2 * t0 - nav["t_ns"][600:]
    n, det = value("out_of_order", nav)
    assert n == len(nav) - 601
    assert det["first_t_s"] == pytest.approx(5.99)
    assert value("repeated", nav)[0] == len(nav) - 601  # every one of them was delivered before


def test_forward_jump_is_seen_though_its_epochs_leave_the_window(nav):
    nav["t_ns"][600:] += 1_000_000 * S
    n, det = value("time_jumps", nav)
    assert n == 1 and det["forward"] == 1 and det["first_step_s"] == pytest.approx(1e6 + 0.01)
    # the jumped epochs arrived in the window: they are judged even on a window they left
    assert value("time_jumps", nav, spec=WindowSpec("tail", start_ns=5 * S))[0] == 1
    assert value("missing_epochs", nav)[0] == 400


def test_backward_jump_beyond_the_bound(nav):
    nav["t_ns"][600:] -= 5 * S
    n, det = value("time_jumps", nav)
    assert n == 1 and det["backward"] == 1
    # a smaller step back is out of order, not a jump
    assert value("time_jumps", nav, bounds=EpochBounds(jump_ns=10 * S))[0] == 0


def test_silence_or_a_backlog_is_not_a_jump(traj):
    t = np.arange(0, END + 1, P)
    silent = nav_of(traj, t[(t < 3 * S) | (t >= 6 * S)], latency_ns=2_000_000)  # 3 s without output
    assert value("time_jumps", silent)[0] == 0
    assert value("max_gap", silent)[0] == pytest.approx(3.01)
    stalled = nav_of(traj, t, latency_ns=2_000_000)  # stalled 3 s, then the backlog at once
    late = (t >= 3 * S) & (t < 6 * S)
    stalled["rx_ns"][late] = 6 * S
    assert value("time_jumps", stalled)[0] == 0
    assert value("latency_max", stalled)[0] == pytest.approx(3.0)


@pytest.mark.parametrize(("fault", "stuck", "other"), [("stuck", 400, 0), ("skip", 0, 400), ("reset", 0, 1)])
def test_counter_faults(nav, fault, stuck, other):
    ep = nav["epoch"].astype(np.int64)
    if fault == "stuck":
        ep[601:] = ep[600]
    elif fault == "skip":
        ep[601:] = ep[601:] + np.arange(1, len(ep) - 600)
    else:
        ep[601:] = ep[601:] - ep[601]
    nav["epoch"] = (ep % 256).astype(np.uint8)
    n, det = value("counter_faults", nav)
    assert (n, det["stuck"], det["other"]) == (stuck + other, stuck, other)
    assert det["first_at_s"] == pytest.approx(6.01)


def test_counter_follows_missing_epochs_and_jitter(traj):
    t = np.arange(0, END + 1, P)
    keep = (t < 3 * S) | (t >= 3 * S + 25 * P)  # 25 epochs lost: the counter skips 26
    nav = nav_of(traj, t)
    nav["epoch"] = (np.arange(len(t)) % 256).astype(np.uint8)
    assert value("counter_faults", nav[keep])[0] == 0
    assert value("counter_gaps", nav[keep])[0] == 25
    rng = np.random.default_rng(1)
    jittered = nav.copy()
    jittered["t_ns"] += rng.integers(-P // 5, P // 5, len(t))
    assert value("counter_faults", jittered)[0] == 0


@pytest.mark.parametrize(
    ("field", "bad", "name"),
    [
        ("lat", math.radians(95.0), "latitude"),
        ("lon", math.radians(-181.0), "longitude"),
        ("heading", 2 * math.pi, "heading"),
        ("heading", -0.01, "heading"),
        ("pitch", math.radians(91.0), "pitch"),
        ("roll", math.nan, "roll"),
        ("h", 1e6, "height"),
        ("h", -2000.0, "height"),
        ("vel_n", 1000.0, "speed"),
        ("vel_n", math.inf, "speed"),
    ],
)
def test_values_out_of_physical_range(nav, field, bad, name):
    nav[field][700:] = bad
    n, det = value("out_of_range", nav)
    assert n == len(nav) - 700 and det["by_field"] == {name: n}
    nav["valid"][700:] = 0  # flagged invalid: the DUT does not claim them
    assert value("out_of_range", nav)[0] == 0


def test_range_bounds_can_be_widened(nav):
    nav["h"][:] = 30_000.0
    assert value("out_of_range", nav)[0] == len(nav)
    assert value("out_of_range", nav, bounds=EpochBounds(height_m=(-1000.0, 40_000.0)))[0] == 0


def test_missing_quality_partners(nav):
    q = quality_of(nav)
    assert value("quality_unmatched", nav, q[:600])[0] == len(nav) - 600


def test_bad_frames_by_kind(nav):
    bad = [{"t_ns": 7 * S, "kind": "crc"}, {"t_ns": 8 * S, "kind": "crc"}, {"t_ns": 9 * S, "kind": "range"}]
    n, det = value("bad_frames", nav, bad=bad)
    assert n == 3 and det["by_kind"] == {"crc": 2, "range": 1}
