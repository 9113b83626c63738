"""Quantities with units as users write them, converted to SI.

Files people write say ``"0.01 deg/h"``, ``"0.001 deg/sqrt(h)"``, ``"100 ug"``,
``"10 ug/sqrt(Hz)"``, ``"50 ppm"``. :func:`quantity` parses such a string, checks its
dimension against what the field expects and returns the SI value (radians for angles).
A bare number takes the field's documented default unit.

Dimensions are exponent vectors over length, time and angle. Angle is kept as a
dimension of its own (although SI calls it dimensionless) so that ``"0.01 m/s"`` given
for a gyro bias is refused instead of silently read as rad/s.
"""

from __future__ import annotations

import math
import re
from fractions import Fraction
from typing import Any

import numpy as np

from bench.errors import ConfigError

__all__ = ["quantity", "vector", "parse_unit", "split_quantity", "DIMENSIONS", "G0", "to_unit"]

#: Standard gravity, m/s^2, used by the units ``g``, ``mg`` and ``ug``.
G0 = 9.80665

Dim = tuple[Fraction, Fraction, Fraction]  # (length, time, angle)

_ZERO: Dim = (Fraction(0), Fraction(0), Fraction(0))


def _d(length: int = 0, time: int = 0, angle: int = 0) -> Dim:
    return (Fraction(length), Fraction(time), Fraction(angle))


_UNITS: dict[str, tuple[float, Dim]] = {
    # length
    "m": (1.0, _d(1)),
    "km": (1e3, _d(1)),
    "cm": (1e-2, _d(1)),
    "mm": (1e-3, _d(1)),
    # time
    "s": (1.0, _d(0, 1)),
    "ms": (1e-3, _d(0, 1)),
    "us": (1e-6, _d(0, 1)),
    "ns": (1e-9, _d(0, 1)),
    "min": (60.0, _d(0, 1)),
    "h": (3600.0, _d(0, 1)),
    "Hz": (1.0, _d(0, -1)),
    "kHz": (1e3, _d(0, -1)),
    # angle
    "rad": (1.0, _d(0, 0, 1)),
    "mrad": (1e-3, _d(0, 0, 1)),
    "urad": (1e-6, _d(0, 0, 1)),
    "deg": (math.pi / 180.0, _d(0, 0, 1)),
    "arcmin": (math.pi / 180.0 / 60.0, _d(0, 0, 1)),
    "arcsec": (math.pi / 180.0 / 3600.0, _d(0, 0, 1)),
    # acceleration in units of standard gravity
    "g": (G0, _d(1, -2)),
    "mg": (G0 * 1e-3, _d(1, -2)),
    "ug": (G0 * 1e-6, _d(1, -2)),
    "Gal": (1e-2, _d(1, -2)),
    # ratios
    "1": (1.0, _ZERO),
    "ppm": (1e-6, _ZERO),
    "ppb": (1e-9, _ZERO),
    "%": (1e-2, _ZERO),
}
_ALIASES = {
    "°": "deg",
    "degree": "deg",
    "degrees": "deg",
    "µg": "ug",
    "μg": "ug",
    "sec": "s",
    "hr": "h",
    "hour": "h",
    "percent": "%",
    "kph": "km/h",
}

#: Named dimensions fields are declared with, as SI unit expressions.
DIMENSIONS: dict[str, str] = {
    "dimensionless": "1",
    "length": "m",
    "time": "s",
    "frequency": "Hz",
    "angle": "rad",
    "velocity": "m/s",
    "acceleration": "m/s^2",
    "jerk": "m/s^3",
    "angular_rate": "rad/s",
    "angular_acceleration": "rad/s^2",
    "angle_random_walk": "rad/sqrt(s)",
    "rate_random_walk": "rad/s/sqrt(s)",
    "velocity_random_walk": "m/s/sqrt(s)",
    "acceleration_random_walk": "m/s^2/sqrt(s)",
    "g_sensitivity": "rad/s/(m/s^2)",
    "angular_rate_psd": "rad/s/sqrt(Hz)",
}

_TOKEN = re.compile(r"\s*(sqrt\(|\(|\)|\*|/|\^|[-+]?\d+(?:\.\d*)?|[A-Za-z%°µμ]+)")


class _UnitParser:
    """Recursive-descent parser of unit expressions: ``deg/h/sqrt(Hz)``, ``m/s^2``."""

    def __init__(self, text: str):
        self.text = text
        self.tokens = self._tokenize(text)
        self.pos = 0

    def _tokenize(self, text: str) -> list[str]:
        tokens: list[str] = []
        i = 0
        while i < len(text):
            if text[i].isspace():
                i += 1
                continue
            m = _TOKEN.match(text, i)
            if not m or m.end() == i:
                raise ValueError(f"cannot read unit {text!r} at {text[i:]!r}")
            tokens.append(m.group(1))
            i = m.end()
        return tokens

    def _peek(self) -> str | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def _take(self) -> str:
        tok = self._peek()
        if tok is None:
            raise ValueError(f"unit {self.text!r} ends too early")
        self.pos += 1
        return tok

    def parse(self) -> tuple[float, Dim]:
        value = self._expr()
        if self._peek() is not None:
            raise ValueError(f"unexpected {self._peek()!r} in unit {self.text!r}")
        return value

    def _expr(self) -> tuple[float, Dim]:
        scale, dim = self._factor()
        while self._peek() in ("*", "/"):
            op = self._take()
            s2, d2 = self._factor()
            if op == "*":
                scale, dim = scale * s2, _add(dim, d2, 1)
            else:
                scale, dim = scale / s2, _add(dim, d2, -1)
        return scale, dim

    def _factor(self) -> tuple[float, Dim]:
        tok = self._take()
        if tok == "sqrt(":
            scale, dim = self._expr()
            if self._take() != ")":
                raise ValueError(f"missing ')' in unit {self.text!r}")
            scale, dim = math.sqrt(scale), _mul(dim, Fraction(1, 2))
        elif tok == "(":
            scale, dim = self._expr()
            if self._take() != ")":
                raise ValueError(f"missing ')' in unit {self.text!r}")
        else:
            name = _ALIASES.get(tok, tok)
            if name not in _UNITS:
                if tok in _ALIASES and "/" in name:  # alias to an expression such as kph
                    scale, dim = _UnitParser(name).parse()
                else:
                    raise ValueError(f"unknown unit {tok!r} in {self.text!r}")
            else:
                scale, dim = _UNITS[name]
        if self._peek() == "^":
            self._take()
            power = Fraction(self._take())
            scale, dim = scale ** float(power), _mul(dim, power)
        return scale, dim


def _add(a: Dim, b: Dim, sign: int) -> Dim:
    return (a[0] + sign * b[0], a[1] + sign * b[1], a[2] + sign * b[2])


def _mul(a: Dim, k: Fraction) -> Dim:
    return (a[0] * k, a[1] * k, a[2] * k)


def parse_unit(text: str) -> tuple[float, Dim]:
    """Return ``(scale to SI, dimension)`` of a unit expression such as ``deg/sqrt(h)``."""
    return _UnitParser(text.strip()).parse()


def _describe(dim: Dim) -> str:
    for name, expr in DIMENSIONS.items():
        if parse_unit(expr)[1] == dim:
            return name
    names = ("m", "s", "rad")
    parts = [f"{n}^{e}" for n, e in zip(names, dim, strict=True) if e != 0]
    return " ".join(parts) or "dimensionless"


_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def split_quantity(text: str) -> tuple[float, str] | None:
    """The number and the unit of a quantity string as written (``"80 ms"`` -> ``(80.0,
    "ms")``, ``"3"`` -> ``(3.0, "")``); None when ``text`` does not start with a number.
    The unit is not checked (:func:`parse_unit`)."""
    m = _NUMBER.match(text)
    return None if not m else (float(m.group(1)), m.group(2))


def quantity(
    value: Any,
    dimension: str,
    default_unit: str,
    *,
    file: str | None = None,
    key: str | None = None,
) -> float:
    """Parse one quantity and return its SI value.

    Parameters
    ----------
    value:
        A number (taken in ``default_unit``) or a string ``"<number> <unit>"``.
    dimension:
        One of :data:`DIMENSIONS`: what the field must measure.
    default_unit:
        The unit of a bare number, and the example given in error messages.
    file, key:
        Where the value came from, for the error message.

    Raises
    ------
    ConfigError
        When the value is not a number or a quantity of the expected dimension, or is not
        finite in SI (TOML's ``nan`` and ``inf``, ``"1e400 m"``, ``"1e306 km"``).
    """
    expected = parse_unit(DIMENSIONS[dimension])[1]
    if isinstance(value, bool):
        raise ConfigError(f"expected {dimension} such as '1 {default_unit}', found {value!r}", file=file, key=key)
    if isinstance(value, (int, float)):
        scale, dim = parse_unit(default_unit)
        return _finite(_times(value, scale), value, dimension, file, key)
    if not isinstance(value, str):
        raise ConfigError(f"expected {dimension} such as '1 {default_unit}', found {value!r}", file=file, key=key)
    m = _NUMBER.match(value)
    if not m:
        raise ConfigError(f"expected {dimension} such as '1 {default_unit}', found {value!r}", file=file, key=key)
    number, unit = float(m.group(1)), m.group(2) or default_unit
    try:
        scale, dim = parse_unit(unit)
    except (ValueError, ArithmeticError) as exc:  # ArithmeticError: "km^400" overflows
        reason = str(exc) if isinstance(exc, ValueError) else f"unit {unit!r} is out of range"
        raise ConfigError(f"{reason}; expected {dimension} such as '1 {default_unit}'", file=file, key=key) from None
    if dim != expected:
        raise ConfigError(
            f"expected {dimension} such as '1 {default_unit}', found {value!r} ({_describe(dim)})",
            file=file,
            key=key,
        )
    return _finite(number * scale, value, dimension, file, key)


def _times(value: int | float, scale: float) -> float:
    try:
        return float(value) * scale
    except OverflowError:  # an integer beyond any float
        return math.inf


def _finite(x: float, value: Any, dimension: str, file: str | None, key: str | None) -> float:
    if not math.isfinite(x):
        raise ConfigError(f"expected a finite {dimension}, found {value!r}", file=file, key=key)
    return x


def vector(
    value: Any,
    dimension: str,
    default_unit: str,
    n: int = 3,
    *,
    file: str | None = None,
    key: str | None = None,
) -> np.ndarray:
    """Parse ``n`` quantities: one value for all axes, or a list of ``n`` values.

    Returns
    -------
    numpy.ndarray, shape (n,)
        SI values.
    """
    if isinstance(value, (list, tuple)):
        if len(value) != n:
            raise ConfigError(f"expected {n} values, found {len(value)}", file=file, key=key)
        return np.array(
            [
                quantity(v, dimension, default_unit, file=file, key=f"{key}[{i}]" if key else None)
                for i, v in enumerate(value)
            ]
        )
    return np.full(n, quantity(value, dimension, default_unit, file=file, key=key))


def to_unit(value_si: float | np.ndarray, unit: str) -> float | np.ndarray:
    """Express an SI value in ``unit`` (for reports and messages)."""
    return value_si / parse_unit(unit)[0]
