"""One mapped quantity: an FMU variable (or a constant) to a bench value and back.

A channel reads ``bench = sign * scale * k * (fmu - offset)`` with ``k`` the SI value of one
``unit`` (:func:`bench.units.parse_unit`); a constant channel (``value = ...``) has no FMU
variable and gives the same formula applied to ``value``. Angles may follow another
convention than the bench's heading (clockwise from north): ``convention =
"ccw_from_east"`` reads ``bench = pi/2 - sign * scale * k * (fmu - offset)`` (a yaw angle
counter-clockwise from east). :meth:`Channel.to_fmu` is the exact inverse, and wraps the
FMU value into ``wrap`` (``"symmetric"``: half a turn either side of zero, ``"positive"``:
one turn from zero, in the FMU's own unit) when the mapping asks for it.

A :class:`VectorChannel` is three channels (each its own variable or constant, unit,
scale, sign and offset) along the axes of a body frame, turned into the bench's RFU axes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.units import parse_unit

__all__ = ["Channel", "VectorChannel", "parse_channel", "parse_vector", "FRAMES", "CONVENTIONS", "WRAPS"]

#: Matrices M with v_RFU = M @ v_frame (proper rotations: rates transform alike).
FRAMES: dict[str, np.ndarray] = {
    "RFU": np.eye(3),
    "FLU": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    "FRD": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),
}
#: Angle conventions of a heading: the bench's own, and a yaw counter-clockwise from east.
CONVENTIONS = ("cw_from_north", "ccw_from_east")
#: How an angle written into the FMU is wrapped (in the FMU's unit).
WRAPS = ("none", "symmetric", "positive")
_KEYS = {"var", "value", "unit", "scale", "sign", "offset", "values", "convention", "wrap"}


@dataclass(frozen=True)
class Channel:
    """One scalar: ``bench = sign * scale * k * (fmu - offset)`` (see the module docstring).

    ``var`` is None for a constant ``value``; ``values`` maps lever positions 0/1/2 to FMU
    codes; ``key`` is the mapping file's key (named in messages).
    """

    var: str | None
    unit: str | None
    k: float = 1.0
    sign: float = 1.0
    offset: float = 0.0
    values: tuple[int, ...] | None = None
    scale: float = 1.0
    value: float | None = None
    convention: str = "cw_from_north"
    wrap: str = "none"
    key: str = ""
    expect: str = ""  # the bench unit of the quantity ("m/s", "rad", "1", "lever")

    @property
    def gain(self) -> float:
        """SI value of one FMU unit, with sign and scale."""
        return self.sign * self.scale * self.k

    def to_bench(self, raw: np.ndarray | float) -> np.ndarray | float:
        """FMU value(s) -> bench value(s) (SI; a heading clockwise from north)."""
        x = self.gain * (raw - self.offset)
        return 0.5 * math.pi - x if self.convention == "ccw_from_east" else x

    def constant(self, n: int) -> np.ndarray:
        """The bench value of a constant channel, ``n`` times."""
        assert self.value is not None
        return np.full(n, float(self.to_bench(self.value)))

    def to_fmu(self, value: float) -> float:
        """Bench value -> FMU value (the inverse of :meth:`to_bench`, wrapped as asked)."""
        if self.values is not None:
            return float(self.values[round(value)])
        x = 0.5 * math.pi - value if self.convention == "ccw_from_east" else value
        raw = self.offset + x / self.gain
        if self.wrap != "none":
            turn = 2.0 * math.pi / abs(self.scale * self.k)
            base = raw - self.offset
            base = math.fmod(base, turn)
            if self.wrap == "positive" and base < 0.0:
                base += turn
            elif self.wrap == "symmetric":
                base = (base + 0.5 * turn) % turn - 0.5 * turn
            raw = self.offset + base
        return raw


@dataclass(frozen=True)
class VectorChannel:
    """Three channels along the axes of ``frame``, converted to RFU and SI."""

    components: tuple[Channel, Channel, Channel]
    frame: str

    @property
    def vars(self) -> tuple[str, ...]:
        """The FMU variables read (constants have none)."""
        return tuple(c.var for c in self.components if c.var is not None)

    def to_rfu(self, columns: list[np.ndarray]) -> np.ndarray:
        """Three (N,) arrays of FMU values (constants: any array of N) -> (N, 3) SI in RFU."""
        parts = [c.constant(len(x)) if c.var is None else c.to_bench(x) for c, x in zip(self.components, columns,
                                                                                        strict=True)]
        return np.column_stack(parts) @ FRAMES[self.frame].T


def unit_factor(unit: Any, expect: str, file: str, key: str) -> float:
    """SI value of ``unit``, checked to measure ``expect`` (a unit expression)."""
    if unit is None:
        return 1.0
    if expect == "lever":
        raise ConfigError("lever channels take 'values', not a unit", file=file, key=key)
    try:
        k, dim = parse_unit(str(unit))
    except Exception as exc:
        raise ConfigError(f"unknown unit {unit!r}: {exc}", file=file, key=key) from None
    if dim != parse_unit(expect)[1]:
        raise ConfigError(f"unit {unit!r} does not measure {expect!r}", file=file, key=key)
    return k


def _number(value: Any, file: str, key: str, *, nonzero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"expected a finite number, found {value!r}", file=file, key=key)
    if nonzero and value == 0:
        raise ConfigError("expected a non-zero number", file=file, key=key)
    return float(value)


def _sign(value: Any, file: str, key: str) -> float:
    if value not in (1, -1) or isinstance(value, bool):
        raise ConfigError(f"expected 1 or -1, found {value!r}", file=file, key=key)
    return float(value)


def _choice(t: Mapping[str, Any], name: str, allowed: tuple[str, ...], file: str, key: str) -> str:
    value = t.get(name, allowed[0])
    if value not in allowed:
        raise ConfigError(f"expected one of {', '.join(allowed)}, found {value!r}", file=file, key=f"{key}.{name}")
    return str(value)


def parse_channel(
    t: Any, expect: str, file: str, key: str, *, defaults: Mapping[str, Any] | None = None, constant: bool = True,
    angle: bool = False,
) -> Channel:
    """A channel table ``{ var | value, unit, scale, sign, offset[, values, convention, wrap] }``.

    A bare string is a variable name. ``defaults`` (a vector's shared ``unit`` and
    ``sign``) fill keys the table leaves out; ``constant`` allows ``value``; ``angle``
    allows ``convention`` and ``wrap``.
    """
    if isinstance(t, str):
        t = {"var": t}
    if not isinstance(t, Mapping):
        raise ConfigError(f"expected a table with 'var' (or 'value'), found {t!r}", file=file, key=key)
    check_keys(t, _KEYS, file=file, key=key)
    if ("var" in t) == ("value" in t):
        what = "'var' or 'value' (a constant)" if constant else "'var'"
        raise ConfigError(f"expected exactly one of {what}", file=file, key=key)
    if "value" in t and not constant:
        raise ConfigError("a constant is not allowed here: give 'var'", file=file, key=f"{key}.value")
    if not angle:
        for k in ("convention", "wrap"):
            if k in t:
                raise ConfigError(f"'{k}' applies to headings only", file=file, key=f"{key}.{k}")
    merged = {**(defaults or {}), **t}
    values = None
    if "values" in t:
        codes = t["values"]
        if (
            expect != "lever"
            or not isinstance(codes, list)
            or len(codes) != 3
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in codes)
        ):
            raise ConfigError("'values' lists the FMU codes of lever positions 0, 1, 2", file=file, key=f"{key}.values")
        values = tuple(int(v) for v in codes)
    unit = merged.get("unit")
    if "var" in t and (not isinstance(t["var"], str) or not t["var"]):
        raise ConfigError(f"expected a variable name, found {t['var']!r}", file=file, key=f"{key}.var")
    return Channel(
        var=str(t["var"]) if "var" in t else None,
        unit=None if unit is None else str(unit),
        k=unit_factor(unit, expect, file, f"{key}.unit") if expect != "lever" else 1.0,
        sign=_sign(merged.get("sign", 1), file, f"{key}.sign"),
        offset=_number(merged.get("offset", 0.0), file, f"{key}.offset"),
        values=values,
        scale=_number(merged.get("scale", 1.0), file, f"{key}.scale", nonzero=True),
        value=_number(t["value"], file, f"{key}.value") if "value" in t else None,
        convention=_choice(t, "convention", CONVENTIONS, file, key),
        wrap=_choice(t, "wrap", WRAPS, file, key),
        key=key,
        expect=expect,
    )


def parse_vector(t: Any, expect: str, frame: str, file: str, key: str) -> VectorChannel:
    """``{ vars = [three channels], unit, signs }`` (the original form: three names, one unit)
    or ``{ x = ..., y = ..., z = ... }`` (each component a channel of its own; ``unit``,
    ``sign`` shared where a component leaves them out). Components are along ``frame``."""
    if not isinstance(t, Mapping):
        raise ConfigError("expected a table with 'vars' or 'x', 'y', 'z'", file=file, key=key)
    if "vars" in t:
        check_keys(t, {"vars", "unit", "signs"}, file=file, key=key)
        comps = t["vars"]
        if not isinstance(comps, list) or len(comps) != 3:
            raise ConfigError("expected 'vars' = three variables (names or tables)", file=file, key=f"{key}.vars")
        signs = t.get("signs", [1, 1, 1])
        if not isinstance(signs, list) or len(signs) != 3:
            raise ConfigError("expected three signs", file=file, key=f"{key}.signs")
        keys = [f"{key}.vars[{i}]" for i in range(3)]
        defaults = [{"unit": t.get("unit"), "sign": _sign(s, file, f"{key}.signs")} for s in signs]
    else:
        check_keys(t, {"x", "y", "z", "unit", "sign"}, file=file, key=key)
        missing = [a for a in ("x", "y", "z") if a not in t]
        if missing:
            raise ConfigError(f"missing component(s) {', '.join(missing)} (give 'value = 0' for one the model does "
                              "not have)", file=file, key=key)
        comps = [t["x"], t["y"], t["z"]]
        keys = [f"{key}.{a}" for a in ("x", "y", "z")]
        defaults = [{"unit": t.get("unit"), "sign": t.get("sign", 1)}] * 3
    chans = tuple(parse_channel(c, expect, file, k, defaults={d: v for d, v in dd.items() if v is not None})
                  for c, k, dd in zip(comps, keys, defaults, strict=True))
    return VectorChannel(components=chans, frame=frame)  # type: ignore[arg-type]
