"""A case at one sweep point: ``[sweep_point]`` in a case's text sets values by key.

``bench campaign`` runs a case with ``[[sweep]]`` tables once per point; each point's case
is the file's text with a ``[sweep_point]`` table appended::

    [sweep_point]
    "sensors.doppler.scale_factor_markov" = "0.2 %"
    "fault[0].start" = "600 s"

Every case text is read through :func:`apply_sweep_point`, so the case attached to a
swept run's recording is the swept case: ``bench score`` re-judges it with the values the
run had, and a reader of the attachment sees them at its end.

A key is a dotted path into the case's tables; ``name[i]`` picks the i-th table of an
array of tables (``criterion[2].at_most``, ``fault[0].magnitude``). A sensor given by its
set's name (``doppler = "seed000"``) is read as ``{model = "seed000"}`` (``{grade = ...}``
for the IMU) when a key reaches into it, as the case schema reads it.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

from bench.errors import ConfigError

__all__ = ["apply_sweep_point", "sweep_point_toml", "parse_key", "check_key", "TABLE"]

#: The table of a case text that sets the values of its sweep point.
TABLE = "sweep_point"
_PART = re.compile(r"^([A-Za-z0-9_-]+)(?:\[(\d+)\])?$")
_SENSOR_NAME = {"imu": "grade"}  # the others: "model"


def parse_key(key: str) -> list[tuple[str, int | None]]:
    """``"a.b[2].c"`` -> ``[("a", None), ("b", 2), ("c", None)]``; ValueError when malformed."""
    if not isinstance(key, str) or not key:
        raise ValueError(f"expected a dotted key such as 'dut.config.rate', found {key!r}")
    out: list[tuple[str, int | None]] = []
    for part in key.split("."):
        m = _PART.match(part)
        if m is None:
            raise ValueError(
                f"expected a dotted key such as 'dut.config.rate' or 'criterion[0].at_most', found {key!r}")
        out.append((m.group(1), None if m.group(2) is None else int(m.group(2))))
    return out


def check_key(key: str, *, file: str | None = None, where: str = "sweep") -> None:
    """:func:`parse_key` as a :class:`ConfigError` naming the file and the key."""
    try:
        parse_key(key)
    except ValueError as exc:
        raise ConfigError(str(exc), file=file, key=where) from None


def _set(doc: dict[str, Any], key: str, value: Any, file: str | None) -> None:
    parts = parse_key(key)
    node: Any = doc
    path = ""
    for depth, (name, index) in enumerate(parts):
        last = depth == len(parts) - 1 and index is None
        path = f"{path}.{name}" if path else name
        if not isinstance(node, dict):
            raise ConfigError(f"cannot set {key!r}: {path.rsplit('.', 1)[0]!r} is not a table", file=file, key=TABLE)
        if last:
            node[name] = value
            return
        child = node.get(name)
        if child is None and index is None:
            child = node[name] = {}
        elif isinstance(child, str) and depth == 1 and parts[0][0] == "sensors" and index is None:
            child = node[name] = {_SENSOR_NAME.get(name, "model"): child}  # a sensor named by its set
        if index is not None:
            if not isinstance(child, list):
                raise ConfigError(f"cannot set {key!r}: {path!r} is not an array of tables", file=file, key=TABLE)
            if index >= len(child):
                raise ConfigError(f"cannot set {key!r}: {path!r} has {len(child)} entries", file=file, key=TABLE)
            path += f"[{index}]"
            if depth == len(parts) - 1:
                child[index] = value
                return
            child = child[index]
        node = child


def apply_sweep_point(doc: dict[str, Any], *, file: str | None = None) -> dict[str, Any]:
    """``doc`` with its ``[sweep_point]`` table's values set and the table removed (see the
    module docstring); a document without one is returned as is."""
    point = doc.pop(TABLE, None)
    if point is None:
        return doc
    if not isinstance(point, Mapping):
        raise ConfigError("expected a table of key = value", file=file, key=TABLE)
    for key, value in point.items():
        _set(doc, key, value, file)
    return doc


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")) if not math.isfinite(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a JSON string is a TOML basic string
    if isinstance(v, Mapping):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, Sequence):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise TypeError(f"a sweep value must be a TOML value, found {v!r}")


def sweep_point_toml(point: Sequence[tuple[str, Any]], label: str = "") -> str:
    """The ``[sweep_point]`` table setting ``point`` (appended to a case's text)."""
    head = f"\n# bench campaign sweep point{': ' + label if label else ''}\n[{TABLE}]\n"
    return head + "".join(f"{json.dumps(k)} = {_value(v)}\n" for k, v in point)
