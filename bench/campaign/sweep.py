"""Parameter sweeps declared in a case: ``[[sweep]]`` tables, expanded by ``bench campaign``.

::

    [[sweep]]
    key = "dut.synthetic.latency"      # a dotted path into the case's tables
    values = ["2 ms", "4 ms", "8 ms"]  # each replaces the value at key, as written in TOML

Several ``[[sweep]]`` tables sweep their cartesian product. Each point is the case with
those values set (then checked as any case is), run for every variant and seed; its runs
have their own keys and their own group in the aggregate (``CASE{key=value}``). A key
reaches into arrays of tables by index (``criterion[0].at_most``) and into a sensor named
by its set (``sensors.doppler.scale_factor_markov``); the case is the file's text with a
``[sweep_point]`` table appended (:mod:`bench.acceptance.sweep_point`), which is what its
recordings carry. ``bench accept`` ignores ``[[sweep]]``: it runs the case as written.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

from bench.acceptance.case import TestCase, load_case, parse_case
from bench.acceptance.sweep_point import TABLE, check_key, sweep_point_toml
from bench.config.files import read_text, read_toml
from bench.errors import ConfigError

__all__ = ["SweepPoint", "sweep_points", "case_at", "point_label"]

#: One point: (dotted key, value) pairs in declaration order (hashable, picklable).
SweepPoint = tuple[tuple[str, Any], ...]


def _doc(path: Path) -> dict[str, Any]:
    return read_toml(path, what="test case file")  # bounded, nested <= 64 levels, every number finite


def sweep_points(path: str | Path) -> list[SweepPoint]:
    """The points of the case file's sweeps (``[()]`` without ``[[sweep]]``)."""
    sweeps = _doc(Path(path)).get("sweep", [])
    if not isinstance(sweeps, list):
        raise ConfigError("expected [[sweep]] tables", file=str(path), key="sweep")
    axes: list[list[tuple[str, Any]]] = []
    for i, s in enumerate(sweeps):
        where = f"sweep[{i}]"
        if not isinstance(s, dict) or set(s) != {"key", "values"}:
            raise ConfigError("expected exactly 'key' and 'values'", file=str(path), key=where)
        key, values = s["key"], s["values"]
        check_key(key, file=str(path), where=f"{where}.key")
        if not isinstance(values, list) or not values:
            raise ConfigError("expected a non-empty array of values", file=str(path), key=f"{where}.values")
        axes.append([(key, v) for v in values])
    return [tuple(p) for p in itertools.product(*axes)]


def point_label(point: SweepPoint) -> str:
    """``{key=value, ...}`` (empty for no sweep)."""
    if not point:
        return ""
    return "{" + ", ".join(f"{k}={json.dumps(v, sort_keys=True, ensure_ascii=False)}" for k, v in point) + "}"


def case_at(path: str | Path, point: SweepPoint) -> TestCase:
    """The case of ``path`` at the sweep ``point``, checked as a case file is: its text with
    a ``[sweep_point]`` table appended (:mod:`bench.acceptance.sweep_point`), so the case a
    run's recording carries is the swept one."""
    p = Path(path)
    if not point:
        return load_case(p)
    text = read_text(p, what="test case file")
    if TABLE in _doc(p):
        raise ConfigError(f"a case with [[sweep]] cannot also set [{TABLE}]", file=str(p), key=TABLE)
    return parse_case(text.rstrip("\n") + "\n" + sweep_point_toml(point, point_label(point)), file=str(p),
                      base=p.resolve().parent, check_files=True, path=p)
