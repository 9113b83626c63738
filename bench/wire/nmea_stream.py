"""Decoding the ``gnss`` byte stream: sentence framing, epoch assembly, counting.

Framing rule (:func:`frame_events`), decided on the 82 bytes from each ``$`` (the longest
sentence NMEA allows, ``$`` to LF), so that it never depends on how the bytes are split
into reads:

``line``       a CR LF ends within those 82 bytes before any other ``$``: one sentence;
``truncated``  another ``$`` comes first: the bytes before it (a cut sentence never
               swallows the next one); also a sentence cut by the end of the stream;
``length``     neither within 82 bytes: the run up to the next ``$`` is one event;
``sync``       bytes outside sentences, one event per run up to the next ``$``.

Each framed sentence is parsed strictly (:mod:`bench.wire.nmea_fields`): ``checksum``,
``format``, ``unknown_id``, ``range`` events. The decoder is total: any bytes either
decode or are counted as one of these kinds, and its state stays valid for what follows.

Epoch assembly: sentences with the same UTC time field belong to one epoch (VTG, which
has no time, to the epoch in progress). An epoch closes at its ZDA or when a sentence of
another time arrives; each ICD sentence it lacks counts as ``missing``, and a sentence
identical to one already in the epoch (or the epoch just closed) as ``duplicate``. When the UTC
of bench time zero is known (BENCH_EPOCH), each epoch gets its bench time and, with a tolerance, a ``late``
check of arrival minus measurement time. An epoch whose UTC (date plus midnights passed)
does not fit int64 nanoseconds is one ``range`` event.

Stamps: an epoch's ``rx_ns`` is the arrival of the last byte of its last sentence; a kept
bad frame's ``t_ns`` the arrival of its last byte. Both are the same whatever the split.
"""

from __future__ import annotations

import math

import numpy as np

from bench.errors import CodecError
from bench.frames import SerialBatch
from bench.wire.nmea import GNSS_FIX_DTYPE, MAX_SENTENCE, SENTENCES, TALKERS
from bench.wire.nmea_fields import days_since_1970, decode_fields, parse_sentence
from bench.wire.tally import Tally

__all__ = ["NmeaStreamDecoder", "frame_events", "NMEA_KINDS"]

_DAY_NS = 86_400_000_000_000
_INT64 = (-(2**63), 2**63 - 1)
_KEEP = 256  # bytes of a bad run kept for the recording
#: Every kind the decoder counts.
NMEA_KINDS = (
    "sync",
    "truncated",
    "length",
    "checksum",
    "format",
    "unknown_id",
    "range",
    "duplicate",
    "missing",
    "late",
)
_REASONS = {
    "sync": "bytes outside any sentence",
    "truncated": "next '$' before CR LF",
    "length": f"no CR LF within {MAX_SENTENCE} characters",
}


def frame_events(buf: bytes, *, final: bool) -> tuple[list[tuple[str, int, int]], int]:
    """The framing events of ``buf`` in order, ``(kind, start, end)`` with kind ``line``,
    ``sync``, ``truncated`` or ``length`` (see the module docstring), and the offset of the
    bytes still undecided (a ``$`` with fewer than 82 bytes after it and no CR LF or ``$``
    yet; none when ``final``: the end of the stream cuts it, ``truncated``). A ``sync`` or
    ``length`` run that reaches the end of ``buf`` may go on in the next bytes."""
    events: list[tuple[str, int, int]] = []
    i, n = 0, len(buf)
    while i < n:
        if buf[i] != 0x24:  # not '$'
            k = buf.find(b"$", i)
            end = n if k < 0 else k
            events.append(("sync", i, end))
            i = end
            continue
        lf = buf.find(b"\r\n", i, i + MAX_SENTENCE)
        k = buf.find(b"$", i + 1, i + MAX_SENTENCE)
        if lf >= 0 and (k < 0 or lf < k):
            events.append(("line", i, lf + 2))
            i = lf + 2
        elif k >= 0:
            events.append(("truncated", i, k))
            i = k
        elif n - i >= MAX_SENTENCE:
            k = buf.find(b"$", i + MAX_SENTENCE)
            end = n if k < 0 else k
            events.append(("length", i, end))
            i = end
        elif final:
            events.append(("truncated", i, n))
            i = n
        else:
            break
    return events, i


class _Epoch:
    __slots__ = ("lines", "rx_ns", "tod_ns", "values")

    def __init__(self, tod_ns: int | None):
        self.tod_ns = tod_ns
        self.lines: dict[str, bytes] = {}
        self.values: dict[str, dict] = {}
        self.rx_ns = 0


class NmeaStreamDecoder:
    """Stateful decoder of the ``gnss`` serial stream (see the module docstring).

    Parameters
    ----------
    epoch_utc_ns:
        UTC of bench time zero (ns since 1970), if known; gives each fix its bench time.
    late_ns:
        Count an epoch ``late`` when its last sentence arrives more than this after the
        measurement time (needs ``epoch_utc_ns`` and arrival times in bench time).
    talkers:
        Accepted talker identifiers.

    Counters: ``bytes_in`` (fed), ``bytes_good`` (in good sentences), ``bytes_bad`` (in
    every event counted); after :meth:`flush` ``bytes_in == bytes_good + bytes_bad``.
    ``lines`` sentences framed, ``sentences`` of them good (not duplicates).
    """

    def __init__(
        self,
        *,
        epoch_utc_ns: int | None = None,
        late_ns: int | None = None,
        talkers: tuple[str, ...] = TALKERS,
        stream: str = "serial:gnss",
        tally: Tally | None = None,
    ):
        self.epoch_utc_ns = epoch_utc_ns
        self.late_ns = late_ns
        self.talkers = talkers
        self.stream = stream
        self.tally = tally if tally is not None else Tally()
        self.sentences = 0
        self.lines = 0
        self.bytes_in = self.bytes_good = self.bytes_bad = 0
        self._buf = b""  # undecided bytes: a '$' and what follows it so far
        self._buf_rx: list[int] = []  # arrival of each of them
        self._run: list | None = None  # the sync or length run in progress: [kind, head, size, last rx]
        self._epoch: _Epoch | None = None
        self._day: int | None = None  # date of the last dated epoch (+ midnights since), days since 1970
        self._last_tod: int | None = None
        self._out: list[tuple] = []
        self._last_lines: dict[str, bytes] = {}  # sentences of the last epoch closed

    # ------------------------------------------------------------------ framing
    def feed(self, data: bytes, rx_ns: int = 0) -> np.ndarray:
        """Decode the bytes of one read (arrived at ``rx_ns``); returns the epochs completed
        (:data:`~bench.wire.nmea.GNSS_FIX_DTYPE`)."""
        self._scan(bytes(data), rx_ns, final=False)
        return self._drain()

    def feed_batch(self, batch: SerialBatch) -> np.ndarray:
        """Decode received chunks, each with its own arrival time; returns the epochs completed."""
        for k in range(len(batch)):
            self._scan(batch.buf[batch.offsets[k] : batch.offsets[k + 1]].tobytes(), int(batch.t_ns[k]), final=False)
        return self._drain()

    def flush(self, rx_ns: int = 0) -> np.ndarray:
        """End of stream: count what is left (stamped with the arrival of its last byte;
        ``rx_ns`` is not needed), close the epoch in progress, return its fix."""
        self._scan(b"", rx_ns, final=True)
        self._close_run()
        self._close()
        return self._drain()

    def _scan(self, data: bytes, rx_ns: int, *, final: bool) -> None:
        self.bytes_in += len(data)
        held, held_rx = self._buf, self._buf_rx
        buf = held + data if held else data
        n_held = len(held)

        def rx_at(j: int) -> int:
            return held_rx[j] if j < n_held else rx_ns

        if self._run is not None and buf[:1] == b"$":
            self._close_run()
        events, rest = frame_events(buf, final=final)
        n = len(buf)
        for kind, a, b in events:
            if self._run is not None:
                if kind == "sync" and a == 0:  # the run in progress goes on
                    run = self._run
                    run[1] += buf[: min(b, max(0, _KEEP - len(run[1])))]
                    run[2] += b
                    run[3] = rx_at(b - 1)
                    if b < n:
                        self._close_run()
                    continue
                self._close_run()
            if kind == "line":
                self._line(buf[a:b], rx_at(b - 1))
            elif kind == "truncated":
                self._reject(
                    "truncated",
                    buf[a:b],
                    b - a,
                    rx_at(b - 1),
                    "stream ended inside a sentence" if b == n and final else _REASONS["truncated"],
                )
            else:
                self._run = [kind, buf[a : min(b, a + _KEEP)], b - a, rx_at(b - 1)]
                if b < n:
                    self._close_run()
        self._buf = buf[rest:]
        self._buf_rx = [rx_at(j) for j in range(rest, n)]

    def _reject(self, kind: str, data: bytes, size: int, rx_ns: int, reason: str) -> None:
        self.bytes_bad += size
        self.tally.reject(rx_ns, self.stream, kind, data[:_KEEP], reason)

    def _close_run(self) -> None:
        if self._run is not None:
            kind, head, size, rx = self._run
            self._run = None
            self._reject(kind, head, size, rx, f"{_REASONS[kind]} ({size} bytes)")

    def _line(self, line: bytes, rx_ns: int) -> None:
        self.lines += 1
        try:
            _talker, kind, fields = parse_sentence(line, talkers=self.talkers)
            values = decode_fields(kind, fields)
        except CodecError as exc:
            self._reject(exc.kind, line, len(line), rx_ns, str(exc))
            return
        tod = values.get("tod_ns")
        ep = self._epoch
        if (ep is not None and ep.lines.get(kind) == line) or (ep is None and self._last_lines.get(kind) == line):
            self._reject("duplicate", line, len(line), rx_ns, f"{kind} sent twice")
            return
        self.sentences += 1
        self.bytes_good += len(line)
        if (ep is not None and kind in ep.lines) or (
            ep is not None and tod is not None and ep.tod_ns is not None and tod != ep.tod_ns
        ):
            self._close()
            ep = None
        if ep is None:
            ep = self._epoch = _Epoch(tod)
        if ep.tod_ns is None:
            ep.tod_ns = tod
        ep.lines[kind] = line
        ep.values[kind] = values
        ep.rx_ns = rx_ns
        if kind == "ZDA":
            self._close()

    # ------------------------------------------------------------------ epochs
    def _close(self) -> None:
        ep, self._epoch = self._epoch, None
        if ep is None:
            return
        self._last_lines = ep.lines
        missing = [k for k in SENTENCES if k not in ep.lines]
        if missing:
            self.tally.count("missing", len(missing))
        v = ep.values
        dated = [v[k]["date"] for k in ("ZDA", "RMC") if k in v and v[k]["date"] is not None]
        if dated:
            self._day = days_since_1970(dated[0])
        elif (
            self._day is not None
            and self._last_tod is not None
            and ep.tod_ns is not None
            and ep.tod_ns < self._last_tod - _DAY_NS // 2
        ):
            self._day += 1  # midnight passed in an epoch without a date field
        if ep.tod_ns is None or self._day is None:
            return  # no time of the epoch: nothing to hand on
        self._last_tod = ep.tod_ns
        utc_ns = self._day * _DAY_NS + ep.tod_ns
        t_ns = utc_ns - self.epoch_utc_ns if self.epoch_utc_ns is not None else 0
        if not (_INT64[0] <= utc_ns <= _INT64[1] and _INT64[0] <= t_ns <= _INT64[1]):
            self.tally.reject(
                ep.rx_ns,
                self.stream,
                "range",
                b"".join(ep.lines.values())[:_KEEP],
                f"epoch UTC {utc_ns} ns (bench time {t_ns} ns) does not fit int64 nanoseconds",
            )
            return
        gga, rmc, gst, vtg = v.get("GGA"), v.get("RMC"), v.get("GST"), v.get("VTG")
        pos = gga or rmc or {}
        vel = vtg or rmc or {}
        sog, cog = vel.get("sog", math.nan), vel.get("cog", math.nan)
        quality = gga["quality"] if gga else (1 if rmc and rmc["valid"] else 0)
        self._out.append(
            (
                t_ns,
                utc_ns,
                ep.rx_ns,
                pos.get("lat", math.nan),
                pos.get("lon", math.nan),
                gga["h"] if gga else math.nan,
                (sog * math.sin(cog), sog * math.cos(cog), math.nan),
                gst["sigma_lat"] if gst else math.nan,
                gst["sigma_lon"] if gst else math.nan,
                gst["sigma_alt"] if gst else math.nan,
                gga["sats"] if gga else 0,
                gga["hdop"] if gga else math.nan,
                quality,
            )
        )
        if self.late_ns is not None and self.epoch_utc_ns is not None and ep.rx_ns - t_ns > self.late_ns:
            self.tally.count("late")

    def _drain(self) -> np.ndarray:
        out = np.array(self._out, GNSS_FIX_DTYPE) if self._out else np.zeros(0, GNSS_FIX_DTYPE)
        self._out = []
        return out
