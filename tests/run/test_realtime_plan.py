"""The real-time plan: one plan for the whole run (the windows joined, so the emission
loop never leaves its loop between windows), each window's emissions and end kept."""

from __future__ import annotations

import numpy as np

from bench.frames import CanBatch, CanFrame, SerialBatch, SerialChunk
from bench.run.realtime_plan import EMIT_CAN, EMIT_GNSS, EMIT_IMU, join_plans, plan_emissions
from bench.run.traffic import Traffic


def _window(t0: int, n_can: int, n_imu: int) -> Traffic:
    can = CanBatch.from_frames([CanFrame(t0 + 10_000_000 * (i + 1), 0x100 + i, bytes([i]) * 8) for i in range(n_can)])
    imu = SerialBatch.from_chunks([SerialChunk(t0 + 1_000_000 * (i + 1), bytes([0xA0 + i]) * 40) for i in range(n_imu)])
    return Traffic(can, imu, SerialBatch.empty(), np.zeros(0))


def _emissions(plan) -> list[tuple[int, int, bytes]]:
    """(time, link, payload bytes) of every emission of a plan, in order."""
    out = []
    for t, kind, i in zip(plan.times, plan.kinds, plan.index, strict=True):
        item = (plan.can, plan.imu, plan.gnss)[kind][i]
        out.append((t, kind, item.data if kind == EMIT_CAN else item))
    return out


def test_joined_windows_keep_every_emission_in_order_with_the_windows_ends():
    w1, w2, w3 = _window(0, 3, 25), _window(100_000_000, 5, 12), _window(200_000_000, 0, 7)
    plans = [plan_emissions(w, 460_800, 115_200) for w in (w1, w2, w3)]
    joined = join_plans([(100_000_000, plans[0]), (200_000_000, plans[1]), (300_000_000, plans[2])])
    assert _emissions(joined) == _emissions(plans[0]) + _emissions(plans[1]) + _emissions(plans[2])
    sizes = [len(p.times) for p in plans]
    assert joined.ends == [sizes[0], sizes[0] + sizes[1], sum(sizes)]
    assert joined.window_t1 == [100_000_000, 200_000_000, 300_000_000]
    assert len(joined.can) == 8 and len(joined.imu) == len(plans[0].imu) + len(plans[1].imu) + len(plans[2].imu)
    assert set(joined.kinds) <= {EMIT_CAN, EMIT_IMU, EMIT_GNSS}


def test_a_single_window_plan_has_no_ends_and_joining_none_gives_an_empty_plan():
    plan = plan_emissions(_window(0, 2, 3), 460_800, 115_200)
    assert plan.ends == [] and plan.window_t1 == []
    empty = join_plans([])
    assert empty.times == [] and empty.ends == [] and empty.window_t1 == []
