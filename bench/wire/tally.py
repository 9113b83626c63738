"""Counting and keeping what a receiver rejects or flags, without ever raising.

A :class:`Tally` counts events by kind (``crc``, ``counter``, ``length``, ``unknown_id``,
``sync``, ``skip`` ...) and keeps the bad frames themselves, bytes and reason, for the
recording. It never stops a run: the receiver hands on the good frames and moves on.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any

__all__ = ["BadFrame", "Tally"]


@dataclass(frozen=True, slots=True)
class BadFrame:
    """A frame (or run of bytes) a receiver rejected or flagged."""

    t_ns: int  # arrival, bench time
    stream: str  # "can:NAV_SOLUTION", "can:0x123", "serial:imu", "serial:gnss"
    kind: str
    data: bytes
    reason: str = ""

    def to_json(self) -> dict[str, Any]:
        """The record written to the recording (bytes as hex)."""
        return {
            "t_ns": self.t_ns,
            "stream": self.stream,
            "kind": self.kind,
            "data": self.data.hex(),
            "reason": self.reason,
        }


class Tally:
    """Counts by kind and the kept bad frames (the first ``keep`` of them; all are counted)."""

    def __init__(self, keep: int = 100_000):
        self.counts: Counter[str] = Counter()
        self.bad: list[BadFrame] = []
        self.keep = keep
        self.dropped_records = 0

    def count(self, kind: str, n: int = 1) -> None:
        """Count ``n`` events of ``kind`` without keeping a frame (e.g. frames lost)."""
        if n:
            self.counts[kind] += int(n)

    def reject(self, t_ns: int, stream: str, kind: str, data: bytes, reason: str = "") -> None:
        """Count one bad frame and keep it."""
        self.counts[kind] += 1
        if len(self.bad) < self.keep:
            self.bad.append(BadFrame(int(t_ns), stream, kind, bytes(data), reason))
        else:
            self.dropped_records += 1

    def __getitem__(self, kind: str) -> int:
        return self.counts.get(kind, 0)

    def as_dict(self) -> dict[str, int]:
        """Non-zero counts by kind."""
        return {k: v for k, v in sorted(self.counts.items()) if v}

    def pop_bad(self) -> list[BadFrame]:
        """The kept bad frames since the last call (the recorder drains them)."""
        out, self.bad = self.bad, []
        return out
