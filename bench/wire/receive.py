"""Receivers of CAN traffic: the bench's side of DUT output, the DUT's side of bench traffic.

Both take time-stamped batches of received frames (:class:`~bench.frames.CanBatch`, ``t_ns``
the arrival in bench time), decode every message of the ICD with its vectorised codec,
and never raise on a bad frame: each one is counted by kind in a
:class:`~bench.wire.tally.Tally` and kept (bytes and reason) for the recording.

Kinds: ``unknown_id`` (identifier not in the ICD for this direction), ``length`` (wrong
DLC or FD flag), ``crc``, ``format`` (reserved bits set), ``range`` (a field outside its
allowed values); on the good frames, per message, the sequence labels of
:mod:`bench.wire.sequence`.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from functools import cache

import numpy as np

from bench.frames import CanBatch
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from bench.wire.can import DECODE_KINDS, CanCodec, codec
from bench.wire.sequence import SEQ_DUPLICATE, SEQ_KINDS, SEQ_REPEAT, SEQ_SKIP, SequenceChecker
from bench.wire.tally import Tally

__all__ = [
    "NavOutput",
    "NavReceiver",
    "BenchTrafficDecoder",
    "empty_columns",
    "DUT_OUTPUT_MESSAGES",
    "BENCH_MESSAGES",
]

#: What the DUT sends (ICD 2.2).
DUT_OUTPUT_MESSAGES = ("NAV_SOLUTION", "NAV_QUALITY", "DUT_READY")
#: What the bench sends (ICD 2.1).
BENCH_MESSAGES = ("BENCH_TIME", "BENCH_EPOCH", "BENCH_CMD", "ODOMETER", "DRIVER_INPUT", "DOPPLER")
_KEEP_PER_KIND = 64  # sequence-labelled frames kept per kind and batch (all are counted)
#: How far (time of validity) a NAV_QUALITY and its NAV_SOLUTION may be apart in what
#: has arrived: much longer than any sane DUT latency.
PAIR_WINDOW_NS = 10_000_000_000
_MAX_KEPT = 1 << 18  # solutions kept for pairing at most (a DUT whose times of validity jump around)


class _CanReceiver:
    """Grouping by identifier, checking, and sequence labelling shared by both receivers."""

    def __init__(self, names: tuple[str, ...], tally: Tally | None, stale: tuple[str, ...] = ()):
        self.tally = tally if tally is not None else Tally()
        self.codecs = {codec(n).frame_id: codec(n) for n in names}
        self.sequences = {
            c.frame_id: SequenceChecker(c.counter_modulus, c.value_mask if c.name in stale else None)
            for c in self.codecs.values()
        }
        self.frames = 0

    def _groups(self, batch: CanBatch):
        """(codec, good sub-batch, decoded values, sequence labels, their rows in ``batch``)
        of each known identifier."""
        self.frames += len(batch)
        known = np.isin(batch.can_id, np.fromiter(self.codecs, np.uint32))
        for i in np.flatnonzero(~known).tolist():
            f = batch.frame(i)
            self.tally.reject(f.t_ns, f"can:0x{f.can_id:03X}", "unknown_id", f.data, "identifier not expected here")
        for frame_id, c in self.codecs.items():
            sel = np.flatnonzero(batch.can_id == frame_id)
            if sel.size == 0:
                continue
            sub = batch.take(sel)
            values, status = c.decode(sub)
            for i in np.flatnonzero(status).tolist():
                f = sub.frame(i)
                kind = DECODE_KINDS[int(status[i])]
                self.tally.reject(f.t_ns, f"can:{c.name}", kind, f.data, f"{c.name}: bad {kind}")
            good = status == 0
            if not good.all():
                sub, sel = sub.take(good), sel[good]
                values = {k: v[good] for k, v in values.items()}
            rows = sub.with_width(c.length).data[:, : c.length]
            labels, lost = self.sequences[frame_id].check(values[c.counter_name], rows)
            self._count_labels(c, sub, labels, lost)
            yield c, sub, values, labels, sel

    def _count_labels(self, c: CanCodec, sub: CanBatch, labels: np.ndarray, lost: np.ndarray) -> None:
        for code in np.unique(labels[labels > 0]).tolist():
            idx = np.flatnonzero(labels == code)
            kind = self._label_kind(code)
            for i in idx[:_KEEP_PER_KIND].tolist():
                f = sub.frame(i)
                self.tally.reject(f.t_ns, f"can:{c.name}", kind, f.data, f"{c.name}: {SEQ_KINDS[code]} counter")
            self.tally.count(kind, idx.size - min(idx.size, _KEEP_PER_KIND))
        self.tally.count("lost", int(lost.sum()))

    def _label_kind(self, code: int) -> str:
        return SEQ_KINDS[code]


@dataclass
class NavOutput:
    """What one batch of DUT frames held, decoded."""

    solutions: np.ndarray = field(default_factory=lambda: np.zeros(0, NAV_SOLUTION_DTYPE))
    qualities: np.ndarray = field(default_factory=lambda: np.zeros(0, NAV_QUALITY_DTYPE))
    ready_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # DUT_READY times, bench ns
    ready_rx_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))


class NavReceiver(_CanReceiver):
    """The bench's receiver of DUT output: NAV_SOLUTION, NAV_QUALITY, DUT_READY.

    Counter anomalies (epoch or alive counter repeated or skipped) count as ``counter``
    (frames still handed on), exact duplicates as ``duplicate`` (dropped), epochs lost as
    ``lost``; a NAV_QUALITY whose epoch counter and time of validity match no NAV_SOLUTION
    as ``pairing``. Any other identifier is ``unknown_id``.

    Pairing is by time of validity and epoch over the whole run, in arrival order and
    whichever of the two frames comes first: a quality pairs with a solution of the same
    key as long as, when the later of the two arrives, no solution more than
    :data:`PAIR_WINDOW_NS` newer (time of validity) has arrived. So memory stays bounded
    (the solutions and waiting qualities of the last 10 s of validity), a DUT that sends a
    burst of solutions before their qualities pairs, and how the frames are cut into
    batches never changes the result. A quality still waiting for its solution is counted
    when a solution 10 s newer arrives, or at :meth:`finish` (the end of the run).
    """

    def __init__(self, tally: Tally | None = None):
        super().__init__(DUT_OUTPUT_MESSAGES, tally)
        self._solutions: dict[tuple[int, int], int] = {}  # (t_ns, epoch) -> t_ns, within the window
        self._waiting: dict[tuple[int, int], list[tuple[int, int]]] = {}  # qualities: key -> [(rx_ns, epoch)]
        self._arrived: deque[tuple[int, tuple[int, int]]] = deque()  # (t_ns, key) in arrival order, to prune
        self._newest = -(1 << 62)  # the newest time of validity among the solutions arrived

    def _label_kind(self, code: int) -> str:
        return "counter" if code in (SEQ_REPEAT, SEQ_SKIP) else SEQ_KINDS[code]

    @staticmethod
    def _records(dtype: np.dtype, values: dict[str, np.ndarray], rx_ns: np.ndarray) -> np.ndarray:
        out = np.zeros(rx_ns.shape[0], dtype)
        out["rx_ns"] = rx_ns
        for name in dtype.names:
            if name in values:
                out[name] = values[name]
        return out

    def feed(self, batch: CanBatch) -> NavOutput:
        """Decode one batch of received frames (arrival times in ``batch.t_ns``)."""
        out = NavOutput()
        sol_rows = q_rows = np.zeros(0, np.int64)
        for c, sub, values, labels, rows in self._groups(batch):
            keep = labels != SEQ_DUPLICATE
            values = {k: v[keep] for k, v in values.items()}
            rx = sub.t_ns[keep]
            if c.name == "NAV_SOLUTION":
                out.solutions, sol_rows = self._records(NAV_SOLUTION_DTYPE, values, rx), rows[keep]
            elif c.name == "NAV_QUALITY":
                out.qualities, q_rows = self._records(NAV_QUALITY_DTYPE, values, rx), rows[keep]
            else:
                out.ready_ns, out.ready_rx_ns = values["time_ns"], rx
        self._pair(out.solutions, sol_rows, out.qualities, q_rows)
        return out

    def _unpaired(self, key: tuple[int, int], rx_ns: int, epoch: int) -> None:
        self.tally.reject(
            rx_ns, "can:NAV_QUALITY", "pairing", b"", f"epoch {epoch} at {key[0]} ns matches no NAV_SOLUTION"
        )

    def _pair(self, sols: np.ndarray, sol_rows: np.ndarray, quals: np.ndarray, q_rows: np.ndarray) -> None:
        """Pair the batch's qualities and solutions in arrival order (see the class docstring)."""
        if sols.size == 0 and quals.size == 0:
            return
        window = PAIR_WINDOW_NS
        store, waiting, arrived = self._solutions, self._waiting, self._arrived
        st, se = sols["t_ns"].tolist(), sols["epoch"].tolist()
        qt, qe, qrx = quals["t_ns"].tolist(), quals["epoch"].tolist(), quals["rx_ns"].tolist()
        rows = np.concatenate([sol_rows, q_rows])
        order = np.argsort(rows, kind="stable").tolist()
        n_sol = len(st)
        newest = self._newest
        for k in order:
            if k < n_sol:
                t = st[k]
                key = (t, se[k])
                newest = max(newest, t)
                store[key] = t
                arrived.append((t, key))
                if key in waiting and newest <= t + window:
                    del waiting[key]  # every quality that waited for it pairs
            else:
                i = k - n_sol
                t = qt[i]
                key = (t, qe[i])
                if key in store and newest <= t + window:
                    continue
                waiting.setdefault(key, []).append((qrx[i], qe[i]))
        self._newest = newest
        limit = newest - window  # nothing older can pair any more
        if waiting:
            for key in [k for k in waiting if k[0] < limit]:
                for rx, ep in waiting.pop(key):
                    self._unpaired(key, rx, ep)
        while arrived and arrived[0][0] < limit:
            store.pop(arrived.popleft()[1], None)
        if len(arrived) > 4 * _MAX_KEPT:  # times of validity out of order: keep the newest
            keep = sorted(arrived)[-_MAX_KEPT:]
            arrived.clear()
            arrived.extend(keep)
            self._solutions = store = {key: t for t, key in keep}

    def finish(self) -> None:
        """The end of the run: every quality still waiting for its solution is counted
        (``pairing``); idempotent."""
        waiting, self._waiting = self._waiting, {}
        for key, items in waiting.items():
            for rx, ep in items:
                self._unpaired(key, rx, ep)


class BenchTrafficDecoder(_CanReceiver):
    """The DUT's side of the CAN bus: bench messages decoded to SI, counted by kind.

    ``feed`` returns, per message name, the decoded values of the frames (duplicates
    dropped) plus ``rx_ns``. The stale check (values frozen while the counter runs) is
    made on the messages in ``stale``: by default BENCH_TIME, whose time always moves;
    add others only where their values must change every frame. ``late_ns`` counts
    BENCH_TIME frames that arrive more than that after the time they carry.
    """

    def __init__(
        self,
        *,
        tally: Tally | None = None,
        stale: tuple[str, ...] = ("BENCH_TIME",),
        late_ns: int | None = None,
    ):
        super().__init__(BENCH_MESSAGES, tally, stale)
        self.late_ns = late_ns

    def feed(self, batch: CanBatch) -> dict[str, dict[str, np.ndarray]]:
        """Decode one batch of received frames (arrival times in ``batch.t_ns``)."""
        out: dict[str, dict[str, np.ndarray]] = {}
        for c, sub, values, labels, _rows in self._groups(batch):
            values = _columns(values, sub.t_ns, labels != SEQ_DUPLICATE)
            if self.late_ns is not None and c.name == "BENCH_TIME":
                self.tally.count("late", int(np.sum(values["rx_ns"] - values["time_ns"] > self.late_ns)))
            out[c.name] = values
        return out


def _columns(values: dict[str, np.ndarray], rx_ns: np.ndarray, keep: np.ndarray) -> dict[str, np.ndarray]:
    """The columns :meth:`BenchTrafficDecoder.feed` gives one message: the codec's decoded
    values of the frames kept, plus ``rx_ns``."""
    out = {k: v[keep] for k, v in values.items()}
    out["rx_ns"] = rx_ns[keep]
    return out


@cache
def _layout(name: str) -> tuple[tuple[str, np.dtype, tuple[int, ...]], ...]:
    c = codec(name)
    empty = CanBatch.empty(c.length)
    values, _ = c.decode(empty)
    cols = _columns(values, empty.t_ns, np.zeros(0, bool))
    return tuple((k, v.dtype, v.shape[1:]) for k, v in cols.items())


def empty_columns(name: str) -> dict[str, np.ndarray]:
    """The columns :meth:`BenchTrafficDecoder.feed` gives bench message ``name`` when no
    frame of it arrived: every field, zero-length, of the decoder's own dtype and shape
    (fresh arrays on every call: a caller may write into them).

    Raises
    ------
    KeyError
        When ``name`` is not a bench-to-DUT message (:data:`BENCH_MESSAGES`).
    """
    if name not in BENCH_MESSAGES:
        raise KeyError(f"{name!r} is not a message the bench sends; expected one of {', '.join(BENCH_MESSAGES)}")
    return {k: np.zeros((0, *shape), dtype) for k, dtype, shape in _layout(name)}
