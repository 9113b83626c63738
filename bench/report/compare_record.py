"""A results record read for ``bench compare``: checked, its cases and criteria by key.

The file is read by :func:`bench.config.files.read_json`: a regular file of at most 256
MiB, nested at most 64 levels, every number finite (a raw ``NaN``, ``Infinity`` or
``1e999`` is refused; an infinite measurement is the string ``"inf"``). Only what the
comparison uses is checked further (a criterion's id, comparator, value, verdict, unit,
limit and variant); unknown fields are ignored. Anything else raises
:class:`~bench.errors.ConfigError` naming the file and the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.acceptance.criteria import COMPARATORS
from bench.config.files import read_json
from bench.errors import ConfigError

__all__ = ["Key", "Record", "load_record", "value_of"]

Key = tuple[str, str, str | None, bool]  # case id, criterion id, variant, control


@dataclass(frozen=True)
class Record:
    """A checked results record: its file, the raw JSON, the cases and criteria by key."""

    path: str
    data: dict[str, Any]
    cases: dict[str, dict[str, Any]]
    criteria: dict[Key, dict[str, Any]]


def value_of(x: Any) -> float | None:
    """A record's value as a float: ``"inf"``/``"-inf"`` as infinities, None (unmeasured) kept."""
    if x is None:
        return None
    if x == "inf":
        return math.inf
    if x == "-inf":
        return -math.inf
    return float(x)


def _is_value(x: Any) -> bool:
    return x is None or x in ("inf", "-inf") or (isinstance(x, int | float) and not isinstance(x, bool))


def _check(ok: bool, path: str, key: str, expected: str, found: Any) -> None:
    if not ok:
        shown = repr(found) if len(repr(found)) < 60 else repr(found)[:57] + "..."
        raise ConfigError(f"not a results record: expected {expected}, found {shown}", file=path, key=key)


def load_record(path: str | Path) -> Record:
    """Read and check a results record, or the ``results.json`` in folder ``path``.

    Raises :class:`ConfigError` naming the file (and the field) for a file that cannot be
    read or is not a results record."""
    p = Path(path)
    if p.is_dir():
        p = p / "results.json"
    name = str(p)
    data = read_json(p, what="results record")
    _check(isinstance(data, dict), name, "", "a JSON object", type(data).__name__)
    schema = data.get("schema")
    _check(isinstance(schema, str) and schema.startswith("bench.results"), name, "schema",
           "'bench.results.v1'", schema)
    _check(isinstance(data.get("cases"), list), name, "cases", "an array of cases", data.get("cases"))
    cases: dict[str, dict[str, Any]] = {}
    criteria: dict[Key, dict[str, Any]] = {}
    for i, case in enumerate(data["cases"]):
        at = f"cases[{i}]"
        _check(isinstance(case, dict), name, at, "an object", case)
        _check(isinstance(case.get("id"), str), name, f"{at}.id", "a case id", case.get("id"))
        _check(isinstance(case.get("verdict"), str), name, f"{at}.verdict", "a verdict", case.get("verdict"))
        _check(case["id"] not in cases, name, f"{at}.id", "a unique case id", case["id"])
        _check(isinstance(case.get("criteria"), list), name, f"{at}.criteria", "an array", case.get("criteria"))
        cases[case["id"]] = case
        for j, c in enumerate(case["criteria"]):
            ct = f"{at}.criteria[{j}]"
            _check(isinstance(c, dict), name, ct, "an object", c)
            for k, ok, what in (
                ("id", isinstance(c.get("id"), str), "a criterion id"),
                ("comparator", c.get("comparator") in COMPARATORS, f"one of {', '.join(COMPARATORS)}"),
                ("value", _is_value(c.get("value")), "a number, 'inf' or null"),
                ("verdict", isinstance(c.get("verdict"), str), "a verdict"),
                ("unit", isinstance(c.get("unit"), str), "a unit"),
                ("limit_si", isinstance(c.get("limit_si"), dict)
                 and all(_is_value(c["limit_si"].get(s)) for s in ("low", "high")), "{low, high}"),
                ("variant", c.get("variant") is None or isinstance(c.get("variant"), str), "a variant or null"),
            ):
                _check(ok, name, f"{ct}.{k}", what, c.get(k))
            key = (case["id"], c["id"], c.get("variant"), bool(c.get("control")))
            _check(key not in criteria, name, f"{ct}.id", "a unique (criterion, variant, control)", c["id"])
            criteria[key] = c
    return Record(name, data, cases, criteria)
