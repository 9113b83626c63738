"""Sequence checks on the good frames of one stream: counters, duplicates, stale values.

Every ICD stream carries a counter (alive counter modulo 16 on classic CAN, epoch counter
modulo 256 on NAV frames, frame counter modulo 256 on the IMU link). A receiver compares
each good frame with the previous good frame of the same stream, like an AUTOSAR E2E
check, and labels it:

``duplicate``
    every byte equal to the previous frame (the same frame twice);
``repeat``
    counter equal to the previous one, payload different (a stale counter);
``skip``
    counter advanced by more than one; ``delta - 1`` frames count as lost;
``stale``
    counter advanced by one but every value byte (the bytes outside counter, time of
    validity and CRC) equal to the previous frame's (frozen data); only checked on
    streams whose values change from frame to frame.

The labels are computed for a whole batch at once; :class:`SequenceChecker` carries the
last frame across batches.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "SEQ_OK",
    "SEQ_DUPLICATE",
    "SEQ_REPEAT",
    "SEQ_SKIP",
    "SEQ_STALE",
    "SEQ_KINDS",
    "SequenceChecker",
    "CounterSequence",
]

SEQ_OK, SEQ_DUPLICATE, SEQ_REPEAT, SEQ_SKIP, SEQ_STALE = range(5)
#: Label names by code.
SEQ_KINDS = ("ok", "duplicate", "repeat", "skip", "stale")


class SequenceChecker:
    """Labels of the good frames of one stream, batch after batch.

    Parameters
    ----------
    modulus:
        Counter modulus (16 or 256).
    value_mask:
        (L,) uint8 mask of the value bits compared by the stale check, or None to skip it.
    """

    def __init__(self, modulus: int, value_mask: np.ndarray | None = None):
        self.modulus = modulus
        self.value_mask = None if value_mask is None else np.asarray(value_mask, np.uint8)
        self.last_counter: int | None = None
        self.last_row: np.ndarray | None = None

    def check(self, counters: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Labels (N,) uint8 (:data:`SEQ_KINDS`) and frames lost before each (N,) int64.

        ``counters`` (N,) are the frames' counters, ``rows`` (N, L) their bytes.
        """
        counters = np.asarray(counters, np.int64)
        rows = np.asarray(rows, np.uint8)
        n = counters.shape[0]
        labels = np.zeros(n, np.uint8)
        lost = np.zeros(n, np.int64)
        if n == 0:
            return labels, lost
        if self.last_row is not None and self.last_row.shape[0] != rows.shape[1]:
            self.last_row, self.last_counter = None, None
        has_prev = np.ones(n, bool)
        if self.last_counter is None:
            prev_c = np.concatenate([counters[:1] - 1, counters[:-1]])
            prev_rows = np.concatenate([rows[:1] ^ 0xFF, rows[:-1]])
            has_prev[0] = False
        else:
            prev_c = np.concatenate([[self.last_counter], counters[:-1]])
            prev_rows = np.concatenate([self.last_row[None], rows[:-1]])
        delta = (counters - prev_c) % self.modulus
        identical = np.all(rows == prev_rows, axis=1) & has_prev
        labels[(delta > 1) & has_prev] = SEQ_SKIP
        lost[labels == SEQ_SKIP] = delta[labels == SEQ_SKIP] - 1
        labels[(delta == 0) & has_prev] = SEQ_REPEAT
        if self.value_mask is not None:
            same = np.all((rows & self.value_mask) == (prev_rows & self.value_mask), axis=1)
            labels[same & (delta == 1) & has_prev] = SEQ_STALE
        labels[identical] = SEQ_DUPLICATE
        self.last_counter = int(counters[-1])
        self.last_row = rows[-1].copy()
        return labels, lost


class CounterSequence:
    """The counter a sender puts in each transmission: +1 modulo ``modulus``, across batches."""

    def __init__(self, modulus: int, start: int = 0):
        self.modulus = modulus
        self.next = start % modulus

    def take(self, n: int) -> np.ndarray:
        """The counters of the next ``n`` transmissions, (n,) int64."""
        out = (self.next + np.arange(n, dtype=np.int64)) % self.modulus
        self.next = (self.next + n) % self.modulus
        return out
