"""Reading TOML tables strictly: every error names the file, the key and what was expected.

:class:`Table` wraps one parsed table. Each getter checks the type (and unit, choices,
finiteness, bound) of one key and remembers it was read; :meth:`Table.finish` then refuses
any key nobody read, listing the ones allowed. Numbers are finite (TOML's ``nan`` and
``inf`` are refused, and so is ``"1e400 m"``); ``bound=`` names a kind of
:data:`bench.config.bounds.BOUNDS`. Loaders that walk raw tables use :func:`check_keys`
for the same unknown-key message. Messages look like::

    test_cases/S000.toml: criterion[2].at_most: expected length such as '1 m', found '3 m/s' (velocity)
    test_cases/S000.toml: run.monte_carlo: expected a number of runs <= 10000, found 1000000000
"""

from __future__ import annotations

import datetime as _dt
import math
import re
from collections.abc import Collection, Iterable, Mapping
from typing import Any

from bench.config.bounds import check
from bench.errors import ConfigError
from bench.units import quantity

__all__ = ["Table", "type_name", "check_keys", "unknown_key"]


def type_name(value: Any) -> str:
    """What a TOML value is, for messages."""
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, (_dt.date, _dt.time)):
        return "a date/time"
    return type(value).__name__


def unknown_key(
    name: Any, allowed: Iterable[str], *, file: str | None, key: str = "", noun: str = "key"
) -> ConfigError:
    """The error of an unknown key ``name`` in the table at ``key``, listing ``allowed``."""
    listed = ", ".join(sorted(allowed)) or "none"
    where = f"{key}.{name}" if key else str(name)
    return ConfigError(f"unknown {noun} {name!r}; expected one of: {listed}", file=file, key=where)


def check_keys(
    data: Mapping[str, Any], allowed: Collection[str], *, file: str | None, key: str = "", noun: str = "key"
) -> None:
    """Refuse the first key of ``data`` not in ``allowed`` (the message lists them), or
    ``data`` itself when it is not a table."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"expected a table, found {data!r} ({type_name(data)})", file=file, key=key or None)
    for name in data:
        if name not in allowed:
            raise unknown_key(name, allowed, file=file, key=key, noun=noun)


class Table:
    """A TOML table read key by key (see the module docstring)."""

    def __init__(self, data: Any, file: str | None, key: str = ""):
        if not isinstance(data, Mapping):
            raise ConfigError(f"expected a table, found {type_name(data)}", file=file, key=key or None)
        self.data = data
        self.file = file
        self.key = key
        self._used: set[str] = set()

    # -- basics -------------------------------------------------------------------------
    def path(self, name: str) -> str:
        return f"{self.key}.{name}" if self.key else name

    def error(self, name: str | None, message: str) -> ConfigError:
        return ConfigError(message, file=self.file, key=self.path(name) if name else (self.key or None))

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: Any = None, *, required: bool = False, expect: str = "a value") -> Any:
        self._used.add(name)
        if name not in self.data:
            if required:
                raise self.error(name, f"missing field; expected {expect}")
            return default
        return self.data[name]

    def finish(self) -> None:
        """Refuse keys that were never read."""
        check_keys(self.data, self._used, file=self.file, key=self.key)

    def bounded(self, name: str, kind: str | None, value: float, shown: Any) -> float:
        """``value`` checked against the bound ``kind`` (None: no bound)."""
        if kind is None:
            return value
        return check(kind, value, file=self.file, key=self.path(name), shown=shown)

    # -- typed getters ------------------------------------------------------------------
    def str(
        self,
        name: str,
        default: str | None = None,
        *,
        required: bool = False,
        choices: Iterable[str] | None = None,
        pattern: str | None = None,
        expect: str = "a string",
    ) -> str | None:
        choices = tuple(choices) if choices is not None else None
        if choices:
            expect = "one of " + ", ".join(repr(c) for c in choices)
        v = self.raw(name, default, required=required, expect=expect)
        if v is None:
            return None
        if not isinstance(v, str):
            raise self.error(name, f"expected {expect}, found {v!r} ({type_name(v)})")
        if choices is not None and v not in choices:
            raise self.error(name, f"expected {expect}, found {v!r}")
        if pattern is not None and not re.fullmatch(pattern, v):
            raise self.error(name, f"expected {expect} matching {pattern}, found {v!r}")
        return v

    def int(
        self,
        name: str,
        default: int | None = None,
        *,
        required: bool = False,
        minimum: int | None = None,
        maximum: int | None = None,
        bound: str | None = None,
    ) -> int | None:
        bounds = [f">= {minimum}" if minimum is not None else "", f"<= {maximum}" if maximum is not None else ""]
        expect = " ".join(["an integer", " and ".join(b for b in bounds if b)]).strip()
        v = self.raw(name, default, required=required, expect=expect)
        if v is None:
            return None
        if not isinstance(v, int) or isinstance(v, bool):
            raise self.error(name, f"expected {expect}, found {v!r} ({type_name(v)})")
        if (minimum is not None and v < minimum) or (maximum is not None and v > maximum):
            raise self.error(name, f"expected {expect}, found {v}")
        self.bounded(name, bound, v, v)
        return v

    def number(
        self,
        name: str,
        default: float | None = None,
        *,
        required: bool = False,
        bound: str | None = None,
    ) -> float | None:
        """A finite number (an integer is taken as a float), optionally bounded."""
        v = self.raw(name, default, required=required, expect="a number")
        if v is None:
            return None
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            raise self.error(name, f"expected a number, found {v!r} ({type_name(v)})")
        try:
            x = float(v)
        except OverflowError:  # an integer beyond any float
            x = math.inf
        if not math.isfinite(x):
            raise self.error(name, f"expected a finite number, found {v!r}")
        return self.bounded(name, bound, x, v)

    def bool(self, name: str, default: bool | None = None, *, required: bool = False) -> bool | None:
        v = self.raw(name, default, required=required, expect="true or false")
        if v is None:
            return None
        if not isinstance(v, bool):
            raise self.error(name, f"expected true or false, found {v!r} ({type_name(v)})")
        return v

    def str_list(self, name: str, *, required: bool = False, allow_single: bool = True) -> list[str]:
        expect = "an array of strings" + (" or a string" if allow_single else "")
        v = self.raw(name, None, required=required, expect=expect)
        if v is None:
            return []
        if allow_single and isinstance(v, str):
            return [v]
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            raise self.error(name, f"expected {expect}, found {v!r} ({type_name(v)})")
        return list(v)

    def quantity(
        self,
        name: str,
        dimension: str,
        unit: str,
        default: Any = None,
        *,
        required: bool = False,
        positive: bool = False,
        nonnegative: bool = False,
        bound: str | None = None,
    ) -> float | None:
        """A finite quantity in SI (see :func:`bench.units.quantity`), optionally bounded."""
        v = self.raw(name, default, required=required, expect=f"{dimension} such as '1 {unit}'")
        if v is None:
            return None
        x = quantity(v, dimension, unit, file=self.file, key=self.path(name))
        if positive and not x > 0.0:
            raise self.error(name, f"expected a positive {dimension}, found {v!r}")
        if nonnegative and x < 0.0:
            raise self.error(name, f"expected a non-negative {dimension}, found {v!r}")
        return self.bounded(name, bound, x, v)

    def time_ns(
        self,
        name: str,
        default: Any = None,
        *,
        required: bool = False,
        positive: bool = False,
        bound: str | None = None,
    ) -> int | None:
        """A time in integer ns, bounded (default: ``duration`` if positive, else ``time``)."""
        kind = bound or ("duration" if positive else "time")
        x = self.quantity(
            name, "time", "s", default, required=required, positive=positive, nonnegative=True, bound=kind
        )
        return None if x is None else round(x * 1e9)

    def table(self, name: str, *, required: bool = False) -> Table | None:
        v = self.raw(name, None, required=required, expect=f"a [{self.path(name)}] table")
        if v is None:
            return None
        if not isinstance(v, Mapping):
            raise self.error(name, f"expected a table, found {v!r} ({type_name(v)})")
        return Table(v, self.file, self.path(name))

    def tables(self, name: str) -> list[Table]:
        v = self.raw(name, None)
        if v is None:
            return []
        if not isinstance(v, list):
            raise self.error(name, f"expected an array of [[{self.path(name)}]] tables, found {type_name(v)}")
        return [Table(x, self.file, f"{self.path(name)}[{i}]") for i, x in enumerate(v)]
