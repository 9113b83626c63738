"""The serial half of the wire-fault injector: chunks of bytes on the ``imu`` and ``gnss`` lines.

Order of the edits on a batch of chunks (one IMU frame or one NMEA sentence each):

1. IMU frame content (``freeze``, ``offset``, ``scale``, counters, ``corrupt_crc``) on the
   ``(N, 42)`` frame array, as for CAN messages (:meth:`WireFaultInjector._content`);
2. byte edits per chunk: ``truncate`` (the chunk is cut: an IMU frame keeps 3..41 bytes,
   a sentence 1..len-5, so its ``*hh`` and CR LF are lost), ``bad_checksum`` (the ``hh``
   of a sentence xor-ed with a random non-zero value), ``baud_mismatch`` (the bytes as a
   UART at the link's baud reads them when sent at ``baud``; :mod:`bench.wire.uart`);
3. presence and time: ``silence``, ``drop``, ``delay`` (first in first out: a serial line
   never reorders), ``duplicate``;
4. ``garbage`` bursts inserted at ``start``, ``start + every``, ... : uniform random bytes
   that never hold the stream's frame start (0xAA on ``imu``, ``$`` on ``gnss``), so a
   burst is noise and never a false frame (what a broken frame looks like is what
   ``truncate`` and ``corrupt_crc`` make).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from bench.faults.wire_kinds import concat_events
from bench.faults.wire_kinds import events as _events
from bench.faults.wire_nmea import edit_sentence
from bench.faults.wire_ops import ImuAdapter
from bench.frames import SerialBatch
from bench.wire import imu
from bench.wire.uart import uart_receive

if TYPE_CHECKING:
    from bench.faults.wire import WireFaultInjector

__all__ = ["apply_serial", "FRAME_START"]

#: The byte a garbage burst never holds, per stream.
FRAME_START = {"imu": 0xAA, "gnss": ord("$")}
_CONTENT = ("freeze", "offset", "scale", "counter_stale", "counter_skip", "corrupt_crc")
_BYTES = ("truncate", "bad_checksum", "baud_mismatch")


def _truncate(data: bytes, stream: str, keep: int, rng: np.random.Generator) -> bytes:
    n = len(data)
    if n <= 1:
        return data
    if keep:
        return data[: min(keep, n - 1)]
    if stream == "imu" and n == imu.FRAME_SIZE:
        return data[: int(rng.integers(3, imu.FRAME_SIZE))]
    if stream == "gnss" and data.endswith(b"\r\n") and n > 6:
        return data[: int(rng.integers(1, n - 4))]
    return data[: int(rng.integers(1, n))]


def _bad_checksum(data: bytes, rng: np.random.Generator) -> tuple[bytes, int]:
    star = data.rfind(b"*")
    if star < 0 or len(data) < star + 3:
        return data, -1
    x = int(rng.integers(1, 256))
    value = int(data[star + 1 : star + 3], 16) ^ x
    return data[: star + 1] + b"%02X" % value + data[star + 3 :], value


def _bursts(inj: WireFaultInjector, stream: str, w, limit: int) -> list[tuple[int, bytes]]:
    """Garbage bursts of window ``w`` due by ``limit`` not yet sent."""
    k = inj._bursts.get(w.id, 0)  # bursts of this window already sent
    every = round(w.params["every"] * 1e9)
    out = []
    while True:
        t = w.start_ns + k * every
        if t >= w.end_ns or t > limit or (k > 0 and every == 0):
            break
        rng = inj.rng(w, f"serial:{stream}")
        forbidden = FRAME_START.get(stream)
        raw = rng.integers(0, 255 if forbidden is not None else 256, w.params["length"])
        if forbidden is not None:
            raw[raw >= forbidden] += 1
        out.append((t, raw.astype(np.uint8).tobytes()))
        k += 1
    inj._bursts[w.id] = k
    return out


def apply_serial(
    inj: WireFaultInjector, stream: str, batch: SerialBatch, until_ns: int | None
) -> tuple[SerialBatch, np.ndarray]:
    """See :meth:`bench.faults.wire.WireFaultInjector.serial`."""
    target = f"serial:{stream}"
    evs: list[np.ndarray] = []
    pieces = [inj._held_serial[stream]] if stream in inj._held_serial else []
    limit = until_ns if until_ns is not None else (int(batch.t_ns.max()) if len(batch) else None)
    t = batch.t_ns
    t0 = int(t.min()) if len(batch) else (limit if limit is not None else 0)
    t1 = int(t.max()) if len(batch) else t0
    wins = inj.windows_on(target, t0, max(t1, limit if limit is not None else t1))
    if not wins and not inj._shift.get(target) and target not in inj._fifo:
        pieces.append(batch)
        if len(batch):  # what a freeze would hold
            inj._last[target] = batch.buf[batch.offsets[-2] : batch.offsets[-1]].copy()
    else:
        if (
            stream == "imu"
            and len(batch)
            and np.all(batch.lengths == imu.FRAME_SIZE)
            and (inj._shift.get(target) or any(w.kind in _CONTENT for w in wins))
        ):
            rows = inj._content(ImuAdapter(), target, t, batch.buf.reshape(-1, imu.FRAME_SIZE), wins, 0, evs)
            batch = SerialBatch.from_fixed(t, rows)
        chunks: list[bytes] | None = None
        if stream == "gnss":
            for w in wins:
                if w.kind not in ("offset", "scale"):
                    continue
                m = np.flatnonzero((t >= w.start_ns) & (t < w.end_ns))
                if m.size == 0:
                    continue
                if chunks is None:
                    chunks = [c.data for c in batch.chunks()]
                p = w.params
                fn = (lambda v, d=p["value"]: v + d) if w.kind == "offset" else (lambda v, f=p["factor"]: v * f)
                for i in m.tolist():
                    chunks[i] = edit_sentence(chunks[i], p["signal"], fn)
                evs.append(_events(t[m], t[m], w, 0, p["value"] if w.kind == "offset" else p["factor"]))
        for w in wins:
            if w.kind not in _BYTES:
                continue
            m = np.flatnonzero((t >= w.start_ns) & (t < w.end_ns))
            if m.size == 0:
                continue
            if chunks is None:
                chunks = [c.data for c in batch.chunks()]
            values = np.zeros(m.size)
            for j, i in enumerate(m.tolist()):
                if w.kind == "truncate":
                    chunks[i] = _truncate(chunks[i], stream, w.params["keep"], inj.rng(w, f"serial:{stream}"))
                    values[j] = len(chunks[i])
                elif w.kind == "bad_checksum":
                    chunks[i], values[j] = _bad_checksum(chunks[i], inj.rng(w, f"serial:{stream}"))
                else:
                    baud, framing = inj.serial_links.get(stream, (w.params["baud"], "8N1"))
                    chunks[i] = uart_receive(chunks[i], w.params["baud"], baud, framing)
                    values[j] = len(chunks[i])
            evs.append(_events(t[m], t[m], w, 0, values))
        keep, out, copies = inj._presence(target, t, wins, 0, evs)
        if chunks is None and not copies:
            kept = batch.take(keep)
            pieces.append(SerialBatch(out[keep], kept.offsets, kept.buf))
        else:
            if chunks is None:
                chunks = [c.data for c in batch.chunks()]
            extra: dict[int, list[int]] = {}  # source chunk -> times of its copies
            for src, t_copy in copies:
                for i, tc in zip(src.tolist(), t_copy.tolist(), strict=True):
                    extra.setdefault(i, []).append(int(tc))
            items = []  # each copy right after its original (the sort below is stable)
            for i in np.flatnonzero(keep | np.isin(np.arange(len(chunks)), list(extra))).tolist():
                if keep[i]:
                    items.append((int(out[i]), chunks[i]))
                items += [(tc, chunks[i]) for tc in extra.get(i, [])]
            pieces.append(_from_items(items))
        for w in wins:
            bursts = _bursts(inj, stream, w, limit) if w.kind == "garbage" and limit is not None else []
            if bursts:
                times = [tb for tb, _ in bursts]
                evs.append(_events(times, times, w, 0, float(w.params["length"])))
                pieces.append(_from_items(bursts))
    merged = SerialBatch.concat(pieces).sorted() if pieces else SerialBatch.empty()
    if until_ns is not None and len(merged):
        late = merged.t_ns > until_ns
        if late.any():
            inj._held_serial[stream] = merged.take(late)
            merged = merged.take(~late)
        else:
            inj._held_serial.pop(stream, None)
    else:
        inj._held_serial.pop(stream, None)
    return merged, concat_events(evs)


def _from_items(items: list[tuple[int, bytes]]) -> SerialBatch:
    if not items:
        return SerialBatch.empty()
    lengths = [len(d) for _, d in items]
    offsets = np.zeros(len(items) + 1, np.int64)
    np.cumsum(lengths, out=offsets[1:])
    return SerialBatch([tc for tc, _ in items], offsets, b"".join(d for _, d in items))
