"""The ``sweeps`` section of a campaign's aggregate: each swept parameter as an axis.

For each case (and variant) whose runs were swept (``[[sweep]]``), per swept key, the
points in declaration order (the records carry the declared values, ``sweep_axes``; a
value not declared there comes after them, in the order of its JSON text). With several
swept keys, a point of one key pools the runs at that value over the other keys.

A point's ``x`` is its value as a number when the value is a quantity (``"80 ms"``,
``"0.1 %"``: the number as written, ``unit`` the unit as written, ``x_si`` in SI, parsed
as :func:`bench.units.quantity` parses) or a number; a table value (``{ model = "seed000",
scale_factor_markov = "0.1 %" }``) is numeric by the one field that differs between its
points (``field``). Otherwise the axis is categorical (``numeric`` false, ``x`` None) and
the points are told by their ``label``.

Per point: the runs, their verdicts, the run pass rate with its Clopper-Pearson interval,
and per criterion (display unit) its pass rate with interval, ``median``, ``p10``,
``p90`` (with its order-statistic ``p90_interval``), ``min``, ``max`` and every run's
``values``. Pure function of the records, in the order of their keys.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from bench.campaign.aggregate import criterion_meta, pass_rate, quantile_interval
from bench.units import parse_unit, split_quantity

__all__ = ["sweeps", "parse_x", "axis_of"]


def _text(v: Any) -> str:
    return json.dumps(v, sort_keys=True, ensure_ascii=False)


def label_of(v: Any) -> str:
    """A point's value as shown: a string as written, anything else as JSON."""
    return v if isinstance(v, str) else _text(v)


def parse_x(value: Any) -> tuple[float, str, float] | None:
    """``(number as written, unit as written, SI value)`` of a number or a quantity string
    (``"80 ms"`` -> ``(80.0, "ms", 0.08)``); None when it is neither."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return float(value), "", float(value)
    if not isinstance(value, str):
        return None
    split = split_quantity(value)
    if split is None:
        return None
    number, unit = split
    if not unit:
        return number, "", number
    try:
        scale, _dim = parse_unit(unit)
    except (ValueError, ArithmeticError):
        return None
    return number, unit, number * scale


def axis_of(values: Sequence[Any]) -> dict[str, Any]:
    """How the values of one swept key are drawn: ``numeric``, ``unit`` (as written; "" for
    none, ``"SI"`` when the points are written in different units), ``field`` (the
    varying field of table values), and per value ``x`` / ``x_si`` (None: categorical)."""
    field = None
    items = list(values)
    if items and all(isinstance(v, Mapping) for v in items):
        keys = sorted({k for v in items for k in v})
        varying = [k for k in keys if len({_text(v.get(k)) for v in items}) > 1]
        if len(varying) == 1 and all(varying[0] in v for v in items):
            field = varying[0]
            items = [v[field] for v in items]
    parsed = [parse_x(v) for v in items]
    if not parsed or any(p is None for p in parsed):
        return {"numeric": False, "unit": "", "field": None, "x": [None] * len(values), "x_si": [None] * len(values)}
    units = {p[1] for p in parsed}  # type: ignore[index]
    same = len(units) == 1
    x = [p[0] if same else p[2] for p in parsed]  # type: ignore[index]
    return {"numeric": True, "unit": units.pop() if same else "SI", "field": field, "x": x,
            "x_si": [p[2] for p in parsed]}  # type: ignore[index]


def _point_criterion(entries: Sequence[Mapping[str, Any]], confidence: float) -> dict[str, Any]:
    verdicts = [c["verdict"] for c in entries]
    rate, interval = pass_rate(verdicts, confidence)
    values = sorted(float(c["display"]) for c in entries if c.get("display") is not None)
    out: dict[str, Any] = {"runs": len(entries), "verdicts": {v: verdicts.count(v) for v in sorted(set(verdicts))},
                           "pass_rate": rate, "pass_rate_interval": interval, "values": values}
    if values:
        arr = np.asarray(values)

        def q(p: float) -> float:
            return float(np.quantile(arr, p, method="inverted_cdf"))

        out.update(median=q(0.5), p10=q(0.1), p90=q(0.9), p90_interval=list(quantile_interval(values, 0.9, confidence)),
                   min=values[0], max=values[-1])
    return out


def _ordered(declared: Sequence[Any] | None, seen: Mapping[str, Any]) -> list[Any]:
    """The values seen, in declaration order, then those not declared by their JSON text."""
    order = [_text(v) for v in declared or []]
    first = [t for t in order if t in seen]
    rest = sorted(t for t in seen if t not in order)
    return [seen[t] for t in dict.fromkeys(first + rest)]


def sweeps(records: Sequence[Mapping[str, Any]], confidence: float = 0.95) -> dict[str, Any]:
    """The ``sweeps`` section (see the module docstring) of records sorted by key."""
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for r in records:
        if r.get("sweep"):
            groups.setdefault((r["case_id"], r.get("variant") or ""), []).append(r)
    out: dict[str, Any] = {}
    for (case_id, variant), runs in sorted(groups.items()):
        keys = list(dict.fromkeys(k for r in runs for k, _ in r["sweep"]))
        declared: dict[str, list[Any]] = {}
        for r in runs:
            for k, vals in r.get("sweep_axes") or []:
                declared.setdefault(k, vals)
        per: dict[str, list[tuple[Mapping[str, Any], Mapping[str, Any]]]] = {}
        for r in runs:
            for cid, c in sorted(r.get("criteria", {}).items()):
                per.setdefault(cid, []).append((r, c))
        meta = {cid: criterion_meta(cid, per[cid])[0] for cid in sorted(per)}
        axes = []
        for key in keys:
            at: dict[str, list[Mapping[str, Any]]] = {}
            seen: dict[str, Any] = {}
            for r in runs:
                for k, v in r["sweep"]:
                    if k == key:
                        seen.setdefault(_text(v), v)
                        at.setdefault(_text(v), []).append(r)
            values = _ordered(declared.get(key), seen)
            axis = axis_of(values)
            points = []
            for i, v in enumerate(values):
                prs = at[_text(v)]
                verdicts = [r["verdict"] for r in prs]
                rate, interval = pass_rate(verdicts, confidence)
                crit = {cid: _point_criterion([r["criteria"][cid] for r in prs if cid in r.get("criteria", {})],
                                              confidence) for cid in sorted(per)}
                points.append({"value": v, "label": label_of(v), "x": axis["x"][i], "x_si": axis["x_si"][i],
                               "runs": len(prs), "seeds": sorted(r["seed"] for r in prs),
                               "verdicts": {k: verdicts.count(k) for k in sorted(set(verdicts))},
                               "pass_rate": rate, "pass_rate_interval": interval, "criteria": crit})
            axes.append({"key": key, "numeric": axis["numeric"], "unit": axis["unit"], "field": axis["field"],
                         "pooled": len(keys) > 1, "criteria": meta, "points": points})
        label = case_id + (f"[{variant}]" if variant else "")
        out[label] = {"case_id": case_id, "variant": variant or None, "runs": len(runs), "axes": axes}
    return out
