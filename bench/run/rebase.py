"""A recording's run moved in bench time: what ``bench replay --start S`` does to it.

The replay of a recording from a seek point ``S`` is a run of its own whose bench time
starts at the seek point: bench time ``t`` of the source becomes ``t - S`` and the UTC of
bench time zero (the epoch) becomes ``epoch + S``, so every UTC time (NMEA) stays what it
was. Everything before ``S`` is left out; what remains is moved:

* samples and truth: every integer ``*_ns`` field (``t_ns``, ``tx_ns``...) minus ``S``;
* CAN frames: their times minus ``S``; the payload of every good BENCH_TIME minus ``S``
  and of every good BENCH_EPOCH plus ``S`` (lockstep bit and alive counter kept, CRC
  recomputed; frames a wire fault broke stay as they were);
* IMU bytes: chunk times minus ``S``; the time of validity of every good frame minus
  ``S`` (CRC recomputed), at least 0;
* NMEA bytes: chunk times minus ``S`` (their UTC fields hold with the moved epoch);
* segments, fault windows and bench commands: moved, cut at the new zero (those that
  ended before it are left out).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.faults.schedule import FaultWindow
from bench.frames import CanBatch, SerialBatch
from bench.run.traffic import BENCH_TIME_ID
from bench.wire.can import codec
from bench.wire.imu import FRAME_DTYPE, FRAME_SIZE, refresh_crc
from bench.wire.imu_stream import accept_frames

__all__ = ["rebase_records", "rebase_can", "rebase_serial", "rebase_segments", "rebase_window"]

_EPOCH_ID = codec("BENCH_EPOCH").frame_id
_OFFS = np.arange(FRAME_SIZE)


def rebase_records(records: np.ndarray, s_ns: int) -> np.ndarray:
    """Records at or after ``s_ns``, every integer ``*_ns`` field moved by ``-s_ns``."""
    out = records[records["t_ns"] >= s_ns].copy()
    for name in out.dtype.names or ():
        if name.endswith("_ns") and out.dtype[name].kind == "i":
            out[name] -= s_ns
    return out


def _recoded(can: CanBatch, rows: np.ndarray, name: str, field: str, shift_ns: int) -> None:
    c = codec(name)
    values, status = c.decode(can.take(rows))
    good = status == 0
    if not good.any():
        return
    sel = rows[good]
    fields = {k: np.asarray(v)[good] for k, v in values.items()}
    fields[field] = np.maximum(np.round(fields[field]).astype(np.int64) + shift_ns, 0)
    rebuilt = c.encode(can.t_ns[sel], fields)
    can.data[sel, :8] = rebuilt.data[:, :8]


def rebase_can(can: CanBatch, s_ns: int) -> CanBatch:
    """CAN frames at or after ``s_ns`` moved by ``-s_ns`` (see the module docstring)."""
    keep = can.take(np.flatnonzero(can.t_ns >= s_ns))
    out = CanBatch(keep.t_ns - s_ns, keep.can_id, keep.data.copy(), keep.length, keep.fd)
    if s_ns:
        _recoded(out, np.flatnonzero(out.can_id == BENCH_TIME_ID), "BENCH_TIME", "time_ns", -s_ns)
        _recoded(out, np.flatnonzero(out.can_id == _EPOCH_ID), "BENCH_EPOCH", "epoch_utc_ns", s_ns)
    return out


def rebase_serial(batch: SerialBatch, s_ns: int, *, imu: bool) -> SerialBatch:
    """Serial chunks at or after ``s_ns`` moved by ``-s_ns``; on the IMU line the frames'
    times of validity too."""
    keep = batch.take(np.flatnonzero(batch.t_ns >= s_ns))
    buf = keep.buf.copy()
    if imu and s_ns and buf.size:
        starts, _ = accept_frames(buf)
        if starts.size:
            rows = buf[starts[:, None] + _OFFS]
            rec = rows.view(FRAME_DTYPE).reshape(-1)
            rec["time_us"] = np.maximum(rec["time_us"].astype(np.int64) - s_ns // 1000, 0).astype(np.uint64)
            refresh_crc(rows)
            buf[starts[:, None] + _OFFS] = rows
    return SerialBatch(keep.t_ns - s_ns, keep.offsets, buf)


def rebase_segments(doc: dict[str, Any], s_ns: int) -> dict[str, Any]:
    """A ``/scenario/segments`` document with its stretches moved and cut at zero."""
    s = s_ns * 1e-9
    out = []
    for seg in doc.get("segments", []):
        try:
            start, end = float(seg["start_s"]), float(seg["end_s"])
        except (KeyError, TypeError, ValueError):
            continue
        if end <= s:
            continue
        out.append({**seg, "start_s": max(start - s, 0.0), "end_s": end - s})
    return {**doc, "segments": out}


def rebase_window(w: FaultWindow, s_ns: int) -> FaultWindow | None:
    """A fault window moved and cut at zero (None if it ended before the seek point)."""
    if w.end_ns <= s_ns:
        return None
    return FaultWindow(w.id, w.layer, w.target, w.kind, max(w.start_ns - s_ns, 0), w.end_ns - s_ns, w.params, w.origin)
