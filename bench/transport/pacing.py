"""Real-time pacing of serial bytes at the configured baud rate and framing.

A UART puts one character on the line every ``bits_per_byte / baud`` seconds (start bit,
data bits, parity bit if any, stop bits: 10 bits for 8N1), one after the other; a pty or a
USB adapter's driver delivers whatever is written at once. So in real-time mode the
bench schedules the bytes itself:

* :func:`wire_times` gives, for chunks due at ``t_ns`` with ``lengths`` bytes, when each
  chunk starts and ends on the line, first in first out (a chunk waits for the one
  before it): ``end_i = max(t_i, end_{i-1}) + len_i * T_byte``, computed without a loop
  as ``C_i T + cummax_j<=i (t_j - C_{j-1} T)`` with ``C`` the cumulative byte count;
* :func:`byte_groups` cuts the byte stream into groups by the slot (``group_ns``) in
  which each byte's stop bit ends; a group is written when its last byte would have
  arrived, so a reader sees bytes no earlier than a real line would deliver them;
* :class:`PacedWriter` writes the groups at their times on a clock.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bench.frames import SerialBatch, parse_framing

__all__ = ["bits_per_byte", "parse_framing", "byte_time_ns", "wire_times", "byte_groups", "PacedWriter"]


def bits_per_byte(framing: str = "8N1") -> float:
    """Bits on the line per character: start + data + parity + stop (10 for 8N1)."""
    data, parity, stop = parse_framing(framing)
    return 1 + data + (parity != "N") + stop


def byte_time_ns(baud: float, framing: str = "8N1") -> float:
    """Line time of one character, ns (21701.4 ns at 460800 8N1)."""
    return bits_per_byte(framing) * 1e9 / baud


def wire_times(t_ns: np.ndarray, lengths: np.ndarray, byte_ns: float) -> tuple[np.ndarray, np.ndarray]:
    """(start, end) (N,) float64 ns of each chunk on the line, first in first out."""
    t = np.asarray(t_ns, np.float64)
    c = np.cumsum(np.asarray(lengths, np.float64)) * byte_ns
    c_prev = np.concatenate([[0.0], c[:-1]])
    end = c + np.maximum.accumulate(t - c_prev)
    start = end - np.asarray(lengths, np.float64) * byte_ns
    return start, end


def byte_groups(batch: SerialBatch, byte_ns: float, group_ns: int = 1_000_000) -> tuple[np.ndarray, np.ndarray]:
    """Write times (G,) int64 ns and byte offsets (G + 1,) of the groups of ``batch``.

    Group ``g`` is ``batch.buf[offsets[g]:offsets[g + 1]]``, to be written at ``times[g]``:
    the time its last byte's stop bit ends on a real line. ``group_ns`` bounds how far
    a byte may be held back (1 ms: about 46 bytes at 460800 baud).
    """
    lengths = batch.lengths
    if batch.buf.size == 0:
        return np.zeros(0, np.int64), np.zeros(1, np.int64)
    start, _ = wire_times(batch.t_ns, lengths, byte_ns)
    chunk_of = np.repeat(np.arange(len(batch)), lengths)
    k = np.arange(batch.buf.size) - np.repeat(batch.offsets[:-1], lengths)
    byte_end = start[chunk_of] + (k + 1) * byte_ns
    slot = np.floor(byte_end / group_ns).astype(np.int64)
    last = np.flatnonzero(np.diff(slot)) + 1
    offsets = np.concatenate([[0], last, [batch.buf.size]]).astype(np.int64)
    times = np.ceil(byte_end[offsets[1:] - 1]).astype(np.int64)
    return times, offsets


@dataclass
class PacedWriter:
    """Writes serial batches at line speed on a clock (real-time mode).

    ``write(data)`` is the link's write; ``now_ns()`` the bench clock (the same time base as the
    batches' ``t_ns``); ``sleep(s)`` waits.
    ``lag_ns`` is the largest delay of a group behind its due time seen so far (the host
    could not keep up); ``backlog_ns`` the largest wait of a chunk behind the chunks before
    it (the traffic exceeds the line's capacity).
    """

    write: Callable[[bytes], object]
    baud: float
    now_ns: Callable[[], int]
    framing: str = "8N1"
    sleep: Callable[[float], None] = time.sleep
    group_ns: int = 1_000_000
    lag_ns: int = 0
    backlog_ns: int = 0

    def write_batch(self, batch: SerialBatch) -> None:
        """Write every byte of ``batch`` when a real line would have delivered it."""
        byte_ns = byte_time_ns(self.baud, self.framing)
        if len(batch):
            start, _ = wire_times(batch.t_ns, batch.lengths, byte_ns)
            self.backlog_ns = max(self.backlog_ns, int(np.max(start - batch.t_ns)))
        times, offsets = byte_groups(batch, byte_ns, self.group_ns)
        buf = batch.buf
        for g, due in enumerate(times.tolist()):
            wait = due - self.now_ns()
            if wait > 0:
                self.sleep(wait * 1e-9)
            else:
                self.lag_ns = max(self.lag_ns, -wait)
            self.write(buf[offsets[g] : offsets[g + 1]].tobytes())
