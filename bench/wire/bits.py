"""Little-endian (Intel) bit fields packed into and out of many payloads at once.

A :class:`Field` is where an integer lives in a payload: start bit (DBC numbering, bit
``k`` is bit ``k % 8`` of byte ``k // 8``), length in bits (1..64) and signedness. Raw
values travel as int64 arrays (signed fields and unsigned fields up to 63 bits) or uint64
arrays (unsigned 64-bit fields), so the full range of every field is exact.

:func:`pack` and :func:`unpack` loop over the bytes a field touches (at most 9) and run
each step on all N payloads, so their cost does not grow with a per-frame Python loop.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["Field", "pack", "unpack", "replace", "covered_mask", "round_div", "INT64_MAX_US"]

#: Largest microsecond time that fits int64 nanoseconds.
INT64_MAX_US = int(np.iinfo(np.int64).max // 1000)


@dataclass(frozen=True)
class Field:
    """An integer field of a little-endian payload."""

    name: str
    start: int
    length: int
    signed: bool = False

    def __post_init__(self) -> None:
        if not 1 <= self.length <= 64:
            raise ValueError(f"{self.name}: field length must be 1..64 bits, found {self.length}")
        if self.start < 0:
            raise ValueError(f"{self.name}: start bit must be >= 0, found {self.start}")

    @property
    def raw_min(self) -> int:
        """Smallest raw value the field holds."""
        return -(1 << (self.length - 1)) if self.signed else 0

    @property
    def raw_max(self) -> int:
        """Largest raw value the field holds."""
        return (1 << (self.length - 1)) - 1 if self.signed else (1 << self.length) - 1

    @property
    def raw_dtype(self) -> np.dtype:
        """int64, or uint64 for an unsigned 64-bit field."""
        return np.dtype(np.uint64 if (self.length == 64 and not self.signed) else np.int64)

    def spans(self) -> list[tuple[int, int, int, int]]:
        """(byte, bit offset in byte, bit offset in field, number of bits) of each byte touched."""
        out = []
        bit, end = self.start, self.start + self.length
        while bit < end:
            byte, offset = divmod(bit, 8)
            nbits = min(8 - offset, end - bit)
            out.append((byte, offset, bit - self.start, nbits))
            bit += nbits
        return out


@lru_cache(maxsize=256)
def _word_layout(fields: tuple[Field, ...], length: int) -> tuple[tuple[Field, int, int], ...] | None:
    """(field, 64-bit word, shift) of each field if no field crosses a word boundary."""
    if length % 8:
        return None
    out = []
    for f in fields:
        word, shift = divmod(f.start, 64)
        if shift + f.length > 64 or (word + 1) * 8 > length:
            return None
        out.append((f, word, shift))
    return tuple(out)


def _as_u64(value) -> np.ndarray:
    v = np.asarray(value)
    return v.astype(np.int64, copy=False).view(np.uint64) if v.dtype.kind in "ib" else v.astype(np.uint64)


def pack(fields: Sequence[Field], raw: Mapping[str, np.ndarray], out: np.ndarray) -> np.ndarray:
    """Write the raw values of ``fields`` into ``out`` (N, L) uint8 (OR-ed in; ``out`` starts zeroed).

    ``raw[name]`` is an (N,) integer array (or scalar) in the field's range; values are
    masked to the field's width, so a negative value of a signed field lands in two's
    complement. Range checking is the caller's job (codecs raise ``CodecError("range")``).
    Payloads of whole 64-bit words whose fields stay inside a word (every ICD message)
    are packed a word at a time; others a byte at a time.
    """
    n = out.shape[0]
    layout = _word_layout(tuple(fields), out.shape[1]) if out.flags.c_contiguous else None
    if layout is not None:
        words = out.view("<u8")
        for f, word, shift in layout:
            u = _as_u64(raw[f.name])
            if f.length < 64:
                u = u & np.uint64((1 << f.length) - 1)
            words[:, word] |= u << np.uint64(shift) if shift else u
        return out
    for f in fields:
        u = np.broadcast_to(_as_u64(raw[f.name]), (n,))
        for byte, offset, shift, nbits in f.spans():
            part = (u >> np.uint64(shift)) & np.uint64((1 << nbits) - 1)
            if offset:
                part = part << np.uint64(offset)
            out[:, byte] |= part.astype(np.uint8)
    return out


def _signed(f: Field, u: np.ndarray) -> np.ndarray:
    if f.signed:
        if f.length < 64:
            sign = np.uint64(1 << (f.length - 1))
            u = (u ^ sign) - sign  # sign-extend in modular arithmetic
        return u.view(np.int64)
    return u if f.length == 64 else u.view(np.int64)


def unpack(fields: Sequence[Field], data: np.ndarray) -> dict[str, np.ndarray]:
    """Read the raw values of ``fields`` from ``data`` (N, L) uint8 -> {name: (N,) int64 or uint64}."""
    result: dict[str, np.ndarray] = {}
    layout = _word_layout(tuple(fields), data.shape[1])
    if layout is not None:
        words = np.ascontiguousarray(data).view("<u8")
        for f, word, shift in layout:
            u = words[:, word] >> np.uint64(shift) if shift else words[:, word].copy()
            if f.length < 64:
                u &= np.uint64((1 << f.length) - 1)
            result[f.name] = _signed(f, u)
        return result
    for f in fields:
        u = np.zeros(data.shape[0], np.uint64)
        for byte, offset, shift, nbits in f.spans():
            part = data[:, byte].astype(np.uint64)
            if offset:
                part = part >> np.uint64(offset)
            part &= np.uint64((1 << nbits) - 1)
            if shift:
                part = part << np.uint64(shift)
            u |= part
        result[f.name] = _signed(f, u)
    return result


def covered_mask(fields: Sequence[Field], length: int) -> np.ndarray:
    """(length,) uint8: the bits of each byte that some field covers."""
    mask = np.zeros(length, np.uint8)
    for f in fields:
        for byte, offset, _shift, nbits in f.spans():
            mask[byte] |= ((1 << nbits) - 1) << offset
    return mask


def round_div(t_ns: np.ndarray, unit_ns: int) -> np.ndarray:
    """Integer ``t_ns`` (int64) in units of ``unit_ns``, rounded half up, without overflow."""
    q, r = np.divmod(np.asarray(t_ns, np.int64), unit_ns)
    return q + (r >= (unit_ns + 1) // 2)


def replace(field: Field, raw, data: np.ndarray) -> np.ndarray:
    """Overwrite ``field`` in payloads ``data`` (N, L) uint8 in place with ``raw`` (N,) or scalar."""
    for byte, offset, _shift, nbits in field.spans():
        data[:, byte] &= np.uint8(~(((1 << nbits) - 1) << offset) & 0xFF)
    return pack([field], {field.name: raw}, data)
