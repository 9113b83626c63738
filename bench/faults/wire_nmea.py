"""Offset and scale of a value inside NMEA sentences (wire faults on ``serial:gnss``).

The sentence stays well formed: the field is rewritten with the decimals it had, the
hemisphere letter follows the sign of a coordinate, and the checksum is recomputed, so a
receiver accepts it and only the value is wrong. Signals, in SI (the sentences carrying
them): ``lat``, ``lon`` (rad; RMC, GGA), ``h`` (m, altitude; GGA), ``speed`` (m/s; RMC,
VTG knots and km/h), ``course`` (rad; RMC, VTG), ``hdop`` (GGA), ``sigma_lat``,
``sigma_lon``, ``sigma_alt`` (m; GST). Empty fields (no fix) stay empty.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from bench.errors import ConfigError
from bench.wire.nmea import KNOT, checksum

__all__ = ["NMEA_SIGNALS", "edit_sentence"]

# signal -> {sentence type: [(field index, kind)]}; kinds: lat, lon (ddmm.m + hemisphere in
# the next field), num (value = SI * factor), deg (value in degrees of an SI angle)
_FIELDS: dict[str, dict[str, list[tuple[int, str, float]]]] = {
    "lat": {"RMC": [(2, "lat", 1.0)], "GGA": [(1, "lat", 1.0)]},
    "lon": {"RMC": [(4, "lon", 1.0)], "GGA": [(3, "lon", 1.0)]},
    "h": {"GGA": [(8, "num", 1.0)]},
    "speed": {"RMC": [(6, "num", 1.0 / KNOT)], "VTG": [(4, "num", 1.0 / KNOT), (6, "num", 3.6)]},
    "course": {"RMC": [(7, "deg", 1.0)], "VTG": [(0, "deg", 1.0)]},
    "hdop": {"GGA": [(7, "num", 1.0)]},
    "sigma_lat": {"GST": [(5, "num", 1.0)]},
    "sigma_lon": {"GST": [(6, "num", 1.0)]},
    "sigma_alt": {"GST": [(7, "num", 1.0)]},
}
NMEA_SIGNALS = tuple(_FIELDS)


def _decimals(text: str) -> int:
    return len(text.split(".", 1)[1]) if "." in text else 0


def _coord(value: str, hemi: str, width: int, pos: str, neg: str, fn: Callable[[float], float]) -> tuple[str, str]:
    deg = float(value[:width]) + float(value[width:]) / 60.0
    rad = fn(math.radians(-deg if hemi == neg else deg))
    d = abs(math.degrees(rad))
    dec = _decimals(value)
    whole = int(d)
    minutes = round((d - whole) * 60.0, dec)
    if minutes >= 60.0:
        whole, minutes = whole + 1, 0.0
    return f"{whole:0{width}d}{minutes:0{3 + dec if dec else 2}.{dec}f}", (neg if rad < 0 else pos)


def edit_sentence(line: bytes, signal: str, fn: Callable[[float], float]) -> bytes:
    """``line`` (``$...*hh\\r\\n``) with ``signal`` replaced by ``fn(value)`` (SI); the line
    unchanged when it does not carry the signal or is not a well-formed sentence."""
    if signal not in _FIELDS:
        raise ConfigError(f"NMEA signal {signal!r}; expected one of {', '.join(NMEA_SIGNALS)}", key="params.signal")
    star = line.rfind(b"*")
    if not line.startswith(b"$") or star < 0:
        return line
    body = line[1:star].decode("ascii", "replace")
    head, *fields = body.split(",")
    spec = _FIELDS[signal].get(head[-3:])
    if not spec:
        return line
    for idx, kind, factor in spec:
        if idx >= len(fields) or fields[idx] == "":
            continue
        try:
            if kind in ("lat", "lon"):
                width, pos, neg = (2, "N", "S") if kind == "lat" else (3, "E", "W")
                fields[idx], fields[idx + 1] = _coord(fields[idx], fields[idx + 1], width, pos, neg, fn)
            elif kind == "deg":
                v = math.degrees(fn(math.radians(float(fields[idx])))) % 360.0
                fields[idx] = f"{v:.{_decimals(fields[idx])}f}"
            else:
                v = fn(float(fields[idx]) / factor) * factor
                fields[idx] = f"{v:.{_decimals(fields[idx])}f}"
        except (ValueError, IndexError):
            return line  # a field the sentence does not hold as expected: left alone
    new = ",".join([head, *fields]).encode("ascii")
    return b"$" + new + b"*" + f"{checksum(new):02X}".encode() + line[star + 3 :]
