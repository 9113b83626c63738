"""The aggregate's per-criterion display fields and its ``sweeps`` section, from hand-made records."""

from __future__ import annotations

import pytest

from bench.campaign.aggregate import aggregate
from bench.campaign.aggregate_sweep import axis_of, parse_x

LIMIT = {"unit": "ms", "comparator": "at_most", "limit_text": "<= 50 ms", "limit": {"low": None, "high": 50.0},
         "marginal_band": 5.0, "metric": "output.latency_max", "window": "all", "requirements": ["R1"]}


def rec(key: str, seed: int, point: list, value_ms: float, axes: list | None = None, **over) -> dict:
    verdict = "PASS" if value_ms <= 50.0 else "FAIL"
    crit = {"value": value_ms / 1e3, "display": value_ms, "verdict": verdict, "reason": "", "worse": "higher",
            **LIMIT, **over}
    return {"version": 2, "key": key, "case_id": "S001", "variant": None, "seed": seed, "verdict": verdict,
            "sweep": point, "sweep_axes": axes, "recording": f"recordings/S001/{key}.mcap", "criteria": {"LAT": crit}}


def test_parse_of_sweep_values():
    assert parse_x("0.1 %") == pytest.approx((0.1, "%", 0.001))
    assert parse_x("80 ms") == pytest.approx((80.0, "ms", 0.08))
    assert parse_x(3) == (3.0, "", 3.0)
    assert parse_x("seed001_driving") is None and parse_x(True) is None
    axis = axis_of(["80 ms", "20 ms", "0.2 s"])
    assert axis["numeric"] and axis["unit"] == "SI" and axis["x"] == pytest.approx([0.08, 0.02, 0.2])
    axis = axis_of([{"model": "seed000", "scale_factor_markov": "0.05 %"},
                    {"model": "seed000", "scale_factor_markov": "0.2 %"}])
    assert axis["numeric"] and axis["field"] == "scale_factor_markov" and axis["unit"] == "%"
    assert axis["x"] == pytest.approx([0.05, 0.2])
    cat = axis_of(["open", "urban"])
    assert not cat["numeric"] and cat["x"] == [None, None]


def test_the_sweeps_section_in_declaration_order_with_pass_rates_and_medians():
    key = "sensors.bds.latency"
    axes = [[key, ["80 ms", "20 ms", "150 ms"]]]  # declared out of numeric order
    values = {"20 ms": [10.0, 12.0, 30.0], "80 ms": [40.0, 60.0, 45.0], "150 ms": [70.0, 90.0, 80.0]}
    recs = [rec(f"{x}{i}", i, [[key, x]], v, axes) for x, vs in values.items() for i, v in enumerate(vs)]
    agg = aggregate(recs)
    sw = agg["sweeps"]["S001"]
    (axis,) = sw["axes"]
    assert axis["key"] == key and axis["numeric"] and axis["unit"] == "ms"
    assert [p["label"] for p in axis["points"]] == ["80 ms", "20 ms", "150 ms"]
    assert [p["x"] for p in axis["points"]] == [80.0, 20.0, 150.0]
    assert [p["x_si"] for p in axis["points"]] == pytest.approx([0.08, 0.02, 0.15])
    assert [p["pass_rate"] for p in axis["points"]] == pytest.approx([2 / 3, 1.0, 0.0])
    lat = [p["criteria"]["LAT"] for p in axis["points"]]
    assert [c["median"] for c in lat] == [45.0, 12.0, 80.0]
    assert [(c["min"], c["max"]) for c in lat] == [(40.0, 60.0), (10.0, 30.0), (70.0, 90.0)]
    assert lat[1]["pass_rate"] == 1.0 and lat[1]["pass_rate_interval"][1] == 1.0
    assert axis["criteria"]["LAT"]["limit"]["high"] == 50.0 and axis["criteria"]["LAT"]["unit"] == "ms"
    group = agg["cases"]['S001{sensors.bds.latency="20 ms"}']["criteria"]["LAT"]
    assert group["unit"] == "ms" and group["limit_text"] == "<= 50 ms" and group["marginal_band"] == 5.0
    assert group["display"]["values"] == [10.0, 12.0, 30.0] and group["notes"] == []
    assert aggregate(list(reversed(recs))) == agg  # canonical


def test_a_categorical_sweep_and_a_limit_that_differs_is_noted():
    key = "scenario.defaults.gnss"
    recs = [rec("a", 1, [[key, "urban"]], 10.0), rec("b", 2, [[key, "open"]], 60.0),
            rec("c", 3, [[key, "open"]], 20.0, limit={"low": None, "high": 40.0})]
    agg = aggregate(recs)
    (axis,) = agg["sweeps"]["S001"]["axes"]
    assert not axis["numeric"] and [p["label"] for p in axis["points"]] == ["open", "urban"]  # undeclared: by text
    assert [p["x"] for p in axis["points"]] == [None, None]
    assert axis["points"][0]["pass_rate"] == 0.5
    crit = agg["cases"]['S001{scenario.defaults.gnss="open"}']["criteria"]["LAT"]
    assert crit["limit"]["high"] == 50.0 and len(crit["notes"]) == 1 and "limit differs" in crit["notes"][0]
    assert aggregate([r for r in recs if r["key"] == "a"] + [rec("n", 4, [], 1.0)])["sweeps"]["S001"]["runs"] == 1
