"""Decoding a byte stream of IMU frames: resynchronisation, counting, sequence checks.

Resynchronisation rule
----------------------
Every position where the bytes ``AA 55`` occur is a candidate frame start. A candidate is
good when its 42 bytes are there, its length byte is 36, its CRC matches and its fields
are in range. Good candidates are accepted greedily from the front: after a frame at
``p`` the search goes on at ``p + 42``; after a bad candidate it goes on at the next
``AA 55`` (one byte on, never 42), so a false or broken start never swallows an intact
frame that follows it.

The bytes between two accepted frames are split at every ``AA 55`` into runs, and each
run is one event, classified by its first bytes:

``sync``       the run does not start with ``AA 55`` (line noise, garbage);
``length``     it starts with ``AA 55`` and a length byte other than 36;
``truncated``  it starts with ``AA 55 24`` and is shorter than a frame (the next start came early);
``crc``        it starts with ``AA 55 24``, is at least a frame long, and the CRC fails
               (``format`` or ``range`` if the CRC holds but a field is out of range).

Accepted frames then go through the :class:`~bench.wire.sequence.SequenceChecker` of the
frame counter (``duplicate``, ``repeat``, ``skip`` with ``lost``, and ``stale`` when asked) and, when a
tolerance is given, a ``late`` check of arrival time minus time of validity. Duplicates
are counted and not handed on; every other accepted frame is.

The work per call is vectorised over the frames of the chunk; Python loops run only over
the bad runs and over the breaks in a run of back-to-back frames.
"""

from __future__ import annotations

import numpy as np

from bench.frames import SerialBatch
from bench.wire.imu import (
    FRAME_SIZE,
    IMU_KINDS,
    IMU_SAMPLE_DTYPE,
    PAYLOAD_LENGTH,
    VALUE_MASK,
    check_frames,
    decode_frames,
)
from bench.wire.sequence import SEQ_DUPLICATE, SEQ_KINDS, SequenceChecker
from bench.wire.tally import Tally

__all__ = ["ImuStreamDecoder", "accept_frames"]

_OFFS = np.arange(FRAME_SIZE)
_KEEP_BYTES = 256  # bytes of a bad run kept for the recording


def accept_frames(buf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start offsets of the frames the resynchronisation rule accepts in ``buf`` (greedy,
    one step per run of back-to-back good frames), and every ``AA 55`` position."""
    n = buf.size
    syncs = np.flatnonzero((buf[:-1] == 0xAA) & (buf[1:] == 0x55)) if n > 1 else np.zeros(0, np.int64)
    complete = syncs[syncs + FRAME_SIZE <= n]
    valid = complete[check_frames(buf[complete[:, None] + _OFFS]) == 0] if complete.size else complete
    accepted = []
    if valid.size:
        ends = np.append(np.flatnonzero(np.diff(valid) != FRAME_SIZE), valid.size - 1)
        i = 0
        while i < valid.size:
            j = int(ends[np.searchsorted(ends, i)])
            accepted.append(valid[i : j + 1])
            i = int(np.searchsorted(valid, valid[j] + FRAME_SIZE))
    return (np.concatenate(accepted) if accepted else np.zeros(0, np.int64)), syncs


class ImuStreamDecoder:
    """Stateful decoder of the ``imu`` serial stream (see the module docstring).

    Parameters
    ----------
    stale:
        Check for frozen values (``stale``): only for data that must change every frame
        (a noiseless IMU at rest repeats its increments exactly).
    late_ns:
        Count a frame as ``late`` when its arrival is more than this after its time of
        validity (None: no check; needs arrival times in bench time).
    stream:
        Name used in the tally's kept frames.
    """

    def __init__(
        self, *, stale: bool = False, late_ns: int | None = None, stream: str = "serial:imu", tally: Tally | None = None
    ):
        self.late_ns = late_ns
        self.stream = stream
        self.tally = tally if tally is not None else Tally()
        self.sequence = SequenceChecker(256, VALUE_MASK if stale else None)
        self.frames = 0  # frames accepted (duplicates included)
        self.bytes_in = 0
        self._buf = np.zeros(0, np.uint8)
        self._carried = 0  # bytes of earlier reads at the front of the current buffer
        #: End offsets (exclusive, in the bytes of the last ``feed``) of the samples it returned.
        self.last_ends = np.zeros(0, np.int64)
        self._pending: str | None = None  # "sync": an uncounted noise run continues; "counted": a counted run does
        self._noise = b""  # first bytes of the uncounted noise run, for the record

    # ------------------------------------------------------------------ bad runs
    @staticmethod
    def _starts_with_sync(run: np.ndarray) -> bool:
        return run.size >= 2 and run[0] == 0xAA and run[1] == 0x55

    def _run_kind(self, run: np.ndarray) -> str:
        if self._starts_with_sync(run):
            if run.size >= 3 and run[2] != PAYLOAD_LENGTH:
                return "length"
            if run.size < FRAME_SIZE:
                return "truncated"
            kind = IMU_KINDS[int(check_frames(run[None, :FRAME_SIZE])[0])]
            return "crc" if kind == "ok" else kind
        return "sync"

    def _reject(self, run: np.ndarray, kind: str, rx_ns: int) -> None:
        self.tally.reject(rx_ns, self.stream, kind, run[:_KEEP_BYTES].tobytes(), f"{run.size} bytes")

    def _end_pending(self, run: np.ndarray, rx_ns: int) -> None:
        """The noise run that began in earlier bytes ends with ``run``."""
        if self._pending == "sync":
            self._reject(np.frombuffer(self._noise + run[:_KEEP_BYTES].tobytes(), np.uint8), "sync", rx_ns)
        self._pending = None
        self._noise = b""

    def _finish(self, buf: np.ndarray, r0: int, r1: int, rx_ns: int) -> None:
        run = buf[r0:r1]
        if r0 == 0 and self._pending is not None:
            self._end_pending(run, rx_ns)
        else:
            self._reject(run, self._run_kind(run), rx_ns)

    def _hold(self, buf: np.ndarray, r0: int, r1: int, rx_ns: int) -> None:
        """The last run of the buffer: keep what may still become a frame."""
        run = buf[r0:r1]
        if self._starts_with_sync(run):
            if run.size < FRAME_SIZE:
                self._buf = run.copy()
                return
            self._reject(run, self._run_kind(run), rx_ns)  # a whole bad frame: counted now,
            self._pending = "counted"  # the bytes after it belong to the same run
        elif run[:-1].size or run[-1] != 0xAA:  # noise (a lone trailing 0xAA may yet start a sync)
            if not (r0 == 0 and self._pending is not None):
                self._pending, self._noise = "sync", b""
            if self._pending == "sync" and len(self._noise) < _KEEP_BYTES:
                noise = run[:-1] if run[-1] == 0xAA else run
                self._noise += noise[: _KEEP_BYTES - len(self._noise)].tobytes()
        self._buf = run[-1:].copy() if run[-1] == 0xAA else np.zeros(0, np.uint8)

    @staticmethod
    def _split_runs(a: int, b: int, syncs: np.ndarray) -> list[tuple[int, int]]:
        """The runs of ``[a, b)`` cut at every sync position strictly inside it."""
        if b <= a:
            return []
        cuts = syncs[np.searchsorted(syncs, a, side="right") : np.searchsorted(syncs, b, side="left")]
        edges = [a, *cuts.tolist(), b]
        return [(edges[k], edges[k + 1]) for k in range(len(edges) - 1) if edges[k + 1] > edges[k]]

    # ------------------------------------------------------------------ feeding
    def feed(self, data: bytes, rx_ns: int = 0) -> np.ndarray:
        """Decode the bytes of one read; returns the new samples (:data:`IMU_SAMPLE_DTYPE`)."""
        new = np.frombuffer(data, np.uint8)
        self.bytes_in += new.size
        self._carried = self._buf.size
        self.last_ends = np.zeros(0, np.int64)
        buf = np.concatenate([self._buf, new]) if self._buf.size else new.copy()
        n = buf.size
        if n == 0:
            return np.zeros(0, IMU_SAMPLE_DTYPE)
        if self._pending is not None and self._starts_with_sync(buf):
            self._end_pending(buf[:0], rx_ns)
        starts, syncs = accept_frames(buf)
        prev_end = np.concatenate([[0], starts[:-1] + FRAME_SIZE])
        for i in np.flatnonzero(starts > prev_end).tolist():  # only where bad bytes lie between frames
            for r0, r1 in self._split_runs(int(prev_end[i]), int(starts[i]), syncs):
                self._finish(buf, r0, r1, rx_ns)
        pos = int(starts[-1]) + FRAME_SIZE if starts.size else 0
        tail = self._split_runs(pos, n, syncs)
        for r0, r1 in tail[:-1]:
            self._finish(buf, r0, r1, rx_ns)
        if tail:
            self._hold(buf, *tail[-1], rx_ns)
        else:
            self._buf = np.zeros(0, np.uint8)
        return self._accept(buf, starts, rx_ns)

    def _accept(self, buf: np.ndarray, starts: np.ndarray, rx_ns: int) -> np.ndarray:
        if starts.size == 0:
            return np.zeros(0, IMU_SAMPLE_DTYPE)
        rows = buf[starts[:, None] + _OFFS]
        samples, _ = decode_frames(rows, rx_ns, check=False)  # checked in feed
        labels, lost = self.sequence.check(samples["counter"], rows)
        self.frames += starts.size
        for code in np.unique(labels[labels > 0]).tolist():
            idx = np.flatnonzero(labels == code)
            kind = SEQ_KINDS[code]
            for i in idx[:64].tolist():  # keep a few of each kind; count them all
                self.tally.reject(rx_ns, self.stream, kind, rows[i].tobytes(), f"counter {int(samples['counter'][i])}")
            self.tally.count(kind, idx.size - min(idx.size, 64))
        self.tally.count("lost", int(lost.sum()))
        keep = labels != SEQ_DUPLICATE
        self.last_ends = (starts + FRAME_SIZE - self._carried)[keep]
        if self.late_ns is not None:
            late = keep & (np.int64(rx_ns) - samples["t_ns"] > self.late_ns)
            self.tally.count("late", int(late.sum()))
        return samples[keep]

    def feed_batch(self, batch: SerialBatch) -> np.ndarray:
        """Decode a batch of received chunks in one call; each sample's ``rx_ns`` is the
        arrival time of the chunk holding its last byte."""
        if len(batch) == 0:
            return np.zeros(0, IMU_SAMPLE_DTYPE)
        samples = self.feed(batch.tobytes(), int(batch.t_ns[-1]))
        if samples.size:
            chunk = np.searchsorted(batch.offsets[1:], self.last_ends - 1, side="right")
            samples["rx_ns"] = batch.t_ns[chunk]
        return samples

    def flush(self, rx_ns: int = 0) -> None:
        """End of stream: count what is left as a bad run."""
        if self._buf.size and self._starts_with_sync(self._buf):
            self._reject(self._buf, self._run_kind(self._buf), rx_ns)
        elif self._buf.size:
            self._finish(self._buf, 0, self._buf.size, rx_ns)
        elif self._pending == "sync":
            self._reject(self._buf, "sync", rx_ns)
        self._buf = np.zeros(0, np.uint8)
        self._pending = None
