"""Values of scenario files: coordinates in degrees or DMS, manoeuvre limits, and the
checks every table of a motion script goes through (unknown keys, quantities with units,
flags), each error naming the file and the key."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from bench.config.bounds import MAX_DURATION_S, bounded_quantity, check
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.units import quantity

__all__ = ["Limits", "parse_latlon", "check_script_size"]


@dataclass
class Limits:
    """Default manoeuvre limits (SI), overridable per segment."""

    accel: float = 1.0  # m/s^2
    jerk: float = 1.0  # m/s^3
    angular_accel: float = math.radians(10.0)  # rad/s^2
    max_rate: float = math.radians(30.0)  # rad/s
    pitch_rate: float = math.radians(1.0)  # rad/s


_DMS = re.compile(
    r"^\s*(?P<deg>[-+]?\d+(?:\.\d+)?)\s*(?:°|deg|d)?\s*"
    r"(?:(?P<min>\d+(?:\.\d+)?)\s*(?:'|′|min|m)\s*)?"
    r"(?:(?P<sec>\d+(?:\.\d+)?)\s*(?:\"|″|sec|s)\s*)?"
    r"(?P<hemi>[NSEWnsew])?\s*$"
)


def parse_latlon(value: Any, axis: str, *, file: str | None = None, key: str | None = None) -> float:
    """Latitude or longitude in radians from degrees or a DMS string.

    Accepts ``34.24605``, ``"34.24605"``, ``"34°14.763'N"``, ``"34d14m45.78sN"``,
    ``"108 54.579 E"``-style strings are not accepted (ambiguous); south and west are
    negative.
    """
    limit = 90.0 if axis == "lat" else 180.0
    hemis = "NS" if axis == "lat" else "EW"
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        deg = float(value)
    elif isinstance(value, str):
        m = _DMS.match(value)
        if not m:
            raise ConfigError(
                f'expected degrees such as 34.246 or "34°14.763\'{hemis[0]}", found {value!r}',
                file=file,
                key=key,
            )
        deg = float(m.group("deg"))
        sign = -1.0 if deg < 0 else 1.0
        deg = abs(deg) + float(m.group("min") or 0) / 60.0 + float(m.group("sec") or 0) / 3600.0
        hemi = (m.group("hemi") or "").upper()
        if hemi and hemi not in hemis:
            raise ConfigError(f"hemisphere {hemi!r} is not one of {hemis}", file=file, key=key)
        if hemi in ("S", "W"):
            sign = -sign
        deg *= sign
    else:
        raise ConfigError(f"expected degrees, found {value!r}", file=file, key=key)
    if not -limit <= deg <= limit:
        raise ConfigError(f"expected a value within +-{limit} deg, found {deg}", file=file, key=key)
    return math.radians(deg)


# -- small helpers --------------------------------------------------------------------------
def _table(doc: Mapping[str, Any], name: str, file: str | None) -> Mapping[str, Any]:
    value = doc.get(name)
    if not isinstance(value, Mapping):
        raise ConfigError(f"expected a [{name}] table", file=file, key=name)
    return value


def _only(table: Mapping[str, Any], allowed: set[str], key: str, file: str | None) -> None:
    check_keys(table, allowed, file=file, key=key)


def _opt(seg: Mapping[str, Any], name: str, dim: str, unit: str, key: str, file: str | None) -> float | None:
    if name not in seg:
        return None
    return quantity(seg[name], dim, unit, file=file, key=f"{key}.{name}")


def _flag(value: Any, allowed: tuple[str, ...], key: str, file: str | None) -> str:
    if value not in allowed:
        raise ConfigError(f"expected one of {', '.join(allowed)}, found {value!r}", file=file, key=key)
    return str(value)


def _limits(table: Mapping[str, Any], base: Limits, key: str, file: str | None) -> Limits:
    spec = {
        "accel": ("acceleration", "m/s^2"),
        "jerk": ("jerk", "m/s^3"),
        "angular_accel": ("angular_acceleration", "deg/s^2"),
        "max_rate": ("angular_rate", "deg/s"),
        "pitch_rate": ("angular_rate", "deg/s"),
    }
    out = Limits(**base.__dict__)
    for name, (dim, unit) in spec.items():
        if name in table:
            v = quantity(table[name], dim, unit, file=file, key=f"{key}.{name}")
            if v <= 0.0:
                raise ConfigError(f"expected a positive limit, found {table[name]!r}", file=file, key=f"{key}.{name}")
            setattr(out, name, v)
    return out


def check_script_size(segments: Any, *, file: str | None, rate_hz: float = 1000.0) -> None:
    """Refuse a motion script that would not stay bounded: each ``repeat`` and the count of
    segments after repeats within their bounds, the declared durations within 30 days and
    within the truth grid at ``rate_hz`` (what cannot be known before the motion is built,
    :func:`build_profile` checks as it goes)."""
    if not isinstance(segments, list):
        return  # build_profile says what is wrong
    total_n, total_s = 0, 0.0
    for i, seg in enumerate(segments):
        if not isinstance(seg, Mapping):
            continue
        key = f"segment[{i}]"
        repeat = seg.get("repeat", 1)
        if isinstance(repeat, int) and not isinstance(repeat, bool) and repeat >= 1:
            check("repeat", repeat, file=file, key=f"{key}.repeat")
        else:
            repeat = 1  # build_profile refuses it
        total_n += repeat
        check("segments", total_n, file=file, key=f"{key}.repeat", shown=f"{total_n} segments up to {key}")
        if "duration" in seg:
            d = bounded_quantity(seg["duration"], "time", "s", "duration", file=file, key=f"{key}.duration")
            total_s += repeat * d
            if total_s > MAX_DURATION_S:
                check("duration", total_s, file=file, key=f"{key}.duration", shown=f"{total_s:g} s up to {key}")
            points = math.ceil(total_s * rate_hz) + 1
            check("points", points, file=file, key=f"{key}.duration",
                  shown=f"{points} ({total_s:g} s up to {key} at {rate_hz:g} Hz)")
