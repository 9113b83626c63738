"""Strict decoding of one NMEA 0183 sentence of the BDS receiver (the decode side of :mod:`bench.wire.nmea`).

:func:`parse_sentence` checks framing and checksum (``CodecError`` kinds ``length``,
``format``, ``checksum``, ``unknown_id``) and :func:`decode_fields` turns the fields of a
known sentence into SI numbers. Both are total: any bytes either decode or raise
:class:`~bench.errors.CodecError`, never another exception.

Numbers are read as NMEA writes them, not as Python's ``float`` would: an optional sign,
digits and at most one decimal point (no exponent, ``nan``, ``inf``, ``_`` or spaces),
``format`` otherwise. Every value must lie in its physical range (``range`` otherwise):

=========================  ==========================================================
field                      allowed
=========================  ==========================================================
time ``hhmmss[.s...]``     hh 0-23, mm 0-59, ss.s < 61 (a leap second)
date (RMC ``ddmmyy``,      a calendar date (no 29 February of a common year) from
ZDA ``dd,mm,yyyy``)        1970-01-01 to 2262-04-10 (UTC in int64 nanoseconds)
latitude ``ddmm.m``        minutes < 60, at most 90 deg; longitude ``dddmm.m`` at most 180 deg
speed, HDOP, sigmas        finite, >= 0
course                     0 to 360 deg
GGA quality                an integer 0-8; satellites an integer 0-255
GGA altitude               -100 km to 10 000 km (the encoder's range)
ZDA local zone             empty or a signed integer: hours -13..13, minutes 0..59
=========================  ==========================================================
"""

from __future__ import annotations

import datetime
import math
import re

from bench.errors import CodecError
from bench.wire.nmea import KNOT, MAX_SENTENCE, SENTENCES, TALKERS, checksum

__all__ = ["parse_sentence", "decode_fields", "DATE_MIN", "DATE_MAX", "days_since_1970"]

#: Dates a sentence may carry: UTC midnight to the end of the day must fit int64 nanoseconds.
DATE_MIN = datetime.date(1970, 1, 1)
DATE_MAX = datetime.date(2262, 4, 10)

_FIELD_COUNTS = {"RMC": 13, "GGA": 14, "GST": 8, "VTG": 9, "ZDA": 6}
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)\Z")
_UINT = re.compile(r"\d+\Z")
_HEX2 = re.compile(rb"[0-9A-Fa-f]{2}\Z")
_RESERVED = re.compile(rb"[^\x20\x22\x23\x25-\x29\x2b-\x7e]")  # non-printable, '!', '$', '*'
_TIME = re.compile(r"(\d\d)(\d\d)(\d\d(?:\.\d*)?)\Z")
_LAT = re.compile(r"(\d\d)(\d\d(?:\.\d*)?)\Z")
_LON = re.compile(r"(\d{3})(\d\d(?:\.\d*)?)\Z")
_EPOCH_ORDINAL = DATE_MIN.toordinal()


def days_since_1970(date: tuple[int, int, int]) -> int:
    """Days from 1970-01-01 to ``date`` (year, month, day), a date :func:`decode_fields` gave."""
    return datetime.date(*date).toordinal() - _EPOCH_ORDINAL


def parse_sentence(line: bytes, *, talkers: tuple[str, ...] = TALKERS) -> tuple[str, str, list[str]]:
    """(talker, type, fields) of one sentence, with or without its CR LF; strict.

    CodecError kinds: ``length`` (over 82 characters), ``format`` (framing, characters,
    talker), ``checksum`` (``*hh`` does not match), ``unknown_id`` (not one of
    :data:`~bench.wire.nmea.SENTENCES`).
    """
    if len(line) > MAX_SENTENCE:
        raise CodecError("length", f"NMEA sentence of {len(line)} characters (at most {MAX_SENTENCE})")
    text = line[:-2] if line.endswith(b"\r\n") else line
    if not text.startswith(b"$"):
        raise CodecError("format", f"NMEA sentence does not start with '$': {line[:20]!r}")
    star = text.rfind(b"*")
    if star < 0 or len(text) - star != 3:
        raise CodecError("format", f"NMEA sentence without '*hh' checksum: {line[-12:]!r}")
    body = text[1:star]
    if _RESERVED.search(body):
        raise CodecError("format", f"NMEA sentence holds a reserved or non-printable character: {line[:40]!r}")
    if not _HEX2.match(text[star + 1 :]):
        raise CodecError("format", f"NMEA checksum {text[star + 1 :]!r} is not two hexadecimal digits")
    given, want = int(text[star + 1 :], 16), checksum(body)
    if given != want:
        raise CodecError("checksum", f"NMEA checksum {given:02X} does not match {want:02X}")
    parts = body.decode("ascii").split(",")
    head = parts[0]
    if len(head) != 5:
        raise CodecError("format", f"NMEA address {head!r} is not a talker and a sentence type")
    talker, kind = head[:2], head[2:]
    if talker not in talkers:
        raise CodecError("format", f"NMEA talker {talker!r} (expected {', '.join(talkers)})")
    if kind not in SENTENCES:
        raise CodecError("unknown_id", f"NMEA sentence type {kind!r} is not one of {', '.join(SENTENCES)}")
    return talker, kind, parts[1:]


# ---------------------------------------------------------------------------- fields
def _num(text: str, what: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    """A decimal number in [lo, hi], NaN if empty."""
    if text == "":
        return math.nan
    if not _NUMBER.match(text):
        raise CodecError("format", f"NMEA {what}: {text!r} is not a decimal number")
    value = float(text)  # at most 82 digits: always finite
    if not lo <= value <= hi:
        raise CodecError("range", f"NMEA {what}: {text} outside [{lo:g}, {hi:g}]")
    return value


def _uint(text: str, what: str, hi: int) -> int:
    """An unsigned integer in [0, hi], 0 if empty."""
    if text == "":
        return 0
    if not _UINT.match(text):
        raise CodecError("format", f"NMEA {what}: {text!r} is not an unsigned integer")
    value = int(text)
    if value > hi:
        raise CodecError("range", f"NMEA {what}: {value} outside [0, {hi}]")
    return value


def _tod(text: str) -> int | None:
    """Time of day ``hhmmss.ss`` -> ns since midnight (None if empty)."""
    if text == "":
        return None
    m = _TIME.match(text)
    if not m:
        raise CodecError("format", f"NMEA time {text!r} is not hhmmss.ss")
    h, mi, s = int(m[1]), int(m[2]), float(m[3])
    if h > 23 or mi > 59 or s >= 61:
        raise CodecError("range", f"NMEA time {text!r} is not a time of day")
    return (h * 3600 + mi * 60) * 1_000_000_000 + round(s * 1e9)


def _date(year: int, month: int, day: int, text: str) -> tuple[int, int, int]:
    try:
        date = datetime.date(year, month, day)
    except ValueError:
        raise CodecError("range", f"NMEA date {text!r} is not a calendar date") from None
    if not DATE_MIN <= date <= DATE_MAX:
        raise CodecError("range", f"NMEA date {text!r} outside {DATE_MIN} .. {DATE_MAX}")
    return year, month, day


def _coord(value: str, hemi: str, lat: bool) -> float:
    if value == "" and hemi == "":
        return math.nan
    pos, neg, limit = ("N", "S", 90.0) if lat else ("E", "W", 180.0)
    m = (_LAT if lat else _LON).match(value)
    if not m or hemi not in (pos, neg):
        raise CodecError("format", f"NMEA coordinate {value!r},{hemi!r}")
    minutes = float(m[2])
    deg = int(m[1]) + minutes / 60.0
    if minutes >= 60 or deg > limit:
        raise CodecError("range", f"NMEA coordinate {value},{hemi} beyond {limit:g} deg or 60 arcmin")
    return math.radians(-deg if hemi == neg else deg)


def _rmc(f: list[str]) -> dict:
    date = None
    if f[8]:
        if len(f[8]) != 6 or not _UINT.match(f[8]):
            raise CodecError("format", f"NMEA RMC date {f[8]!r} is not ddmmyy")
        date = _date(2000 + int(f[8][4:]), int(f[8][2:4]), int(f[8][:2]), f[8])
    if f[1] not in ("A", "V"):
        raise CodecError("format", f"NMEA RMC status {f[1]!r}")
    return {
        "tod_ns": _tod(f[0]),
        "valid": f[1] == "A",
        "lat": _coord(f[2], f[3], True),
        "lon": _coord(f[4], f[5], False),
        "sog": _num(f[6], "RMC speed", 0.0) * KNOT,
        "cog": math.radians(_num(f[7], "RMC course", 0.0, 360.0)),
        "date": date,
        "mode": f[11],
        "nav_status": f[12],
    }


def _gga(f: list[str]) -> dict:
    if f[9] not in ("M", "") or f[11] not in ("M", ""):
        raise CodecError("format", "NMEA GGA units are not metres")
    altitude = _num(f[8], "GGA altitude", -1e5, 1e7)
    geoid = _num(f[10], "GGA geoid separation", -1e5, 1e5) if f[10] else 0.0
    _num(f[12], "GGA age of differential corrections", 0.0)
    return {
        "tod_ns": _tod(f[0]),
        "lat": _coord(f[1], f[2], True),
        "lon": _coord(f[3], f[4], False),
        "quality": _uint(f[5], "GGA quality", 8),
        "sats": _uint(f[6], "GGA satellites", 255),
        "hdop": _num(f[7], "GGA HDOP", 0.0),
        "h": altitude + geoid,
    }


def _gst(f: list[str]) -> dict:
    for i, what in ((1, "RMS"), (2, "semi-major axis"), (3, "semi-minor axis")):
        _num(f[i], f"GST {what}", 0.0)
    _num(f[4], "GST orientation", -360.0, 360.0)
    return {
        "tod_ns": _tod(f[0]),
        "sigma_lat": _num(f[5], "GST sigma lat", 0.0),
        "sigma_lon": _num(f[6], "GST sigma lon", 0.0),
        "sigma_alt": _num(f[7], "GST sigma alt", 0.0),
    }


def _vtg(f: list[str]) -> dict:
    _num(f[2], "VTG magnetic course", 0.0, 360.0)
    _num(f[6], "VTG speed km/h", 0.0)
    return {
        "cog": math.radians(_num(f[0], "VTG course", 0.0, 360.0)),
        "sog": _num(f[4], "VTG speed", 0.0) * KNOT,
        "mode": f[8],
    }


def _zda(f: list[str]) -> dict:
    text = f"{f[1]}/{f[2]}/{f[3]}"
    if not (1 <= len(f[1]) <= 2 and 1 <= len(f[2]) <= 2 and len(f[3]) == 4) or not all(_UINT.match(x) for x in f[1:4]):
        raise CodecError("format", f"NMEA ZDA date {text!r} is not dd,mm,yyyy")
    for i, what, hi in ((4, "ZDA zone hours", 13), (5, "ZDA zone minutes", 59)):
        if f[i] and not re.fullmatch(r"[+-]?\d{1,2}", f[i]):
            raise CodecError("format", f"NMEA {what} {f[i]!r} is not an integer")
        if f[i] and not abs(int(f[i])) <= hi:
            raise CodecError("range", f"NMEA {what} {f[i]} outside [-{hi}, {hi}]")
    return {"tod_ns": _tod(f[0]), "date": _date(int(f[3]), int(f[2]), int(f[1]), text)}


_DECODERS = {"RMC": _rmc, "GGA": _gga, "GST": _gst, "VTG": _vtg, "ZDA": _zda}


def decode_fields(kind: str, fields: list[str]) -> dict:
    """The values of a sentence's fields (SI; NaN or None where the field is empty).

    Raises CodecError ``format`` (field count, a field that is not what its kind is) or
    ``range`` (a value outside its physical range; the module docstring lists them).
    """
    if kind not in _DECODERS:
        raise CodecError("unknown_id", f"NMEA sentence type {kind!r} is not one of {', '.join(SENTENCES)}")
    if len(fields) != _FIELD_COUNTS[kind]:
        raise CodecError("format", f"NMEA {kind}: expected {_FIELD_COUNTS[kind]} fields, found {len(fields)}")
    return _DECODERS[kind](fields)
