"""Sensor parameters as datasheets write them: declared once, parsed with units, documented.

Each aiding sensor declares its parameters as a table of :class:`Param` (dimension,
unit of bare numbers, default, one line of text). A scenario's ``[doppler]``,
``[odometer]``, ``[bds]`` or ``[driver]`` table may name a parameter set in
``models/sensors/<kind>/<name>.toml`` with ``model = "<name>"`` and override any of its
keys; :func:`resolve` reads both, checks every key and returns SI values.
:func:`markdown_table` renders the declarations for ``docs/sensors.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.config.bounds import check
from bench.config.files import read_toml
from bench.config.table import unknown_key
from bench.errors import ConfigError
from bench.paths import models_dir
from bench.units import DIMENSIONS, quantity, vector

__all__ = ["Param", "parse_params", "resolve", "find_model", "markdown_table", "Resolved"]

#: Keys a parameter-set file may carry besides parameters.
_META_KEYS = ("name", "description", "source", "assumed")


@dataclass(frozen=True)
class Param:
    """One parameter.

    ``dimension`` is a :data:`bench.units.DIMENSIONS` name, or ``"integer"``, ``"number"``
    (a plain float), ``"boolean"``, ``"text"`` (one of ``choices`` when given) or
    ``"text_list"``. ``n`` > 1 makes it a vector (one value for all, or a list of n).
    ``lo``/``hi`` bound the SI value (inclusive); rates and times are also held to the
    bench-wide ``rate`` and ``offset`` bounds (:mod:`bench.config.bounds`).
    """

    dimension: str
    unit: str
    default: Any
    description: str
    n: int = 1
    choices: tuple[str, ...] = ()
    lo: float | None = None
    hi: float | None = None


def _check_range(value: Any, p: Param, file: str | None, key: str) -> None:
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"expected a finite value, found {value!r}", file=file, key=key)
    if p.lo is not None and np.any(arr < p.lo):
        raise ConfigError(f"expected a value >= {p.lo:g} (SI), found {value!r}", file=file, key=key)
    if p.hi is not None and np.any(arr > p.hi):
        raise ConfigError(f"expected a value <= {p.hi:g} (SI), found {value!r}", file=file, key=key)
    kind = {"frequency": "rate", "time": "offset"}.get(p.dimension)
    if kind is not None:
        for x in arr:
            check(kind, float(x), file=file, key=key, shown=value)


def _one(value: Any, p: Param, file: str | None, key: str) -> Any:
    if p.dimension == "boolean":
        if not isinstance(value, bool):
            raise ConfigError(f"expected true or false, found {value!r}", file=file, key=key)
        return value
    if p.dimension == "integer":
        if not isinstance(value, int) or isinstance(value, bool):
            raise ConfigError(f"expected an integer, found {value!r}", file=file, key=key)
        _check_range(value, p, file, key)
        return value
    if p.dimension == "number":
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise ConfigError(f"expected a number, found {value!r}", file=file, key=key)
        _check_range(value, p, file, key)
        return float(value)
    if p.dimension == "text":
        if not isinstance(value, str) or (p.choices and value not in p.choices):
            allowed = f"one of {', '.join(p.choices)}" if p.choices else "text"
            raise ConfigError(f"expected {allowed}, found {value!r}", file=file, key=key)
        return value
    if p.dimension == "text_list":
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            raise ConfigError(f"expected a list of names, found {value!r}", file=file, key=key)
        bad = [v for v in value if p.choices and v not in p.choices]
        if bad:
            raise ConfigError(f"unknown {bad[0]!r}; expected names from {', '.join(p.choices)}", file=file, key=key)
        return tuple(value)
    if p.n > 1:
        out = vector(value, p.dimension, p.unit, p.n, file=file, key=key)
    else:
        out = quantity(value, p.dimension, p.unit, file=file, key=key)
    _check_range(out, p, file, key)
    return out


def parse_params(
    table: Mapping[str, Any], specs: Mapping[str, Param], *, file: str | None, where: str, allow: tuple[str, ...] = ()
) -> dict[str, Any]:
    """Only the keys present in ``table``, checked and converted to SI (no defaults).

    Keys in ``allow`` are passed through untouched; any other unknown key is an error.
    """
    out: dict[str, Any] = {}
    for k, v in table.items():
        if k in allow:
            continue
        if k not in specs:
            raise unknown_key(k, [*specs, *allow], file=file, key=where)
        out[k] = _one(v, specs[k], file, f"{where}.{k}")
    return out


def defaults(specs: Mapping[str, Param]) -> dict[str, Any]:
    """Every default, in SI."""
    return {k: _one(p.default, p, None, k) for k, p in specs.items()}


def find_model(kind: str, name: str, *, file: str | None = None, key: str | None = None) -> Path:
    """Path of parameter set ``name`` (a path, or a name in ``models/sensors/<kind>/``)."""
    p = Path(name)
    if p.suffix == ".toml":
        if not p.is_absolute() and file is not None and not p.exists():
            p = Path(file).parent / p
        if not p.exists():
            raise ConfigError(f"parameter set {name!r} not found", file=file, key=key)
        return p
    folder = models_dir() / "sensors" / kind
    candidate = folder / f"{name}.toml"
    if candidate.exists():
        return candidate
    known = ", ".join(sorted(f.stem for f in folder.glob("*.toml"))) or "none"
    raise ConfigError(f"no {kind} parameter set {name!r}; known: {known}", file=file, key=key)


@dataclass
class Resolved:
    """Parameters of one sensor in SI, and where they came from."""

    values: dict[str, Any]
    model_path: Path | None
    model_name: str

    def __getitem__(self, key: str) -> Any:
        return self.values[key]

    def record(self) -> dict[str, Any]:
        """JSON-friendly copy (for the recording's metadata)."""

        def conv(v: Any) -> Any:
            if isinstance(v, np.ndarray):
                return v.tolist()
            if isinstance(v, tuple):
                return list(v)
            if isinstance(v, float) and not math.isfinite(v):
                return str(v)
            return v

        return {k: conv(v) for k, v in self.values.items()}


def resolve(
    kind: str,
    table: Mapping[str, Any] | None,
    specs: Mapping[str, Param],
    *,
    file: str | None = None,
    where: str | None = None,
    allow: tuple[str, ...] = (),
) -> Resolved:
    """Defaults, then the named parameter set (``model = ...``), then the table's own keys."""
    where = where or kind
    if table is not None and not isinstance(table, Mapping):
        raise ConfigError(f"expected a table, found {table!r}", file=file, key=where)
    table = dict(table or {})
    values = defaults(specs)
    model_path: Path | None = None
    model_name = "default"
    ref = table.get("model")
    if ref is not None:
        if not isinstance(ref, str):
            raise ConfigError(f"expected a parameter-set name, found {ref!r}", file=file, key=f"{where}.model")
        model_path = find_model(kind, ref, file=file, key=f"{where}.model")
        doc = read_toml(model_path, what="parameter set")
        model_name = str(doc.get("name", model_path.stem))
        values.update(parse_params(doc, specs, file=str(model_path), where=kind, allow=_META_KEYS))
    values.update(parse_params(table, specs, file=file, where=where, allow=("model", *allow)))
    return Resolved(values, model_path, model_name)


def markdown_table(specs: Mapping[str, Param]) -> str:
    """The parameters as a Markdown table: key, unit of bare numbers, default, meaning."""
    rows = ["| key | unit | default | meaning |", "|---|---|---|---|"]
    for k, p in specs.items():
        if p.dimension in DIMENSIONS:
            unit = p.unit
        else:
            unit = {"integer": "integer", "number": "1", "boolean": "true/false", "text_list": "list"}.get(
                p.dimension, "text"
            )
        d = p.default
        if isinstance(d, bool):
            default = "true" if d else "false"
        elif isinstance(d, (list, tuple)):
            default = "[" + ", ".join(f'"{x}"' if isinstance(x, str) else f"{x:g}" for x in d) + "]"
        elif isinstance(d, str):
            default = f'"{d}"'
        elif p.n > 1:
            default = "[" + ", ".join([f"{d:g}"] * p.n) + "]"
        else:
            default = f"{d:g}"
        text = p.description
        if p.choices and p.dimension == "text":
            text += f" ({', '.join(p.choices)})"
        rows.append(f"| `{k}` | {unit} | {default} | {text} |")
    return "\n".join(rows)
