"""Wire-level frames: the bench's own small types for CAN frames and serial bytes.

Codecs (:mod:`bench.wire`) produce and consume them, links (:mod:`bench.transport`)
send and receive them, fault injection and recording work on them. Kept free of any
bench dependency (like :mod:`bench.topics`) so that every layer can use it; only
:mod:`bench.transport` converts them to and from python-can messages.

Two forms of each:

* one frame at a time: :class:`CanFrame` ``(t_ns, can_id, data, fd)`` and
  :class:`SerialChunk` ``(t_ns, data)``, for per-frame code and tests;
* columnar batches: :class:`CanBatch` (times, ids, lengths, an ``(N, W)`` uint8 payload
  array) and :class:`SerialBatch` (times and chunk offsets into one byte buffer), which
  vectorised codecs fill and links send in one call.

``t_ns`` is integer nanoseconds of bench time: for outgoing traffic the time the frame
is due on the wire, for received traffic the time it arrived.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["CanFrame", "SerialChunk", "CanBatch", "SerialBatch", "CAN_FD_LENGTHS", "fd_length", "parse_framing"]

#: Payload lengths a CAN FD frame can have (DLC 0..15).
CAN_FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


_PARITIES = ("N", "E", "O", "M", "S")


def parse_framing(framing: str) -> tuple[int, str, float]:
    """(data bits, parity, stop bits) of a framing such as ``"8N1"``, ``"7E1"``, ``"8N1.5"``."""
    text = framing.strip().upper()
    if len(text) < 3 or not text[0].isdigit() or text[1] not in _PARITIES:
        raise ValueError(
            f"framing must look like 8N1 (data bits 5-8, parity N/E/O/M/S, stop 1/1.5/2), found {framing!r}"
        )
    data, parity, stop = int(text[0]), text[1], float(text[2:])
    if not 5 <= data <= 8 or stop not in (1.0, 1.5, 2.0):
        raise ValueError(f"framing must have 5-8 data bits and 1, 1.5 or 2 stop bits, found {framing!r}")
    return data, parity, stop


def fd_length(n: int) -> int:
    """The smallest CAN FD payload length that holds ``n`` bytes."""
    for length in CAN_FD_LENGTHS:
        if length >= n:
            return length
    raise ValueError(f"a CAN FD payload holds at most 64 bytes, found {n}")


@dataclass(frozen=True, slots=True)
class CanFrame:
    """One CAN frame: bench time (ns), 11-bit identifier, payload, FD flag (FD frames use BRS)."""

    t_ns: int
    can_id: int
    data: bytes
    fd: bool = False


@dataclass(frozen=True, slots=True)
class SerialChunk:
    """A run of bytes due on (or read from) a serial link at bench time ``t_ns``."""

    t_ns: int
    data: bytes


def _column(value, dtype, n: int) -> np.ndarray:
    """(n,) array of ``dtype`` from an array or one value for all."""
    if np.ndim(value) == 0:
        return np.full(n, value, dtype)
    out = np.asarray(value, dtype=dtype)
    if out.shape != (n,):
        raise ValueError(f"expected {n} values, found shape {out.shape}")
    return out.copy()


class CanBatch:
    """Many CAN frames in columns.

    Attributes
    ----------
    t_ns : (N,) int64
        Bench time of each frame, ns.
    can_id : (N,) uint32
        Identifier.
    length : (N,) uint8
        Payload length in bytes (0..64).
    data : (N, W) uint8
        Payloads, row ``i`` valid in ``[:length[i]]``, zero beyond; ``W >= max(length)``.
    fd : (N,) bool
        CAN FD frame (with bit-rate switch).
    """

    __slots__ = ("can_id", "data", "fd", "length", "t_ns")

    def __init__(self, t_ns, can_id, data, length=None, fd=None):
        self.t_ns = np.asarray(t_ns, dtype=np.int64).reshape(-1)
        n = self.t_ns.shape[0]
        self.can_id = _column(can_id, np.uint32, n)
        data = np.asarray(data, dtype=np.uint8)
        if data.ndim != 2 or data.shape[0] != n:
            raise ValueError(f"data must be (N, W) uint8 with N = {n}, found shape {data.shape}")
        self.data = data
        if length is None:
            length = data.shape[1]
        self.length = _column(length, np.uint8, n)
        if n and int(self.length.max()) > data.shape[1]:
            raise ValueError(f"length up to {int(self.length.max())} does not fit payload width {data.shape[1]}")
        if n and int(self.length.max()) > 64:
            raise ValueError(f"a CAN payload holds at most 64 bytes, found length {int(self.length.max())}")
        self.fd = _column(False if fd is None else fd, bool, n)

    def __len__(self) -> int:
        return int(self.t_ns.shape[0])

    def __repr__(self) -> str:
        return f"CanBatch({len(self)} frames, width {self.data.shape[1]})"

    @classmethod
    def empty(cls, width: int = 8) -> CanBatch:
        """A batch without frames."""
        return cls(np.zeros(0, np.int64), np.zeros(0, np.uint32), np.zeros((0, width), np.uint8))

    @classmethod
    def from_frames(cls, frames: Iterable[CanFrame]) -> CanBatch:
        """Columns of a sequence of frames."""
        frames = list(frames)
        width = max((len(f.data) for f in frames), default=8)
        data = np.zeros((len(frames), max(width, 1)), np.uint8)
        for i, f in enumerate(frames):
            data[i, : len(f.data)] = np.frombuffer(f.data, np.uint8)
        return cls(
            [f.t_ns for f in frames],
            [f.can_id for f in frames],
            data,
            [len(f.data) for f in frames],
            [f.fd for f in frames],
        )

    def frame(self, i: int) -> CanFrame:
        """Frame ``i`` as a :class:`CanFrame`."""
        n = int(self.length[i])
        return CanFrame(int(self.t_ns[i]), int(self.can_id[i]), self.data[i, :n].tobytes(), bool(self.fd[i]))

    def frames(self) -> list[CanFrame]:
        """Every frame as a :class:`CanFrame` (for per-frame code; not for hot paths)."""
        return [self.frame(i) for i in range(len(self))]

    def take(self, index) -> CanBatch:
        """The frames selected by an index array or boolean mask, in that order."""
        return CanBatch(self.t_ns[index], self.can_id[index], self.data[index], self.length[index], self.fd[index])

    def with_width(self, width: int) -> CanBatch:
        """The same frames with a payload array at least ``width`` columns wide."""
        if width <= self.data.shape[1]:
            return self
        data = np.zeros((len(self), width), np.uint8)
        data[:, : self.data.shape[1]] = self.data
        return CanBatch(self.t_ns, self.can_id, data, self.length, self.fd)

    @staticmethod
    def concat(batches: Sequence[CanBatch]) -> CanBatch:
        """The frames of ``batches`` one after another (not re-sorted)."""
        batches = [b for b in batches if len(b)]
        if not batches:
            return CanBatch.empty()
        width = max(b.data.shape[1] for b in batches)
        batches = [b.with_width(width) for b in batches]
        return CanBatch(
            np.concatenate([b.t_ns for b in batches]),
            np.concatenate([b.can_id for b in batches]),
            np.concatenate([b.data for b in batches]),
            np.concatenate([b.length for b in batches]),
            np.concatenate([b.fd for b in batches]),
        )

    def sorted(self) -> CanBatch:
        """The frames in time order (stable: equal times keep their order)."""
        order = np.argsort(self.t_ns, kind="stable")
        return self.take(order)


class SerialBatch:
    """Many serial chunks in columns: chunk ``i`` is ``buf[offsets[i]:offsets[i+1]]``.

    Attributes
    ----------
    t_ns : (N,) int64
        Bench time of each chunk, ns.
    offsets : (N + 1,) int64
        Start of each chunk in ``buf``; ``offsets[-1] == len(buf)``.
    buf : (M,) uint8
        The bytes of all chunks, in order.
    """

    __slots__ = ("buf", "offsets", "t_ns")

    def __init__(self, t_ns, offsets, buf):
        self.t_ns = np.asarray(t_ns, dtype=np.int64).reshape(-1)
        self.offsets = np.asarray(offsets, dtype=np.int64).reshape(-1)
        self.buf = np.frombuffer(buf, np.uint8) if isinstance(buf, bytes | bytearray) else np.asarray(buf, np.uint8)
        if self.offsets.shape[0] != self.t_ns.shape[0] + 1 or self.offsets[0] != 0 or self.offsets[-1] != self.buf.size:
            raise ValueError("offsets must start at 0, end at len(buf) and have one entry more than t_ns")
        if self.offsets.size > 2 and np.any(self.offsets[1:] < self.offsets[:-1]):
            raise ValueError("offsets must not decrease (a chunk cannot have a negative length)")

    def __len__(self) -> int:
        return int(self.t_ns.shape[0])

    def __repr__(self) -> str:
        return f"SerialBatch({len(self)} chunks, {self.buf.size} bytes)"

    @property
    def lengths(self) -> np.ndarray:
        """(N,) int64 length of each chunk."""
        return np.diff(self.offsets)

    @classmethod
    def empty(cls) -> SerialBatch:
        """A batch without chunks."""
        return cls(np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros(0, np.uint8))

    @classmethod
    def from_fixed(cls, t_ns, frames: np.ndarray) -> SerialBatch:
        """Chunks of equal length from an ``(N, L)`` uint8 array (one frame a row)."""
        frames = np.ascontiguousarray(frames, dtype=np.uint8)
        n, size = frames.shape
        return cls(t_ns, np.arange(n + 1, dtype=np.int64) * size, frames.reshape(-1))

    @classmethod
    def from_chunks(cls, chunks: Iterable[SerialChunk]) -> SerialBatch:
        """Columns of a sequence of chunks."""
        chunks = list(chunks)
        lengths = [len(c.data) for c in chunks]
        offsets = np.zeros(len(chunks) + 1, np.int64)
        np.cumsum(lengths, out=offsets[1:])
        return cls([c.t_ns for c in chunks], offsets, b"".join(c.data for c in chunks))

    def chunk(self, i: int) -> SerialChunk:
        """Chunk ``i`` as a :class:`SerialChunk`."""
        return SerialChunk(int(self.t_ns[i]), self.buf[self.offsets[i] : self.offsets[i + 1]].tobytes())

    def chunks(self) -> list[SerialChunk]:
        """Every chunk as a :class:`SerialChunk` (for per-chunk code; not for hot paths)."""
        return [self.chunk(i) for i in range(len(self))]

    def tobytes(self) -> bytes:
        """All bytes in order."""
        return self.buf.tobytes()

    def take(self, index) -> SerialBatch:
        """The chunks selected by an index array or boolean mask, in that order."""
        index = np.arange(len(self))[index]
        starts, stops = self.offsets[index], self.offsets[index + 1]
        lengths = stops - starts
        offsets = np.zeros(index.size + 1, np.int64)
        np.cumsum(lengths, out=offsets[1:])
        if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
            buf = self.buf[starts[0] : stops[-1]]
        else:
            # gather by a per-byte source index (no per-chunk loop)
            src = np.repeat(starts - offsets[:-1], lengths) + np.arange(offsets[-1])
            buf = self.buf[src]
        return SerialBatch(self.t_ns[index], offsets, buf)

    @staticmethod
    def concat(batches: Sequence[SerialBatch]) -> SerialBatch:
        """The chunks of ``batches`` one after another (not re-sorted)."""
        batches = [b for b in batches if len(b)]
        if not batches:
            return SerialBatch.empty()
        shifts = np.cumsum([0] + [b.buf.size for b in batches[:-1]])
        offsets = np.concatenate(
            [batches[0].offsets[:1]] + [b.offsets[1:] + s for b, s in zip(batches, shifts, strict=True)]
        )
        return SerialBatch(np.concatenate([b.t_ns for b in batches]), offsets, np.concatenate([b.buf for b in batches]))

    def sorted(self) -> SerialBatch:
        """The chunks in time order (stable)."""
        order = np.argsort(self.t_ns, kind="stable")
        if np.array_equal(order, np.arange(len(self))):
            return self
        return self.take(order)
