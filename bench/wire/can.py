"""CAN message codecs of the ICD, symmetric, strict and vectorised, driven by the DBC.

Each message of ``models/can/icd_1_0.dbc`` gets a :class:`CanCodec` that speaks SI on
one side and payload bytes on the other:

* batch: :meth:`CanCodec.encode` turns arrays of values into a :class:`~bench.frames.CanBatch`
  (``(N, 8)`` or ``(N, 48)`` payloads, CRC and counter included) and :meth:`CanCodec.decode`
  turns payloads back into arrays plus a per-frame status (0 good, else an index into
  :data:`DECODE_KINDS`), so a link counts bad frames without a per-frame loop;
* one frame: :meth:`CanCodec.encode_one` and :meth:`CanCodec.decode_one`, which raise
  :class:`~bench.errors.CodecError` with kind ``"range"``, ``"length"``, ``"crc"``,
  ``"format"``, ``"counter"`` or ``"unknown_id"``.

Values are SI (m, m/s, rad, integer ns); the quantity names are listed per message in
:data:`bench.wire.quantities.QUANTITIES` and in docs/wire.md. A value that does not fit its field raises
``CodecError("range", ...)`` naming the message and the field. Classic frames carry the
CRC-8 over ``(ID & 0xFF)`` and bytes 0..6 in byte 7; FD frames the CRC-16 over the bytes
before it in their last two bytes. Every bit no signal covers must be zero.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import cache

import numpy as np

from bench.errors import CodecError
from bench.frames import CanBatch
from bench.wire.bits import INT64_MAX_US, covered_mask, pack, replace, round_div, unpack
from bench.wire.crc import crc8_can_rows, crc16_ccitt_false_rows
from bench.wire.dbc import MessageSpec, SignalSpec, load_specs, spec
from bench.wire.quantities import QUANTITIES, Quantity
from bench.wire.sequence import CounterSequence

__all__ = ["CanCodec", "CanEncoder", "codec", "codec_for_id", "DECODE_KINDS"]

#: Status codes of batch decoding: ``status == 0`` good, else ``DECODE_KINDS[status]``.
DECODE_KINDS = ("ok", "length", "crc", "format", "range")

_UNIT_TO_SI = {"deg": math.pi / 180.0, "arcmin": math.pi / 180.0 / 60.0}


_COUNTER_SIGNALS = ("AliveCounter", "EpochCounter")
_CRC_SIGNALS = ("Crc", "Crc16")


def _raw_bounds(sig: SignalSpec) -> tuple[int, int]:
    """Allowed raw range: the field's range cut to the DBC's [minimum, maximum]."""
    lo, hi = sig.field.raw_min, sig.field.raw_max
    if sig.minimum is not None:
        lo = max(lo, math.ceil((sig.minimum - sig.offset) / sig.scale - 1e-6))
    if sig.maximum is not None:
        hi = min(hi, math.floor((sig.maximum - sig.offset) / sig.scale + 1e-6))
    return lo, hi


class CanCodec:
    """Encoder and decoder of one ICD message (see the module docstring)."""

    def __init__(self, message: MessageSpec):
        self.spec = message
        self.name = message.name
        self.frame_id = message.frame_id
        self.length = message.length
        self.fd = message.fd
        self.quantities = QUANTITIES[message.name]
        self._sig = {s.name: s for s in message.signals}
        self._bounds = {s.name: _raw_bounds(s) for s in message.signals}
        #: what the wire's integer fields can carry, whatever the DBC's physical range
        self._field_bounds = {s.name: (s.field.raw_min, s.field.raw_max) for s in message.signals}
        carried = {n for q in self.quantities for n in q.signals}
        extra = [s.name for s in message.signals if s.name not in carried and s.name not in _CRC_SIGNALS]
        if extra:
            raise CodecError("format", f"{self.name}: DBC signals {extra} have no SI quantity in the codec")
        self.crc_signal = next(s for s in message.signals if s.name in _CRC_SIGNALS)
        self.counter_signal = next((s for s in message.signals if s.name in _COUNTER_SIGNALS), None)
        self.counter_name = next(
            (q.name for q in self.quantities if self.counter_signal and q.signals == (self.counter_signal.name,)), None
        )
        self._data_fields = tuple(s.field for s in message.signals if s.name not in _CRC_SIGNALS)
        self._reserved = ~covered_mask(message.fields, self.length)
        self._crc_bytes = self.crc_signal.field.start // 8

    def __repr__(self) -> str:
        return f"CanCodec({self.name}, 0x{self.frame_id:03X}, {self.length} bytes{', FD' if self.fd else ''})"

    def raw_bounds(self, signal: str) -> tuple[int, int]:
        """Allowed raw range of DBC signal ``signal``: its field cut to the DBC [minimum, maximum]."""
        return self._bounds[signal]

    @property
    def value_mask(self) -> np.ndarray:
        """(length,) uint8: the bits of every signal but the counter and the CRC."""
        fields = [s.field for s in self.spec.signals if s is not self.crc_signal and s is not self.counter_signal]
        return covered_mask(fields, self.length)

    def set_counters(self, data: np.ndarray, counters) -> np.ndarray:
        """Overwrite the counter of payloads (N, length) in place and recompute their CRC."""
        replace(self.counter_signal.field, np.asarray(counters, np.int64) % self.counter_modulus, data)
        return self.refresh_crc(data)

    def clip(self, name: str, value) -> np.ndarray:
        """``value`` of quantity ``name`` (SI) clipped to what its field can carry."""
        q = next(q for q in self.quantities if q.name == name)
        out = np.array(value, dtype=np.float64)
        for i, sname in enumerate(q.signals):
            s = self._sig[sname]
            lo, hi = self._bounds[sname]
            unit = _UNIT_TO_SI.get(s.unit, 1.0)
            col = out[..., i] if len(q.signals) > 1 else out
            np.clip(col, (lo * s.scale + s.offset) * unit, (hi * s.scale + s.offset) * unit, out=col)
        return out

    @property
    def counter_modulus(self) -> int:
        """16 for alive counters, 256 for epoch counters."""
        return 1 << self.counter_signal.field.length if self.counter_signal else 0

    # ---------------------------------------------------------------- raw level
    def encode_raw(self, raw: Mapping[str, np.ndarray], n: int | None = None) -> np.ndarray:
        """Payloads (N, length) uint8 from raw integers of every non-CRC signal; the CRC is computed."""
        if n is None:
            n = max((np.size(v) for v in raw.values()), default=1)
        for f in self._data_fields:
            v = np.asarray(raw[f.name])
            lo, hi = f.raw_min, f.raw_max
            if v.size and (int(v.min()) < lo or int(v.max()) > hi):
                raise CodecError("range", f"{self.name}.{f.name}: raw value outside [{lo}, {hi}]")
        out = np.zeros((n, self.length), np.uint8)
        pack(self._data_fields, raw, out)
        self._put_crc(out)
        return out

    def decode_raw(self, data: np.ndarray) -> dict[str, np.ndarray]:
        """Raw integers of every signal (CRC included) of payloads (N, length); no checks."""
        return unpack(self.spec.fields, np.asarray(data, np.uint8))

    def _crc_of(self, data: np.ndarray) -> np.ndarray:
        if self.fd:
            return crc16_ccitt_false_rows(data[:, : self._crc_bytes])
        return crc8_can_rows(self.frame_id, data)

    def _put_crc(self, data: np.ndarray) -> None:
        crc = self._crc_of(data)
        if self.fd:
            data[:, self._crc_bytes] = (crc & 0xFF).astype(np.uint8)
            data[:, self._crc_bytes + 1] = (crc >> 8).astype(np.uint8)
        else:
            data[:, self._crc_bytes] = crc

    def refresh_crc(self, data: np.ndarray) -> np.ndarray:
        """Recompute the CRC of payloads (N, length) in place (fault injection edits payloads)."""
        self._put_crc(data)
        return data

    # ---------------------------------------------------------------- SI level
    def _to_raw(self, q: Quantity, value, wire_range: bool = False) -> dict[str, np.ndarray]:
        sigs = [self._sig[s] for s in q.signals]
        v = np.asarray(value)
        if q.kind in ("time_us", "time_ms"):
            if v.dtype.kind not in "iu":
                raise CodecError("range", f"{self.name}.{q.name}: expected integer nanoseconds, found {v.dtype}")
            raws = {sigs[0].name: round_div(v.astype(np.int64), 1000 if q.kind == "time_us" else 1_000_000)}
        elif q.kind in ("int", "int_wrap"):
            if v.dtype.kind not in "iub" and (not np.all(np.isfinite(v)) or not np.all(v == np.round(v))):
                raise CodecError("range", f"{self.name}.{q.name}: expected integers, found {v!r}")
            iv = v.astype(np.int64)
            if q.kind == "int_wrap":
                iv = iv % (sigs[0].field.raw_max + 1)
            raws = {sigs[0].name: iv}
        elif q.kind == "bits":
            iv = v.astype(np.int64)
            if iv.size and (int(iv.min()) < 0 or int(iv.max()) >= 1 << len(sigs)):
                raise CodecError("range", f"{self.name}.{q.name}: bit mask outside [0, {(1 << len(sigs)) - 1}]")
            raws = {s.name: (iv >> i) & 1 for i, s in enumerate(sigs)}
        else:
            fv = v.astype(np.float64)
            if len(sigs) > 1:
                if fv.shape[-1:] != (len(sigs),):
                    raise CodecError(
                        "range", f"{self.name}.{q.name}: expected shape (N, {len(sigs)}), found {fv.shape}"
                    )
                cols = [fv[..., i] for i in range(len(sigs))]
            else:
                cols = [fv]
            raws = {}
            for s, col in zip(sigs, cols, strict=True):
                if not np.all(np.isfinite(col)):
                    raise CodecError("range", f"{self.name}.{s.name} ({q.name}): value is not finite")
                phys = col / _UNIT_TO_SI.get(s.unit, 1.0)
                if q.kind == "angle_wrap":
                    phys = np.mod(phys, 360.0)
                raw = np.rint((phys - s.offset) / s.scale)
                if q.kind == "angle_wrap":
                    raw = np.mod(raw, round(360.0 / s.scale))
                raws[s.name] = raw
        for name, raw in raws.items():
            lo, hi = (self._field_bounds if wire_range else self._bounds)[name]
            raw = np.asarray(raw)
            if raw.size and (raw.min() < lo or raw.max() > hi):
                s = self._sig[name]
                bad = raw[(raw < lo) | (raw > hi)].ravel()[0]
                what = f"{float(bad) * s.scale + s.offset:.10g} {s.unit}".strip() if not s.is_integer else str(bad)
                raise CodecError(
                    "range",
                    f"{self.name}.{name} ({q.name}): {what} outside [{lo * s.scale + s.offset:.10g}, "
                    f"{hi * s.scale + s.offset:.10g}] {s.unit}".rstrip(),
                )
            raws[name] = raw.astype(np.int64) if raw.dtype.kind == "f" else raw
        return raws

    def _from_raw(self, q: Quantity, raw: Mapping[str, np.ndarray]) -> np.ndarray:
        sigs = [self._sig[s] for s in q.signals]
        if q.kind in ("time_us", "time_ms"):
            r = raw[sigs[0].name]
            return r.astype(np.int64) * (1000 if q.kind == "time_us" else 1_000_000)
        if q.kind in ("int", "int_wrap"):
            return raw[sigs[0].name].astype(np.int64)
        if q.kind == "bits":
            out = np.zeros(raw[sigs[0].name].shape, np.int64)
            for i, s in enumerate(sigs):
                out |= raw[s.name].astype(np.int64) << i
            return out
        cols = [(raw[s.name].astype(np.float64) * s.scale + s.offset) * _UNIT_TO_SI.get(s.unit, 1.0) for s in sigs]
        return np.stack(cols, axis=-1) if len(cols) > 1 else cols[0]

    def encode(self, at_ns, values: Mapping[str, object], *, wire_range: bool = False) -> CanBatch:
        """Frames due at ``at_ns`` (N,) int64 from SI ``values`` (each (N,) or scalar, 3-vectors (N, 3)).

        Values outside the DBC's physical range raise ``CodecError("range")``; with
        ``wire_range`` only values the payload's integer fields cannot carry do (NaN, too
        large): an estimator's output is put on the bus as a DUT would send it, and the
        bench's strict decoder then rejects it as a bad frame, as from any DUT."""
        at_ns = np.atleast_1d(np.asarray(at_ns, np.int64))
        n = at_ns.shape[0]
        missing = [q.name for q in self.quantities if q.name not in values]
        unknown = [k for k in values if k not in {q.name for q in self.quantities}]
        if missing or unknown:
            raise CodecError(
                "format",
                f"{self.name}: expected values {', '.join(q.name for q in self.quantities)}"
                + (f"; missing {', '.join(missing)}" if missing else "")
                + (f"; unknown {', '.join(unknown)}" if unknown else ""),
            )
        raw: dict[str, np.ndarray] = {}
        for q in self.quantities:
            value = np.asarray(values[q.name])
            shape = (n, len(q.signals)) if (q.kind == "float" and len(q.signals) > 1) else (n,)
            if value.shape != shape and value.shape != shape[1:]:  # arrays per frame, or one value for all
                raise CodecError("length", f"{self.name}.{q.name}: expected shape {shape}, found {value.shape}")
            raw.update(self._to_raw(q, value, wire_range))
        data = np.zeros((n, self.length), np.uint8)
        pack(self._data_fields, raw, data)
        self._put_crc(data)
        return CanBatch(at_ns, self.frame_id, data, self.length, self.fd)

    def check(self, batch: CanBatch) -> np.ndarray:
        """Per-frame status (N,) uint8 of frames of this message: index into :data:`DECODE_KINDS`."""
        n = len(batch)
        status = np.zeros(n, np.uint8)
        status[(batch.length != self.length) | (batch.fd != self.fd)] = 1
        data = batch.with_width(self.length).data[:, : self.length]
        ok = status == 0
        if self.fd:
            crc = data[:, self._crc_bytes].astype(np.uint16) | (data[:, self._crc_bytes + 1].astype(np.uint16) << 8)
        else:
            crc = data[:, self._crc_bytes]
        status[ok & (self._crc_of(data) != crc)] = 2
        status[(status == 0) & np.any(data & self._reserved, axis=1)] = 3
        raw = unpack(self._data_fields, data)
        for name, (lo, hi) in self._bounds.items():
            if name in raw:
                r = raw[name]
                status[(status == 0) & ((r < lo) | (r > hi))] = 4
        for q in self.quantities:
            if q.kind in ("time_us", "time_ms"):
                limit = INT64_MAX_US if q.kind == "time_us" else INT64_MAX_US // 1000
                status[(status == 0) & (raw[q.signals[0]] > limit)] = 4
        return status

    def decode(self, batch: CanBatch) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """SI values of every frame and their status (0 good, see :data:`DECODE_KINDS`).

        Values of frames with a bad status are whatever the bytes say; use ``status == 0``.
        """
        status = self.check(batch)
        data = batch.with_width(self.length).data[:, : self.length]
        raw = unpack(self._data_fields, data)
        return {q.name: self._from_raw(q, raw) for q in self.quantities}, status

    # ---------------------------------------------------------------- one frame
    def encode_one(self, **values) -> bytes:
        """The payload of one frame (strict: CodecError on a value that does not fit)."""
        return self.encode([0], {k: np.asarray(v)[None] for k, v in values.items()}).data[0].tobytes()

    def decode_one(self, data: bytes, *, fd: bool | None = None, expect_counter: int | None = None) -> dict:
        """SI values of one payload; raises CodecError (length, crc, format, range, counter)."""
        if len(data) != self.length:
            raise CodecError("length", f"{self.name}: expected {self.length} bytes, found {len(data)}")
        if fd is not None and fd != self.fd:
            raise CodecError("length", f"{self.name}: expected a {'CAN FD' if self.fd else 'classic'} frame")
        row = np.frombuffer(data, np.uint8)[None]
        values, status = self.decode(CanBatch([0], self.frame_id, row, self.length, self.fd))
        kind = DECODE_KINDS[int(status[0])]
        if kind != "ok":
            raise CodecError(kind, f"{self.name}: {self._explain(kind, row)}")
        out = {}
        for q in self.quantities:
            v = values[q.name][0]
            out[q.name] = (
                v.copy()
                if isinstance(v, np.ndarray)
                else (int(v) if q.kind != "float" and q.kind != "angle_wrap" else float(v))
            )
        if expect_counter is not None and self.counter_name and out[self.counter_name] != expect_counter:
            raise CodecError(
                "counter", f"{self.name}: expected counter {expect_counter}, found {out[self.counter_name]}"
            )
        return out

    def _explain(self, kind: str, row: np.ndarray) -> str:
        if kind == "crc":
            got = self.decode_raw(row)[self.crc_signal.name][0]
            return f"CRC 0x{int(got):X} does not match 0x{int(self._crc_of(row)[0]):X}"
        if kind == "format":
            byte = int(np.flatnonzero(row[0] & self._reserved)[0])
            return f"reserved bits set in byte {byte} (0x{int(row[0, byte]):02X})"
        raw = unpack(self._data_fields, row)
        for name, (lo, hi) in self._bounds.items():
            if name in raw and not lo <= int(raw[name][0]) <= hi:
                return f"{name} raw {int(raw[name][0])} outside [{lo}, {hi}]"
        return "time does not fit int64 nanoseconds"


@cache
def codec(name: str) -> CanCodec:
    """The codec of the ICD message ``name`` (``"ODOMETER"``)."""
    return CanCodec(spec(name))


def codec_for_id(frame_id: int) -> CanCodec | None:
    """The codec of identifier ``frame_id``, or None if the ICD has no such message."""
    for m in load_specs().values():
        if m.frame_id == frame_id:
            return codec(m.name)
    return None


class CanEncoder:
    """A sender's encoder: the ICD messages it sends, each with its alive counter running.

    ``encode("ODOMETER", at_ns, pulse_count=..., speed=..., reverse=..., valid=...)`` fills
    ``alive`` from the message's counter (+1 modulo 16 per frame, across calls) unless it
    is given. Epoch counters (NAV frames) are data of the epoch and always given.
    """

    def __init__(self, *, wire_range: bool = False) -> None:
        self.counters: dict[str, CounterSequence] = {}
        #: encode what the payload can carry, not only the DBC's physical range
        #: (:meth:`CanCodec.encode`): the DUT side's encoder
        self.wire_range = wire_range

    def encode(self, name: str, at_ns, **values) -> CanBatch:
        """Frames of message ``name`` due at ``at_ns`` (N,) from SI ``values``."""
        c = codec(name)
        n = np.atleast_1d(np.asarray(at_ns)).shape[0]
        if c.counter_name == "alive" and "alive" not in values:
            values["alive"] = self.counters.setdefault(name, CounterSequence(c.counter_modulus)).take(n)
        return c.encode(at_ns, values, wire_range=self.wire_range)

    def encode_records(self, name: str, records: np.ndarray, at_ns=None) -> CanBatch:
        """Frames from records whose fields are named like the message's quantities
        (``NAV_SOLUTION_DTYPE`` for NAV_SOLUTION); due at ``at_ns`` (default ``records["rx_ns"]``)."""
        c = codec(name)
        values = {q.name: records[q.name] for q in c.quantities if q.name in records.dtype.names}
        return self.encode(name, records["rx_ns"] if at_ns is None else at_ns, **values)
