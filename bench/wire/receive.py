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

from dataclasses import dataclass, field

import numpy as np

from bench.frames import CanBatch
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from bench.wire.can import DECODE_KINDS, CanCodec, codec
from bench.wire.sequence import SEQ_DUPLICATE, SEQ_KINDS, SEQ_REPEAT, SEQ_SKIP, SequenceChecker
from bench.wire.tally import Tally

__all__ = ["NavOutput", "NavReceiver", "BenchTrafficDecoder", "DUT_OUTPUT_MESSAGES", "BENCH_MESSAGES"]

#: What the DUT sends (ICD 2.2).
DUT_OUTPUT_MESSAGES = ("NAV_SOLUTION", "NAV_QUALITY", "DUT_READY")
#: What the bench sends (ICD 2.1).
BENCH_MESSAGES = ("BENCH_TIME", "BENCH_EPOCH", "BENCH_CMD", "ODOMETER", "DRIVER_INPUT", "DOPPLER")
_KEEP_PER_KIND = 64  # sequence-labelled frames kept per kind and batch (all are counted)
_RECENT = 1024  # NAV_SOLUTIONs remembered for pairing NAV_QUALITY frames


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
    ``lost``; a NAV_QUALITY whose epoch counter and time match no NAV_SOLUTION received
    as ``pairing`` (the solution must have arrived before its quality, among the last
    1024 solutions). Any other identifier is ``unknown_id``.
    """

    def __init__(self, tally: Tally | None = None):
        super().__init__(DUT_OUTPUT_MESSAGES, tally)
        self._recent_t = np.zeros(0, np.int64)  # times of validity of the last NAV_SOLUTIONs
        self._recent_epoch = np.zeros(0, np.int64)
        self._recent_seq = np.zeros(0, np.int64)  # their numbers in arrival order
        self._n_solutions = 0

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
        paired = self._pair(out.solutions, sol_rows, out.qualities, q_rows)
        for i in np.flatnonzero(~paired).tolist():
            q = out.qualities[i]
            self.tally.reject(
                int(q["rx_ns"]),
                "can:NAV_QUALITY",
                "pairing",
                b"",
                f"epoch {int(q['epoch'])} at {int(q['t_ns'])} ns matches no NAV_SOLUTION",
            )
        return out

    def _pair(self, sols: np.ndarray, sol_rows: np.ndarray, quals: np.ndarray, q_rows: np.ndarray) -> np.ndarray:
        """(Q,) bool: each NAV_QUALITY has a NAV_SOLUTION of the same time and epoch among the
        last ``_RECENT`` received before it (in arrival order, so batches cut anywhere agree)."""
        base = self._n_solutions
        t_all = np.concatenate([self._recent_t, sols["t_ns"]])
        ep_all = np.concatenate([self._recent_epoch, sols["epoch"].astype(np.int64)])
        seq_all = np.concatenate([self._recent_seq, base + np.arange(sols.size, dtype=np.int64)])
        paired = np.zeros(quals.size, bool)
        if quals.size and t_all.size:
            keys = np.zeros(t_all.size + quals.size, [("t", "<i8"), ("e", "<i8")])
            keys["t"] = np.concatenate([t_all, quals["t_ns"]])
            keys["e"] = np.concatenate([ep_all, quals["epoch"].astype(np.int64)])
            label = np.unique(keys, return_inverse=True)[1].reshape(-1).astype(np.int64)
            ls, lq = label[: t_all.size], label[t_all.size :]
            before = base + np.searchsorted(sol_rows, q_rows)  # solutions received before each quality
            comp = np.sort((ls << 40) | seq_all)
            j = np.searchsorted(comp, (lq << 40) | before) - 1
            cand = comp[np.maximum(j, 0)]
            paired = (j >= 0) & ((cand >> 40) == lq) & ((cand & ((1 << 40) - 1)) >= before - _RECENT)
        self._n_solutions += sols.size
        self._recent_t, self._recent_epoch, self._recent_seq = t_all[-_RECENT:], ep_all[-_RECENT:], seq_all[-_RECENT:]
        return paired


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
            keep = labels != SEQ_DUPLICATE
            values = {k: v[keep] for k, v in values.items()}
            values["rx_ns"] = sub.t_ns[keep]
            if self.late_ns is not None and c.name == "BENCH_TIME":
                self.tally.count("late", int(np.sum(values["rx_ns"] - values["time_ns"] > self.late_ns)))
            out[c.name] = values
        return out
