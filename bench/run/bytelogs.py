"""Byte logs of the serial lines as a vehicle's logger keeps them, cut into timed chunks.

A byte log is the raw stream of one line with no arrival times: what a logger wrote to
a file from the port. The replay (:mod:`bench.run.logreplay`) needs each byte's time on
the line, so the stream is cut into chunks, each due at a time the bytes themselves carry:

IMU (ICD 3)
    Frames are found with the resynchronisation rule of
    :class:`~bench.wire.imu_stream.ImuStreamDecoder` (every ``AA 55`` a candidate; a
    candidate with its 42 bytes, length 36, a good CRC and fields in range is a frame;
    frames accepted greedily from the front). Each chunk is one frame plus the bytes
    before it that are no frame (garbage, broken frames); the bytes after the last frame
    join the last chunk. A chunk is due at its frame's time of validity (bytes 4-11),
    shifted by ``shift_ns`` when asked (the time fields are then rewritten and the CRC
    recomputed). A frame whose time is earlier than one before it goes out with the
    earlier one (a serial line never reorders), so the bytes keep their order.

NMEA (ICD 4)
    A sentence runs from ``$`` to the first CR LF with no ``$`` between, within 82
    characters (:func:`bench.wire.nmea_stream.frame_events`, the framing of
    :class:`~bench.wire.nmea_stream.NmeaStreamDecoder`). Each chunk is one sentence plus
    the bytes before it outside any sentence; bytes after the last sentence join the last
    chunk. Sentences that decode (RMC, GGA, GST, ZDA; any talker; checksum, format and
    every field's range as the stream decoder checks them) give the UTC time of day of
    their epoch; the others (VTG, GSA, GSV, broken sentences, counted by kind) belong to
    the epoch in progress (the first epoch, for those before any time). The date of an
    epoch comes from its ZDA or RMC; an epoch without one takes the date of the epoch
    before, moved on a day when the time of day falls back by more than 12 h (midnight),
    and epochs before the first date take it backwards the same way. A log without any
    date takes the day from the UTC of bench time zero (the day that puts the first epoch
    within 12 h of it).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from bench.errors import CodecError, ConfigError
from bench.frames import SerialBatch
from bench.wire.bits import INT64_MAX_US
from bench.wire.imu import FRAME_DTYPE, FRAME_SIZE, refresh_crc
from bench.wire.imu_stream import accept_frames
from bench.wire.nmea_fields import days_since_1970, decode_fields, parse_sentence
from bench.wire.nmea_stream import frame_events

__all__ = [
    "imu_log_chunks",
    "NmeaLog",
    "read_nmea_log",
    "DAY_NS",
    "describe",
]

DAY_NS = 86_400_000_000_000
_OFFS = np.arange(FRAME_SIZE)
_MAX_SHIFT_NS = 100 * 366 * DAY_NS  # a century
_TIMED = ("RMC", "GGA", "GST", "ZDA")
_MAGIC = {b"\x89MCAP": "an MCAP recording (give it as the recording, not as a field log)", b"LOGG": "a BLF CAN log"}


def describe(data: bytes) -> str:
    """What a file that is not the log expected looks like, in a few words."""
    head = data[:4096]
    for magic, name in _MAGIC.items():
        if head.startswith(magic):
            return name
    buf = np.frombuffer(data[:1 << 20], np.uint8)
    starts, _ = accept_frames(buf)
    if starts.size:
        return f"{starts.size} ICD IMU frames in its first MiB (the imu line's log?)"
    events, _ = frame_events(data[:1 << 20], final=True)
    lines = sum(1 for kind, _, _ in events if kind == "line")
    if lines:
        return f"{lines} NMEA sentences in its first MiB (the gnss line's log?)"
    printable = np.count_nonzero((buf >= 0x20) & (buf < 0x7F) | (buf == 9) | (buf == 10) | (buf == 13))
    if buf.size and printable >= 0.95 * buf.size:
        first = data[: data.find(b"\n")] if b"\n" in data[:200] else data[:60]
        ends = "in CR LF" if b"\r\n" in head else "in LF alone" if b"\n" in head else "nowhere"
        return f"text whose lines end {ends}, starting {first[:60].decode('ascii', 'backslashreplace')!r}"
    return f"binary data ({buf.size - printable} of its first {buf.size} bytes not printable text)"


def _frame_starts(buf: np.ndarray) -> tuple[np.ndarray, int]:
    """Start offsets of the frames of ``buf`` (greedy from the front) and the number of
    ``AA 55`` candidates that were no frame."""
    starts, syncs = accept_frames(buf)
    return starts, int(syncs.size - starts.size)


def _chunks(ends: np.ndarray, size: int) -> np.ndarray:
    """Chunk offsets (N + 1,) cutting ``size`` bytes after each of ``ends``; the last chunk
    runs to the end."""
    offsets = np.concatenate([[0], ends]).astype(np.int64)
    offsets[-1] = size
    return offsets


def imu_log_chunks(data: bytes, *, file: str, shift_ns: int = 0) -> tuple[SerialBatch, dict[str, int]]:
    """The chunks of an IMU byte log, due at their frames' times (see the module docstring),
    and figures of the log (frames, garbage bytes, false starts, frames out of time order,
    frames dropped for a negative shifted time).

    ``shift_ns`` must be a whole number of microseconds (the frame's time resolution).

    Raises
    ------
    ConfigError
        Naming ``file``, when it holds no ICD IMU frame.
    """
    buf = np.frombuffer(data, np.uint8)
    if buf.size == 0:
        raise ConfigError("the IMU byte log is empty", file=file)
    if shift_ns % 1000:
        raise ConfigError(f"the IMU time shift must be whole microseconds, found {shift_ns} ns", file=file)
    if abs(shift_ns) > _MAX_SHIFT_NS:
        raise ConfigError(f"the IMU time shift of {shift_ns / 1e9:g} s is beyond a century", file=file)
    starts, false_starts = _frame_starts(buf)
    if starts.size == 0:
        raise ConfigError(
            f"no ICD IMU frame (AA 55, length 36, CRC-16 over bytes 2..39) in {buf.size} bytes: "
            f"not a byte log of the imu line; found {describe(data)}; IMU logs of other formats are read with "
            "--imu-format psins, kfgins, gnss-ins-sim or declared (a TOML beside the log; docs/exchange.md)",
            file=file,
        )
    rows = buf[starts[:, None] + _OFFS]
    rec = rows.view(FRAME_DTYPE).reshape(-1)
    t_us = rec["time_us"].astype(np.int64)
    if shift_ns:
        t_us = t_us + shift_ns // 1000
        if t_us.max() > INT64_MAX_US:
            raise ConfigError(
                f"the IMU time shift of {shift_ns / 1e9:g} s moves frames past int64 nanoseconds", file=file
            )
        keep = t_us >= 0
        rec["time_us"] = np.maximum(t_us, 0).astype(np.uint64)
        refresh_crc(rows)
        buf = buf.copy()
        buf[starts[:, None] + _OFFS] = rows
    else:
        keep = np.ones(starts.size, bool)
    t_ns = t_us * 1000
    order_breaks = int(np.count_nonzero(t_ns[1:] < np.maximum.accumulate(t_ns)[:-1]))
    batch = SerialBatch(np.maximum.accumulate(t_ns), _chunks(starts + FRAME_SIZE, buf.size), buf)
    dropped = int(np.count_nonzero(~keep))
    if dropped:
        batch = batch.take(keep)
        batch = SerialBatch(np.maximum.accumulate(batch.t_ns), batch.offsets, batch.buf)
    info = {
        "frames": int(starts.size),
        "garbage_bytes": int(buf.size - FRAME_SIZE * starts.size),
        "false_starts": false_starts,
        "out_of_order": order_breaks,
        "dropped_before_zero": dropped,
    }
    if not len(batch):
        raise ConfigError(
            f"every IMU frame lies before bench time zero after the shift of {shift_ns / 1e9:g} s", file=file
        )
    return batch, info


@dataclass
class NmeaLog:
    """An NMEA byte log cut into sentences grouped by epoch (see the module docstring).

    Attributes
    ----------
    file:
        The file (for messages).
    offsets, buf:
        Chunks: chunk ``k`` is ``buf[offsets[k]:offsets[k+1]]``, one sentence each.
    epoch_of:
        (N,) index of each chunk's epoch.
    tod_ns:
        (E,) UTC time of day of each epoch, ns since midnight.
    dates:
        (E,) UTC midnight of each epoch's date (ns since 1970) where a ZDA or RMC gives it, else -1.
    info:
        Figures: sentences, untimed (no time field of their own), bad (framing or
        checksum), epochs, dated epochs.
    """

    file: str
    offsets: np.ndarray
    buf: np.ndarray
    epoch_of: np.ndarray
    tod_ns: np.ndarray
    dates: np.ndarray
    info: dict[str, object]

    def epoch_utc_ns(self, epoch_utc_ns: int | None) -> np.ndarray:
        """(E,) UTC of each epoch, ns since 1970; ``epoch_utc_ns`` (UTC of bench time zero)
        places a log without any date.

        Raises ConfigError when the log has no date and ``epoch_utc_ns`` is None.
        """
        tod, dates = self.tod_ns.tolist(), self.dates.tolist()
        n = len(tod)
        day = [0] * n  # Python integers: midnights added never overflow
        known = np.flatnonzero(self.dates >= 0)
        if known.size:
            a = int(known[0])
            day[a] = dates[a]
        else:
            if epoch_utc_ns is None:
                bad = self.info.get("bad_kinds") or {}
                raise ConfigError(
                    "the NMEA log has no date (no ZDA, no RMC date that decodes) and the UTC of bench time zero "
                    "is unknown: give the epoch (--epoch)"
                    + (f"; sentences that do not decode, by kind: {bad}" if bad else ""),
                    file=self.file,
                )
            a = 0
            first = epoch_utc_ns // DAY_NS * DAY_NS + tod[0]
            if first < epoch_utc_ns - DAY_NS // 2:
                first += DAY_NS
            elif first > epoch_utc_ns + DAY_NS // 2:
                first -= DAY_NS
            day[0] = first - tod[0]
        half = DAY_NS // 2
        for e in range(a + 1, n):
            day[e] = dates[e] if dates[e] >= 0 else day[e - 1] + (DAY_NS if tod[e] < tod[e - 1] - half else 0)
        for e in range(a - 1, -1, -1):
            day[e] = day[e + 1] - (DAY_NS if tod[e] > tod[e + 1] + half else 0)
        utc = [d + t for d, t in zip(day, tod, strict=True)]
        bad = [i for i, u in enumerate(utc) if not -(2**63) <= u < 2**63]
        if bad:
            raise ConfigError(
                f"NMEA epoch {bad[0]}: its UTC (date and midnights passed) does not fit int64 ns", file=self.file
            )
        return np.array(utc, np.int64)

    def batch(self, t_ns: np.ndarray) -> SerialBatch:
        """The chunks due at ``t_ns`` (N,) (made non-decreasing: the line keeps its byte order)."""
        return SerialBatch(np.maximum.accumulate(np.asarray(t_ns, np.int64)), self.offsets, self.buf)


def _sentence_time(line: bytes) -> tuple[int | None, int | None, str | None]:
    """(time of day ns or None, UTC midnight ns of its date or None, kind of its fault or
    None) of one sentence; another sentence type than the ICD's is no fault, it has no time."""
    talker = line[1:3].decode("ascii", "replace")
    try:
        _, kind, fields = parse_sentence(line, talkers=(talker,))
    except CodecError as exc:
        return None, None, None if exc.kind == "unknown_id" else exc.kind
    if kind not in _TIMED:
        return None, None, None
    try:
        values = decode_fields(kind, fields)
    except CodecError as exc:
        return None, None, exc.kind
    date = values.get("date")
    midnight = days_since_1970(date) * DAY_NS if date else None
    return values.get("tod_ns"), midnight, None


def read_nmea_log(data: bytes, *, file: str) -> NmeaLog:
    """Cut an NMEA byte log into sentences and epochs (see the module docstring). A
    sentence that does not decode (checksum, format, a field out of range such as a ZDA
    date that does not exist) is kept on the line, gives no time or date, and is counted
    by kind in ``info["bad_kinds"]``.

    Raises
    ------
    ConfigError
        Naming ``file``, when it holds no sentence or no time field.
    """
    if not data:
        raise ConfigError("the NMEA byte log is empty", file=file)
    events, _ = frame_events(data, final=True)
    lines = [(a, b) for kind, a, b in events if kind == "line"]
    if not lines:
        found = describe(data)
        hint = " (the ICD's NMEA ends its lines in CR LF)" if "LF alone" in found and b"$" in data else ""
        raise ConfigError(
            f"no NMEA sentence ('$' ... CR LF within 82 characters) in {len(data)} bytes; found {found}{hint}",
            file=file,
        )
    n = len(lines)
    epoch_of = np.zeros(n, np.int64)
    tods: list[int] = []
    dates: list[int] = []
    bad: Counter[str] = Counter()
    untimed = 0
    cur = -1
    for k, (a, b) in enumerate(lines):
        tod, midnight, fault = _sentence_time(data[a:b])
        if fault is not None:
            bad[fault] += 1
        if tod is None:
            untimed += 1
        elif cur < 0 or tod != tods[cur]:
            tods.append(tod)
            dates.append(-1)
            cur += 1
        epoch_of[k] = max(cur, 0)
        if midnight is not None and cur >= 0 and dates[cur] < 0:
            dates[cur] = midnight
    if not tods:
        raise ConfigError(
            f"none of the {n} NMEA sentences carries a time field (RMC, GGA, GST, ZDA that decode)"
            + (f"; bad sentences by kind: {dict(sorted(bad.items()))}" if bad else ""),
            file=file,
        )
    ends = np.fromiter((b for _, b in lines), np.int64, n)
    date_arr = np.array(dates, np.int64)
    return NmeaLog(
        file=file,
        offsets=_chunks(ends, len(data)),
        buf=np.frombuffer(data, np.uint8),
        epoch_of=epoch_of,
        tod_ns=np.array(tods, np.int64),
        dates=date_arr,
        info={
            "sentences": n,
            "untimed": untimed,
            "bad": sum(bad.values()),
            "bad_kinds": dict(sorted(bad.items())),
            "epochs": len(tods),
            "dated_epochs": int(np.count_nonzero(date_arr >= 0)),
            "other_bytes": int(len(data) - sum(b - a for a, b in lines)),
        },
    )
