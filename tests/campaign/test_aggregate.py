"""The campaign aggregate: exact binomial intervals, order-statistic bounds, canonical order."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bench.campaign.aggregate import aggregate, clopper_pearson, quantile_interval
from bench.campaign.plan import plan_campaign


def test_clopper_pearson_edges_and_coverage():
    assert clopper_pearson(0, 0) == (0.0, 1.0)
    low, high = clopper_pearson(0, 4)
    assert low == 0.0 and high == pytest.approx(1 - 0.025 ** 0.25)
    low, high = clopper_pearson(4, 4)
    assert high == 1.0 and low == pytest.approx(0.025 ** 0.25)
    low, high = clopper_pearson(7, 20)
    # the defining tail equations of the exact interval
    assert stats.binom.sf(6, 20, low) == pytest.approx(0.025)
    assert stats.binom.cdf(7, 20, high) == pytest.approx(0.025)


def test_quantile_interval_covers_the_median_at_least_as_asked():
    rng = np.random.default_rng(18)
    n, hits, trials = 30, 0, 2000
    for _ in range(trials):
        x = np.sort(rng.standard_normal(n))
        lo, hi = quantile_interval(list(x), 0.5)
        hits += lo is not None and hi is not None and lo <= 0.0 <= hi
    assert hits / trials >= 0.93
    assert quantile_interval([1.0, 2.0, 3.0], 0.99) == (2.0, None)  # too few runs for an upper bound of P99
    assert quantile_interval([], 0.5) == (None, None)


def _record(key: str, seed: int, value: float | None, verdict: str) -> dict:
    return {"key": key, "case_id": "C", "variant": None, "seed": seed, "verdict": verdict,
            "recording": f"recordings/C/{key}.mcap",
            "criteria": {"E": {"value": value, "verdict": verdict, "reason": "", "worse": "higher"}}}


def test_aggregate_is_independent_of_the_order_of_the_records():
    rng = np.random.default_rng(5)
    recs = [_record(f"{i:04x}", i, float(v), "PASS" if v < 1.5 else "FAIL")
            for i, v in enumerate(rng.exponential(1.0, 25))]
    recs.append(_record("ffff", 99, None, "ERROR"))
    first = aggregate(recs)
    shuffled = [recs[i] for i in rng.permutation(len(recs))]
    assert aggregate(shuffled) == first
    crit = first["cases"]["C"]["criteria"]["E"]
    fails = sum(r["verdict"] != "PASS" for r in recs)
    assert crit["verdicts"]["ERROR"] == 1 and first["failing"] == fails
    assert crit["worst"][0]["key"] == "ffff"  # ERROR first, then the largest failing values
    assert crit["worst"][1]["value"] == max(r["criteria"]["E"]["value"] or 0 for r in recs)
    assert crit["pass_rate"] == pytest.approx((26 - fails) / 26)


def test_the_run_key_follows_the_content_of_the_case_and_its_scenario(tmp_path):
    from pathlib import Path

    src = Path(__file__).parent
    for name in ("case.toml", "drive.toml"):
        (tmp_path / name).write_bytes((src / name).read_bytes())
    keys = [r.key for r in plan_campaign([tmp_path / "case.toml"], runs=3)]
    assert len(set(keys)) == 3 and keys == sorted(keys)
    assert [r.key for r in plan_campaign([tmp_path / "case.toml"], runs=3)] == keys
    drive = tmp_path / "drive.toml"
    drive.write_text(drive.read_text().replace('duration = "15 s"', 'duration = "14 s"'))
    assert not set(keys) & {r.key for r in plan_campaign([tmp_path / "case.toml"], runs=3)}
