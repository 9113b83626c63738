"""Wire-level faults: what happens to frames and bytes between the codecs and the links.

Importing this module registers the kinds (layer ``"wire"``) with
:func:`bench.faults.schedule.register_kind`. Targets:

* ``can:<MESSAGE>`` one ICD message (``can:ODOMETER``), ``can:*`` every message on the bus;
* ``can`` the whole CAN link (``silence`` only);
* ``serial:imu``, ``serial:gnss`` a serial stream (a stream is a link of its own).

A window acts on the frames (CAN) or chunks (serial: one IMU frame or one NMEA sentence
each) whose due time ``t`` is in ``[start, end)``. Kinds, parameters (units) and what a
receiver sees are in docs/wire.md; in short:

=============== ======================= ==============================================
kind            targets                 parameters
=============== ======================= ==============================================
drop            can:*, serial:*         probability (1, default 1)
delay           can:*, serial:*         delay (s, 0), jitter (s, 0: uniform 0..jitter)
duplicate       can:*, serial:*         copies (integer, 1), gap (s, 0)
freeze          can:*, serial:imu       -
offset          can:*, serial:imu/gnss  signal (text), value (SI unit of the signal)
scale           can:*, serial:imu/gnss  signal (text), factor (1)
corrupt_crc     can:*, serial:imu       -
counter_stale   can:*, serial:imu       -
counter_skip    can:*, serial:imu       skip (integer, 1)
wrong_dlc       can:*                   dlc (integer bytes, 7)
garbage         serial:*                length (integer bytes, 16), every (s, 0: one burst)
truncate        serial:*                keep (integer bytes, 0: random)
bad_checksum    serial:gnss             -
silence         can, serial:*           -
baud_mismatch   serial:*                baud (integer, required: the sender's real baud)
=============== ======================= ==============================================

:class:`WireFaultInjector` takes the time-ordered batches of outgoing frames of a run and
returns them faulted, plus one event record (:data:`WIRE_EVENT_DTYPE`, topic
``/faults/wire``) per frame a fault acted on. Random choices come from one
:func:`bench.rng.stream` per window and message (or stream), drawn in frame order, so the
result depends on the seed and the schedule only, not on how the run is cut into batches.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from bench.faults.lockstep import LOCKSTEP_TARGET, refuse_lockstep_faults
from bench.faults.schedule import FaultSchedule, FaultWindow
from bench.faults.wire_kinds import (
    SERIAL_LINKS,
    WIRE_EVENT_DTYPE,
    WIRE_EVENTS_TOPIC,
    WIRE_KINDS,
    concat_events,
    register_wire_kinds,
    wire_windows,
)
from bench.faults.wire_kinds import (
    events as _events,
)
from bench.faults.wire_ops import CanAdapter, corrupt_crc, edit_signal, freeze, parse_signal
from bench.faults.wire_serial import apply_serial
from bench.frames import CanBatch, SerialBatch
from bench.rng import stream as rng_stream
from bench.wire.can import codec_for_id

__all__ = [
    "WIRE_KINDS",
    "WIRE_EVENT_DTYPE",
    "WIRE_EVENTS_TOPIC",
    "SERIAL_LINKS",
    "register_wire_kinds",
    "wire_windows",
    "LOCKSTEP_TARGET",
    "refuse_lockstep_faults",
    "WireFaultInjector",
]

class WireFaultInjector:
    """Applies the wire windows of a schedule to outgoing batches (see the module docstring).

    Parameters
    ----------
    schedule:
        The run's fault schedule (windows of other layers are ignored).
    seed:
        The run seed; window ``id`` draws from ``bench.rng.stream(seed, "wire", str(id), target)``
        for each message or stream it acts on.
    serial_links:
        Baud and framing of each serial stream (``baud_mismatch``; default the ICD's).
    lockstep:
        The run is in lockstep: windows on ``can:BENCH_TIME`` are refused
        (:func:`refuse_lockstep_faults`) and ``can:*``/``can`` windows skip BENCH_TIME.

    :meth:`can` and :meth:`serial` take the frames due in ``(t0, until_ns]`` in time order
    and return those that go out by ``until_ns`` (delayed ones are held for a later call,
    :meth:`flush_can`/:meth:`flush_serial` release the rest) with ``t_ns`` the time they go
    out, plus the event records of this call.
    """

    def __init__(
        self,
        schedule: FaultSchedule | Iterable[FaultWindow] | None,
        seed: int = 0,
        *,
        serial_links: Mapping[str, tuple[int, str]] | None = None,
        lockstep: bool = False,
    ):
        self.windows = wire_windows(schedule)
        self.lockstep = lockstep
        if lockstep:
            refuse_lockstep_faults(self.windows)
        self.seed = seed
        self.serial_links = dict(SERIAL_LINKS if serial_links is None else serial_links)
        self._rngs: dict[tuple[int, str], np.random.Generator] = {}
        self._shift: dict[str, int] = {}  # target -> counter shift carried on
        self._frozen: dict[int, np.ndarray] = {}  # window id -> reference payload
        self._last: dict[str, np.ndarray] = {}  # target -> last original payload
        self._fifo: dict[str, int] = {}  # target -> last time a frame went out, while a delay holds the line
        self._bursts: dict[int, int] = {}  # garbage window id -> bursts sent
        self._held_can = CanBatch.empty()
        self._held_serial: dict[str, SerialBatch] = {}
        self._adapters: dict[int, CanAdapter | None] = {}

    # ------------------------------------------------------------------ helpers
    def rng(self, w: FaultWindow, target: str) -> np.random.Generator:
        """The random stream of window ``w`` on message or stream ``target`` (drawn in its frame order)."""
        key = (w.id, target)
        if key not in self._rngs:
            self._rngs[key] = rng_stream(self.seed, "wire", str(w.id), target)
        return self._rngs[key]

    def _applies(self, w: FaultWindow, target: str) -> bool:
        if self.lockstep and target == LOCKSTEP_TARGET:
            return False  # the lockstep frame: can:* and can windows leave it alone
        if w.target == target:
            return True
        if target.startswith("can:"):
            return w.target == "can:*" or (w.target == "can" and w.kind == "silence")
        return False

    def windows_on(self, target: str, t0: int, t1: int) -> list[FaultWindow]:
        """Windows acting on ``target`` that overlap bench times ``[t0, t1]``."""
        return [w for w in self.windows if self._applies(w, target) and w.start_ns <= t1 and w.end_ns > t0]

    # ------------------------------------------------------------------ payload faults
    def _content(
        self,
        adapter,
        target: str,
        t: np.ndarray,
        rows: np.ndarray,
        wins: list[FaultWindow],
        can_id: int,
        events: list[np.ndarray],
    ) -> np.ndarray:
        """Freeze, offset, scale, counter and CRC faults on the rows of one message (time order)."""
        original = rows
        rows = rows.copy()
        for w in wins:
            m = (t >= w.start_ns) & (t < w.end_ns)
            if not m.any():
                continue
            if w.kind == "freeze":
                if w.id not in self._frozen:
                    before = np.flatnonzero(t < w.start_ns)
                    ref = original[before[-1]] if before.size else self._last.get(target, original[np.argmax(m)])
                    self._frozen[w.id] = np.array(ref, np.uint8)
                freeze(adapter, rows, m, self._frozen[w.id])
            elif w.kind in ("offset", "scale"):
                if parse_signal(w.params["signal"])[0] not in adapter.signals():
                    continue  # a can:* window leaves the messages without that signal alone
                fn = (
                    (lambda v, d=w.params["value"]: v + d)
                    if w.kind == "offset"
                    else (lambda v, k=w.params["factor"]: v * k)
                )
                edit_signal(adapter, rows, m, w.params["signal"], fn)
            else:
                continue
            events.append(_events(t[m], t[m], w, can_id, 0.0))
        # counters: a running shift, carried on after the windows
        delta = np.zeros(t.shape[0], np.int64)
        counter_wins = [w for w in wins if w.kind in ("counter_stale", "counter_skip")]
        for w in counter_wins:
            m = (t >= w.start_ns) & (t < w.end_ns)
            delta[m] += -1 if w.kind == "counter_stale" else w.params["skip"]
        shift = self._shift.get(target, 0) + np.cumsum(delta)
        if t.shape[0]:
            self._shift[target] = int(shift[-1]) % adapter.modulus
            need = shift % adapter.modulus != 0
            if need.any():
                counters = adapter.counters(rows[need]) + shift[need]
                sub = rows[need]
                adapter.set_counters(sub, counters)
                rows[need] = sub
                written = np.zeros(t.shape[0], np.int64)
                written[need] = counters % adapter.modulus
                for w in counter_wins:
                    m = (t >= w.start_ns) & (t < w.end_ns)
                    events.append(_events(t[m], t[m], w, can_id, written[m]))
        for w in wins:
            if w.kind == "corrupt_crc":
                m = (t >= w.start_ns) & (t < w.end_ns)
                if m.any():
                    x = corrupt_crc(adapter, rows, m, self.rng(w, target))
                    events.append(_events(t[m], t[m], w, can_id, x))
        if t.shape[0]:
            self._last[target] = original[-1].copy()
        return rows

    # ------------------------------------------------------------------ presence and time
    def _presence(
        self, target: str, t: np.ndarray, wins: list[FaultWindow], can_id: int, events: list[np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
        """(kept mask, out times, copies as (source index, out time)) of one message or stream."""
        keep = np.ones(t.shape[0], bool)
        extra_delay = np.zeros(t.shape[0], np.int64)
        copies: list[tuple[np.ndarray, np.ndarray]] = []
        for w in wins:
            m = (t >= w.start_ns) & (t < w.end_ns)
            if not m.any():
                continue
            if w.kind == "silence":
                keep &= ~m
                events.append(_events(t[m], -1, w, can_id, 0.0))
            elif w.kind == "drop":
                lost = np.zeros_like(m)
                lost[m] = self.rng(w, target).random(int(m.sum())) < w.params["probability"]
                keep &= ~lost
                events.append(_events(t[lost], -1, w, can_id, 0.0))
            elif w.kind == "delay":
                jitter = self.rng(w, target).random(int(m.sum())) * w.params["jitter"] if w.params["jitter"] else 0.0
                extra_delay[m] += np.rint((w.params["delay"] + jitter) * 1e9).astype(np.int64)
        out = t + extra_delay
        last = self._fifo.get(target)
        if keep.any():  # first in first out: a frame never overtakes the one before it
            kept_out = np.maximum.accumulate(np.concatenate([[last if last is not None else out[0]], out[keep]]))[1:]
            out[keep] = kept_out
            if kept_out[-1] > t[keep][-1]:
                self._fifo[target] = int(kept_out[-1])  # a delay still holds the line
            else:
                self._fifo.pop(target, None)
        for w in wins:
            m = (t >= w.start_ns) & (t < w.end_ns) & keep
            if w.kind == "delay" and m.any():
                events.append(_events(t[m], out[m], w, can_id, (out[m] - t[m]).astype(np.float64)))
            elif w.kind == "duplicate" and m.any():
                gap = round(w.params["gap"] * 1e9)
                for k in range(1, w.params["copies"] + 1):
                    src = np.flatnonzero(m)
                    copies.append((src, out[src] + k * gap))
                    events.append(_events(t[src], out[src] + k * gap, w, can_id, float(k)))
        return keep, out, copies

    # ------------------------------------------------------------------ CAN
    def _adapter(self, can_id: int) -> CanAdapter | None:
        if can_id not in self._adapters:
            c = codec_for_id(can_id)
            self._adapters[can_id] = None if c is None else CanAdapter(c)
        return self._adapters[can_id]

    def can(self, batch: CanBatch, until_ns: int | None = None) -> tuple[CanBatch, np.ndarray]:
        """The CAN frames of ``batch`` (time order) with the faults applied; see the class."""
        events: list[np.ndarray] = []
        pieces = [self._held_can] if len(self._held_can) else []
        if len(batch):
            t0, t1 = int(batch.t_ns.min()), int(batch.t_ns.max())
            for can_id in np.unique(batch.can_id).tolist():
                idx = np.flatnonzero(batch.can_id == can_id)
                adapter = self._adapter(can_id)
                target = f"can:{adapter.name}" if adapter else f"can:0x{can_id:03X}"
                wins = self.windows_on(target, t0, t1)
                if not wins and not self._shift.get(target) and target not in self._fifo:
                    pieces.append(batch.take(idx))
                    self._last[target] = batch.data[idx[-1]].copy()  # what a freeze would hold
                    continue
                sub = batch.take(idx)
                t = sub.t_ns
                data, length = sub.data, sub.length.copy()
                if adapter is not None:
                    w8 = adapter.width
                    rows = self._content(adapter, target, t, sub.with_width(w8).data[:, :w8], wins, can_id, events)
                    data = sub.with_width(max(64 if sub.fd.any() else 8, w8)).data.copy()
                    data[:, :w8] = rows
                for w in wins:
                    m = (t >= w.start_ns) & (t < w.end_ns)
                    if w.kind == "wrong_dlc" and m.any():
                        dlc = w.params["dlc"]
                        data = CanBatch(t, can_id, data, length, sub.fd).with_width(dlc).data.copy()
                        data[np.flatnonzero(m)[:, None], np.arange(dlc, data.shape[1])] = 0
                        length[m] = dlc
                        events.append(_events(t[m], t[m], w, can_id, float(dlc)))
                keep, out, copies = self._presence(target, t, wins, can_id, events)
                faulted = CanBatch(out, can_id, data, length, sub.fd)
                pieces.append(faulted.take(keep))
                for src, t_copy in copies:
                    dup = faulted.take(src)
                    pieces.append(CanBatch(t_copy, can_id, dup.data, dup.length, dup.fd))
        merged = CanBatch.concat(pieces).sorted() if pieces else CanBatch.empty()
        if until_ns is not None and len(merged):
            late = merged.t_ns > until_ns
            self._held_can = merged.take(late)
            merged = merged.take(~late)
        else:
            self._held_can = CanBatch.empty()
        return merged, concat_events(events)

    def flush_can(self) -> CanBatch:
        """CAN frames still held back by delays."""
        held, self._held_can = self._held_can, CanBatch.empty()
        return held

    # ------------------------------------------------------------------ serial
    def serial(self, stream: str, batch: SerialBatch, until_ns: int | None = None) -> tuple[SerialBatch, np.ndarray]:
        """The chunks of serial ``stream`` (``imu``, ``gnss``) with the faults applied."""
        return apply_serial(self, stream, batch, until_ns)

    def flush_serial(self, stream: str) -> SerialBatch:
        """Chunks of ``stream`` still held back by delays."""
        held = self._held_serial.pop(stream, SerialBatch.empty())
        return held
