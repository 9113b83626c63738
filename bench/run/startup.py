"""The lockstep start-up per the ICD, and the alive counters it advances.

An external DUT may not listen yet when the bench starts it, so the first step is sent in
rounds, every 100 ms, until the DUT answers with DUT_READY (:meth:`ExternalDut.start
<bench.run.external.ExternalDut.start>`): its serial bytes and its one-time CAN frames
(sensor messages, BENCH_CMD) once, before the first round; each round its BENCH_EPOCH
(the UTC of bench time zero, which a DUT that starts listening late still needs before
its first BENCH_TIME) and its BENCH_TIME, last. Every transmission is a new frame (ICD 1:
the alive counter +1 for every transmission of a message): round ``i`` carries each
counter advanced by ``i``, and every later BENCH_EPOCH and BENCH_TIME of the run by the
number of extra rounds (:class:`AliveShift`). So every frame with time <= T goes before
BENCH_TIME(T) (ICD 6), BENCH_EPOCH(0) included, and a DUT sees each counter run +1 modulo
16 whatever the start-up took.

A replay re-emits a recording's frames (:func:`drop_handshake_copies` keeps one round of
its start-up and moves the counters after it back), so its own start-up continues them.
The counter nibble is advanced without touching anything else: a frame whose CRC a wire
fault broke keeps exactly that error.
"""

from __future__ import annotations

import numpy as np

from bench.frames import CanBatch
from bench.run.traffic import BENCH_TIME_ID, Traffic
from bench.wire.can import codec
from bench.wire.crc import crc8_can_rows

__all__ = ["EPOCH_ID", "REPEATED_IDS", "advance_alive", "AliveShift", "split_first_step", "drop_handshake_copies"]

EPOCH_ID = codec("BENCH_EPOCH").frame_id
#: The messages of the first step repeated in every start-up round (BENCH_TIME last).
REPEATED_IDS = (EPOCH_ID, BENCH_TIME_ID)


def advance_alive(can: CanBatch, ids: tuple[int, ...], shift: int) -> CanBatch:
    """``can`` with the alive counter (byte 6, low nibble) of every frame whose identifier
    is in ``ids`` advanced by ``shift`` modulo 16 and its CRC-8 (byte 7) made again, with
    the same error as before (a correct CRC stays correct, a broken one broken alike)."""
    if not len(can) or not shift % 16:
        return can
    return _advance_rows(can, np.flatnonzero(np.isin(can.can_id, ids)), shift)


def _advance_rows(can: CanBatch, rows: np.ndarray, shift: int) -> CanBatch:
    rows = rows[can.length[rows] == 8]
    if rows.size == 0 or not shift % 16:
        return can
    data = can.data.copy()
    ids = can.can_id[rows]
    error = data[rows, 7] ^ crc8_can_rows(ids, data[rows])
    byte6 = data[rows, 6].astype(np.int64)
    data[rows, 6] = (byte6 & 0xF0) | ((byte6 & 0x0F) + shift) % 16
    data[rows, 7] = crc8_can_rows(ids, data[rows]) ^ error
    return CanBatch(can.t_ns, can.can_id, data, can.length, can.fd)


class AliveShift:
    """The counter advance of the run's BENCH_EPOCH and BENCH_TIME frames after its
    start-up (``rounds - 1``: the encoder counted one transmission of the first step)."""

    def __init__(self) -> None:
        self.shift = 0

    def started(self, rounds: int) -> None:
        """The start-up took ``rounds`` rounds."""
        self.shift = max(rounds - 1, 0) % 16

    def apply(self, traffic: Traffic) -> Traffic:
        """``traffic`` with those counters advanced."""
        if not self.shift:
            return traffic
        return Traffic(advance_alive(traffic.can, REPEATED_IDS, self.shift), traffic.imu, traffic.gnss, traffic.events)


def split_first_step(traffic: Traffic, t_first: int) -> tuple[Traffic, Traffic]:
    """The first step's traffic (time <= ``t_first``) and the rest of the window."""

    def cut(batch):
        n = int(np.searchsorted(batch.t_ns, t_first, side="right"))
        return batch.take(np.arange(n)), batch.take(np.arange(n, len(batch)))

    (c0, c1), (i0, i1), (g0, g1) = cut(traffic.can), cut(traffic.imu), cut(traffic.gnss)
    return Traffic(c0, i0, g0, traffic.events[:0]), Traffic(c1, i1, g1, traffic.events)


def drop_handshake_copies(can: CanBatch) -> CanBatch:
    """A recorded run's frames with one round of its start-up kept.

    The rounds repeat the first BENCH_TIME (and the BENCH_EPOCH at its time): the repeats
    of a message are its frames at the first one's time with the same bytes 0..5 (and
    lockstep bit). They are dropped, and when they advanced the counter (recordings since
    ICD start-up rounds; older ones repeated the frame byte for byte) the message's later
    frames are moved back by as many, so the kept traffic counts one transmission each.
    """
    bt = np.flatnonzero(can.can_id == BENCH_TIME_ID)
    if bt.size < 2:
        return can
    t_first = can.t_ns[bt[0]]
    drop = np.zeros(len(can), bool)
    shifts: dict[int, int] = {}
    for cid in REPEATED_IDS:
        rows = np.flatnonzero(can.can_id == cid)
        at = rows[can.t_ns[rows] == t_first]
        if at.size < 2:
            continue
        first = can.data[at[0]]
        same = np.all(can.data[at[1:], :6] == first[:6], axis=1) & ((can.data[at[1:], 6] & 0xF0) == (first[6] & 0xF0))
        copies = at[1:][same]
        drop[copies] = True
        # every copy advanced the counter, or (older recordings) none did; the 16th copy of
        # a round-advancing start-up is byte for byte the first again, so count them all
        advanced = bool(np.any(np.any(can.data[copies] != first, axis=1)))
        shifts[cid] = int(copies.size) if advanced else 0
    kept = can.take(~drop)
    for cid, k in shifts.items():
        rows = np.flatnonzero(kept.can_id == cid)[1:]  # the frames after the kept first one
        kept = _advance_rows(kept, rows, -k)
    return kept
