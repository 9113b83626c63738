"""Decoding the ``gnss`` byte stream: sentence framing, epoch assembly, counting.

Framing rule: a sentence starts at ``$`` and ends at the first CR LF; a ``$`` before the
CR LF starts a new sentence and makes the bytes before it one ``truncated`` event, so a
cut sentence never swallows the next one. Bytes outside sentences form ``sync`` events
(one per run up to the next ``$``), a ``$`` without CR LF within 82 characters a
``length`` event. Each framed sentence is parsed strictly (:func:`bench.wire.nmea.parse_sentence`):
``checksum``, ``format``, ``unknown_id`` events.

Epoch assembly: sentences with the same UTC time field belong to one epoch (VTG, which
has no time, to the epoch in progress). An epoch closes at its ZDA or when a sentence of
another time arrives; each ICD sentence it lacks counts as ``missing``, and a sentence
identical to one already in the epoch (or the epoch just closed) as ``duplicate``. When the UTC
of bench time zero is known (BENCH_EPOCH), each epoch gets its bench time and, with a tolerance, a ``late``
check of arrival minus measurement time.
"""

from __future__ import annotations

import calendar
import datetime
import math

import numpy as np

from bench.errors import CodecError
from bench.wire.nmea import GNSS_FIX_DTYPE, MAX_SENTENCE, SENTENCES, TALKERS, decode_fields, parse_sentence
from bench.wire.tally import Tally

__all__ = ["NmeaStreamDecoder"]

_DAY_NS = 86_400_000_000_000


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
        self.sentences = 0  # good sentences
        self._buf = b""
        self._pending: str | None = None  # "sync": an uncounted noise run continues; "counted": a counted one
        self._noise = b""  # first bytes of the uncounted noise run
        self._epoch: _Epoch | None = None
        self._date: datetime.date | None = None
        self._last_tod: int | None = None
        self._out: list[tuple] = []
        self._last_lines: dict[str, bytes] = {}  # sentences of the last epoch closed

    # ------------------------------------------------------------------ framing
    def feed(self, data: bytes, rx_ns: int = 0) -> np.ndarray:
        """Decode the bytes of one read; returns the epochs completed (:data:`GNSS_FIX_DTYPE`)."""
        buf = self._buf + data
        while buf:
            start = buf.find(b"$")
            if start != 0:
                noise = buf if start < 0 else buf[:start]
                if start < 0:  # the run may go on in the next read
                    if self._pending is None:
                        self._pending = "sync"
                        self._noise = noise[:256]
                    buf = b""
                    break
                self._end_noise(noise, rx_ns)
                buf = buf[start:]
                continue
            if self._pending is not None:
                self._end_noise(b"", rx_ns)
            nxt = buf.find(b"$", 1)
            lf = buf.find(b"\r\n")
            if lf >= 0 and (nxt < 0 or lf < nxt):
                self._line(buf[: lf + 2], rx_ns)
                buf = buf[lf + 2 :]
            elif nxt >= 0:
                self.tally.reject(rx_ns, self.stream, "truncated", buf[:nxt], "next '$' before CR LF")
                buf = buf[nxt:]
            elif len(buf) > MAX_SENTENCE:
                self.tally.reject(rx_ns, self.stream, "length", buf[:256], f"no CR LF within {MAX_SENTENCE}")
                self._pending = "counted"
                buf = b""
            else:
                break
        self._buf = buf
        return self._drain()

    def _end_noise(self, noise: bytes, rx_ns: int) -> None:
        if self._pending == "counted":
            pass
        elif self._pending == "sync":
            self.tally.reject(
                rx_ns, self.stream, "sync", self._noise + noise[: 256 - len(self._noise)], "bytes outside any sentence"
            )
        elif noise:
            self.tally.reject(rx_ns, self.stream, "sync", noise[:256], "bytes outside any sentence")
        self._pending = None

    def _line(self, line: bytes, rx_ns: int) -> None:
        try:
            _talker, kind, fields = parse_sentence(line, talkers=self.talkers)
            values = decode_fields(kind, fields)
        except CodecError as exc:
            self.tally.reject(rx_ns, self.stream, exc.kind, line, str(exc))
            return
        self.sentences += 1
        tod = values.get("tod_ns")
        ep = self._epoch
        if (ep is not None and ep.lines.get(kind) == line) or (ep is None and self._last_lines.get(kind) == line):
            self.tally.reject(rx_ns, self.stream, "duplicate", line, f"{kind} sent twice")
            return
        if (ep is not None and kind in ep.lines) or (
            ep is not None and tod is not None and ep.tod_ns is not None and tod != ep.tod_ns
        ):
            self._close(rx_ns)
            ep = None
        if ep is None:
            ep = self._epoch = _Epoch(tod)
        if ep.tod_ns is None:
            ep.tod_ns = tod
        ep.lines[kind] = line
        ep.values[kind] = values
        ep.rx_ns = rx_ns
        if kind == "ZDA":
            self._close(rx_ns)

    # ------------------------------------------------------------------ epochs
    def _close(self, rx_ns: int) -> None:
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
            self._date = datetime.date(*dated[0])
        elif (
            self._date is not None
            and self._last_tod is not None
            and ep.tod_ns is not None
            and ep.tod_ns < self._last_tod - _DAY_NS // 2
        ):
            self._date += datetime.timedelta(days=1)  # midnight passed in an epoch without a date field
        if ep.tod_ns is None or self._date is None:
            return  # no time of the epoch: nothing to hand on
        self._last_tod = ep.tod_ns
        utc_ns = calendar.timegm(self._date.timetuple()) * 1_000_000_000 + ep.tod_ns
        gga, rmc, gst, vtg = v.get("GGA"), v.get("RMC"), v.get("GST"), v.get("VTG")
        pos = gga or rmc or {}
        vel = vtg or rmc or {}
        sog, cog = vel.get("sog", math.nan), vel.get("cog", math.nan)
        t_ns = utc_ns - self.epoch_utc_ns if self.epoch_utc_ns is not None else 0
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

    def flush(self, rx_ns: int = 0) -> np.ndarray:
        """End of stream: count what is left, close the epoch in progress, return its fix."""
        if self._buf:
            self.tally.reject(rx_ns, self.stream, "truncated", self._buf, "stream ended inside a sentence")
        elif self._pending == "sync":
            self._end_noise(b"", rx_ns)
        self._buf, self._pending = b"", None
        self._close(rx_ns)
        return self._drain()
