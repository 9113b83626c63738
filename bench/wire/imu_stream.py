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
run is one event, classified by its first bytes and its length:

``sync``       the run does not start with ``AA 55`` (line noise, garbage);
``length``     it starts with ``AA 55`` and a length byte other than 36;
``truncated``  it starts with ``AA 55 24`` and is shorter than a frame (the next start came early);
``crc``        it starts with ``AA 55 24``, is at least a frame long, and the CRC fails
               (``format`` or ``range`` if the CRC holds but a field is out of range).

Split independence
------------------
The rule is a function of the whole byte stream, and the decoder applies it to each read
without guessing: a candidate is decided once its 42 bytes are there (until then it and
everything after it are held), a run is classified when the next ``AA 55`` (or a frame,
or the end of the stream) ends it, and a lone trailing ``AA`` waits for the next byte.
So the same bytes give the same frames, the same events and the same stamps whatever
the reads: a frame's ``rx_ns`` is the arrival of its last byte, a kept bad run's ``t_ns``
the arrival of its last byte. (A frame cut by its last byte followed by a frame whose
sync byte equals the missing CRC byte is, byte for byte, an intact frame: it is accepted,
and the next frame is a run; the same way for every split.)

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

__all__ = ["ImuStreamDecoder", "accept_frames", "run_kind", "RUN_KINDS"]

_OFFS = np.arange(FRAME_SIZE)
_KEEP_BYTES = 256  # bytes of a bad run kept for the recording
_KEEP_LABELS = 64  # sequence-labelled frames kept per kind and call (all are counted)
#: The kinds of bad runs.
RUN_KINDS = ("sync", "length", "truncated", "crc", "format", "range")


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


def run_kind(head: bytes, size: int) -> str:
    """The kind of a bad run of ``size`` bytes that begins with ``head`` (at least its
    first 42 bytes, or all of it)."""
    if size >= 2 and head[0] == 0xAA and head[1] == 0x55:
        if size >= 3 and head[2] != PAYLOAD_LENGTH:
            return "length"
        if size < FRAME_SIZE:
            return "truncated"
        kind = IMU_KINDS[int(check_frames(np.frombuffer(head[:FRAME_SIZE], np.uint8)[None])[0])]
        return kind if kind in ("format", "range") else "crc"
    return "sync"


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

    Counters: ``bytes_in`` (fed), ``frames`` (accepted, duplicates included), ``bytes_bad``
    (in bad runs); after :meth:`flush` ``bytes_in == 42 * frames + bytes_bad``.
    """

    def __init__(
        self, *, stale: bool = False, late_ns: int | None = None, stream: str = "serial:imu", tally: Tally | None = None
    ):
        self.late_ns = late_ns
        self.stream = stream
        self.tally = tally if tally is not None else Tally()
        self.sequence = SequenceChecker(256, VALUE_MASK if stale else None)
        self.frames = 0
        self.bytes_in = 0
        self.bytes_bad = 0
        self._buf = np.zeros(0, np.uint8)  # undecided bytes: from the first candidate still short of 42 bytes
        self._buf_rx = np.zeros(0, np.int64)  # their arrival times
        self._run: list | None = None  # the bad run in progress: [first bytes, size, arrival of its last byte]

    # ------------------------------------------------------------------ feeding
    def feed(self, data: bytes, rx_ns: int = 0) -> np.ndarray:
        """Decode the bytes of one read (arrived at ``rx_ns``); returns the new samples
        (:data:`~bench.wire.imu.IMU_SAMPLE_DTYPE`)."""
        new = np.frombuffer(bytes(data), np.uint8)
        return self._feed(new, np.array([new.size], np.int64), np.array([rx_ns], np.int64))

    def feed_batch(self, batch: SerialBatch) -> np.ndarray:
        """Decode a batch of received chunks in one call; each sample's ``rx_ns`` is the
        arrival time of the chunk holding its last byte."""
        if len(batch) == 0:
            return np.zeros(0, IMU_SAMPLE_DTYPE)
        return self._feed(batch.buf, batch.offsets[1:], batch.t_ns)

    def flush(self, rx_ns: int = 0) -> None:
        """End of stream: what is held (cut candidates) and the run in progress are bad runs
        (stamped with the arrival of their last byte; ``rx_ns`` is not needed)."""
        buf, n = self._buf, self._buf.size
        if n:
            syncs = np.flatnonzero((buf[:-1] == 0xAA) & (buf[1:] == 0x55))
            self._runs(buf, self._rx_fn(n, np.zeros(0, np.int64), np.zeros(0, np.int64)), syncs, 0, n, closes=True)
        self._close_run()
        self._buf, self._buf_rx = np.zeros(0, np.uint8), np.zeros(0, np.int64)

    def _rx_fn(self, n_held: int, ends: np.ndarray, times: np.ndarray):
        held_rx = self._buf_rx

        def rx_of(idx):
            idx = np.asarray(idx, np.int64)
            if times.size == 1 and (n_held == 0 or not idx.size or idx.min() >= n_held):
                return np.full(idx.shape, times[0], np.int64)  # one read, nothing held: one time
            out = np.empty(idx.shape, np.int64)
            old = idx < n_held
            out[old] = held_rx[idx[old]]
            if (~old).any():
                out[~old] = times[np.minimum(np.searchsorted(ends, idx[~old] - n_held, side="right"), times.size - 1)]
            return out

        return rx_of

    def _feed(self, new: np.ndarray, ends: np.ndarray, times: np.ndarray) -> np.ndarray:
        self.bytes_in += new.size
        n_held = self._buf.size
        buf = np.concatenate([self._buf, new]) if n_held else np.asarray(new, np.uint8)
        rx_of = self._rx_fn(n_held, ends, times)
        n = buf.size
        if n == 0:
            return np.zeros(0, IMU_SAMPLE_DTYPE)
        if self._run is not None and n >= 2 and buf[0] == 0xAA and buf[1] == 0x55:
            self._close_run()  # a candidate starts right after the run
        starts, syncs = accept_frames(buf)
        pos = int(starts[-1]) + FRAME_SIZE if starts.size else 0
        later = syncs[syncs >= pos]
        short = later[later + FRAME_SIZE > n]
        if short.size:  # a candidate still short of its 42 bytes: hold it and what follows
            hold, closes = int(short[0]), True
        elif n > pos and buf[n - 1] == 0xAA:  # a lone trailing AA may yet start a sync
            hold, closes = n - 1, False
        else:
            hold, closes = n, False
        prev = 0
        for s in starts.tolist():
            if s > prev:
                self._runs(buf, rx_of, syncs, prev, s, closes=True)
            prev = s + FRAME_SIZE
        self._runs(buf, rx_of, syncs, prev, hold, closes=closes)
        self._buf, self._buf_rx = buf[hold:].copy(), rx_of(np.arange(hold, n))
        return self._accept(buf, starts, rx_of(starts + FRAME_SIZE - 1) if starts.size else starts)

    # ------------------------------------------------------------------ bad runs
    def _runs(self, buf: np.ndarray, rx_of, syncs: np.ndarray, a: int, b: int, *, closes: bool) -> None:
        """The runs of ``buf[a:b]`` (cut at every sync strictly inside); the last one is
        ended by ``b`` when ``closes``, else it may go on in the next read."""
        if b <= a:
            return
        cuts = syncs[np.searchsorted(syncs, a, side="right") : np.searchsorted(syncs, b, side="left")]
        edges = [a, *cuts.tolist(), b]
        last_rx = rx_of(np.array(edges[1:], np.int64) - 1).tolist()
        for k in range(len(edges) - 1):
            r0, r1 = edges[k], edges[k + 1]
            if r0 == 0 and self._run is not None:  # the run of the last read goes on
                run = self._run
                if len(run[0]) < _KEEP_BYTES:
                    run[0] += buf[r0 : min(r1, r0 + _KEEP_BYTES - len(run[0]))].tobytes()
                run[1] += r1 - r0
                run[2] = last_rx[k]
            else:
                self._close_run()
                self._run = [buf[r0 : min(r1, r0 + _KEEP_BYTES)].tobytes(), r1 - r0, last_rx[k]]
            if k < len(edges) - 2 or closes:
                self._close_run()

    def _close_run(self) -> None:
        if self._run is None:
            return
        head, size, rx = self._run
        self._run = None
        self.bytes_bad += size
        self.tally.reject(rx, self.stream, run_kind(head, size), head, f"{size} bytes")

    # ------------------------------------------------------------------ frames
    def _accept(self, buf: np.ndarray, starts: np.ndarray, rx: np.ndarray) -> np.ndarray:
        if starts.size == 0:
            return np.zeros(0, IMU_SAMPLE_DTYPE)
        rows = buf[starts[:, None] + _OFFS]
        samples, _ = decode_frames(rows, check=False)  # checked in accept_frames
        samples["rx_ns"] = rx
        labels, lost = self.sequence.check(samples["counter"], rows)
        self.frames += starts.size
        for code in np.unique(labels[labels > 0]).tolist():
            idx = np.flatnonzero(labels == code)
            kind = SEQ_KINDS[code]
            for i in idx[:_KEEP_LABELS].tolist():
                self.tally.reject(
                    int(rx[i]), self.stream, kind, rows[i].tobytes(), f"counter {int(samples['counter'][i])}"
                )
            self.tally.count(kind, idx.size - min(idx.size, _KEEP_LABELS))
        self.tally.count("lost", int(lost.sum()))
        keep = labels != SEQ_DUPLICATE
        if self.late_ns is not None:
            late = keep & (samples["rx_ns"] - samples["t_ns"] > self.late_ns)
            self.tally.count("late", int(late.sum()))
        return samples[keep]
