"""A real-time window's emissions in time order, prepared before the clock starts.

CAN frames are emitted one by one at their times; the bytes of each serial line are cut
into groups by the 1 ms slot at the line's baud (:func:`bench.transport.pacing.byte_groups`),
so no byte leaves before the line could have carried it. At equal times CAN goes first,
then the IMU line, then the GNSS line. The windows of a run are joined into one plan
(:func:`join_plans`) so that the emission loop runs once over the whole run: code the
loop would run only between windows is code nobody ran for seconds, and on a virtual
machine memory left untouched for seconds is slow to touch again (measured here: about
7 us per 4 KiB page after 10 s, 0.2 us when warm), which stalled the first emissions of
every window by 1.5-5 ms.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.frames import CanFrame
from bench.run.traffic import Traffic
from bench.transport.pacing import byte_groups, byte_time_ns

__all__ = ["RealtimePlan", "plan_emissions", "join_plans", "EMIT_CAN", "EMIT_IMU", "EMIT_GNSS"]

#: Link of an emission.
EMIT_CAN, EMIT_IMU, EMIT_GNSS = 0, 1, 2


@dataclass
class RealtimePlan:
    """One window's emissions in time order: the link of each (:data:`EMIT_CAN`,
    :data:`EMIT_IMU`, :data:`EMIT_GNSS`), its due time and its index into ``can`` (frames)
    or ``imu``/``gnss`` (byte groups paced at the line's baud). A joined plan
    (:func:`join_plans`) has the windows' ends: emissions ``[ends[w - 1], ends[w])`` are
    window ``w``'s, which ends at bench time ``window_t1[w]``; a plan of one window has
    none."""

    kinds: list[int]
    times: list[int]
    index: list[int]
    can: list[CanFrame]
    imu: list[bytes]
    gnss: list[bytes]
    ends: list[int] = field(default_factory=list)
    window_t1: list[int] = field(default_factory=list)


def plan_emissions(traffic: Traffic, imu_baud: int, gnss_baud: int) -> RealtimePlan:
    """The emissions of ``traffic`` in time order (plain lists, for the emission loop)."""
    groups: list[list[bytes]] = []
    parts_k = [np.full(len(traffic.can), EMIT_CAN, np.int8)]
    parts_t = [traffic.can.t_ns]
    parts_i = [np.arange(len(traffic.can))]
    for kind, batch, baud in ((EMIT_IMU, traffic.imu, imu_baud), (EMIT_GNSS, traffic.gnss, gnss_baud)):
        if len(batch):
            times, offsets = byte_groups(batch, byte_time_ns(baud))
        else:
            times, offsets = np.zeros(0, np.int64), np.zeros(1, np.int64)
        groups.append([batch.buf[offsets[g] : offsets[g + 1]].tobytes() for g in range(len(times))])
        parts_k.append(np.full(len(times), kind, np.int8))
        parts_t.append(times)
        parts_i.append(np.arange(len(times)))
    k, t, i = np.concatenate(parts_k), np.concatenate(parts_t), np.concatenate(parts_i)
    order = np.lexsort((k, t))
    return RealtimePlan(
        k[order].tolist(), t[order].tolist(), i[order].tolist(), traffic.can.frames(), groups[0], groups[1]
    )


def join_plans(windows: list[tuple[int, RealtimePlan]]) -> RealtimePlan:
    """One plan of the windows ``(t1, plan)`` in order, with their ends."""
    kinds: list[int] = []
    times: list[int] = []
    index: list[int] = []
    payloads: tuple[list, list, list] = ([], [], [])
    ends, t1s = [], []
    for t1, plan in windows:
        base = (len(payloads[EMIT_CAN]), len(payloads[EMIT_IMU]), len(payloads[EMIT_GNSS]))
        kinds += plan.kinds
        times += plan.times
        index += [i + base[k] for k, i in zip(plan.kinds, plan.index, strict=True)]
        payloads[EMIT_CAN].extend(plan.can)
        payloads[EMIT_IMU].extend(plan.imu)
        payloads[EMIT_GNSS].extend(plan.gnss)
        ends.append(len(times))
        t1s.append(int(t1))
    return RealtimePlan(kinds, times, index, *payloads, ends=ends, window_t1=t1s)
