"""A campaign's aggregate: per-criterion distributions, percentiles, pass rates, worst runs.

Pure functions of the run records, taken in a canonical order (sorted by key), so the
same runs give the same aggregate on any executor and any number of workers.

* percentiles (P50, P90, P95, P99) of each criterion's measured values, each with a
  distribution-free confidence interval from order statistics: the ranks ``l`` and ``u``
  from the binomial(n, p) quantiles, so ``X(l) <= x_p <= X(u)`` with at least the
  confidence asked (a bound is None when n is too small for it);
* the pass rate of each criterion (PASS or MARGINAL among the runs that judged it, N/A
  left out) with its Clopper-Pearson interval (``scipy.stats.beta``);
* the worst runs of each criterion (worst verdict, then farthest value in the direction
  that fails), linked to their recordings;
* per criterion what the campaign report draws it with, from the records: the display
  ``unit``, ``comparator``, ``limit_text``, ``limit`` bounds and ``marginal_band`` in the
  display unit, ``metric``, ``window``, ``requirements`` (a field that differs between
  the records of a group is a bench bug: the first is kept and ``notes`` says so), and the
  distribution of the values in the display unit (``display``);
* ``sweeps``: each swept parameter as an axis (:mod:`bench.campaign.aggregate_sweep`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy import stats

__all__ = [
    "aggregate", "clopper_pearson", "quantile_interval", "distribution", "criterion_meta", "pass_rate", "PERCENTILES",
]

PERCENTILES = (50.0, 90.0, 95.0, 99.0)
_RANK = {"N/A": -1, "PASS": 0, "MARGINAL": 1, "FAIL": 2, "ERROR": 3}


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval of a proportion ``k/n`` (``(0, 1)`` when n is 0)."""
    if n <= 0:
        return 0.0, 1.0
    a = 1.0 - confidence
    low = 0.0 if k <= 0 else float(stats.beta.ppf(a / 2, k, n - k + 1))
    high = 1.0 if k >= n else float(stats.beta.ppf(1 - a / 2, k + 1, n - k))
    return low, high


def quantile_interval(
    sorted_values: Sequence[float], p: float, confidence: float = 0.95
) -> tuple[float | None, float | None]:
    """Order-statistic bounds of the ``p`` quantile (0 < p < 1) of sorted samples: a bound
    that would need a rank outside 1..n is None."""
    n = len(sorted_values)
    if n == 0:
        return None, None
    a = 1.0 - confidence
    dist = stats.binom(n, p)
    lo_rank = int(dist.ppf(a / 2))  # P(B < l) <= a/2, 1-based rank l = ppf
    hi_rank = int(dist.ppf(1 - a / 2)) + 1
    low = sorted_values[lo_rank - 1] if 1 <= lo_rank <= n and dist.cdf(lo_rank - 1) <= a / 2 else None
    high = sorted_values[hi_rank - 1] if 1 <= hi_rank <= n else None
    return low, high


_META = ("unit", "comparator", "limit_text", "limit", "marginal_band", "metric", "window", "requirements")


def distribution(values: Sequence[float], confidence: float = 0.95) -> dict[str, Any]:
    """``min``, ``max``, ``mean``, ``std``, the sorted ``values`` and the ``percentiles``
    P50..P99 with their order-statistic intervals of measured values ({} for none)."""
    values = sorted(values)
    if not values:
        return {}
    arr = np.asarray(values)
    out: dict[str, Any] = {"min": values[0], "max": values[-1], "mean": float(arr.mean()),
                           "std": float(arr.std(ddof=1)) if len(values) > 1 else 0.0, "values": values}
    out["percentiles"] = {
        f"p{p:g}": {"value": float(np.quantile(arr, p / 100.0, method="inverted_cdf")),
                    "interval": list(quantile_interval(values, p / 100.0, confidence))}
        for p in PERCENTILES
    }
    return out


def criterion_meta(cid: str, entries: Sequence[tuple[Mapping[str, Any], Mapping[str, Any]]]
                   ) -> tuple[dict[str, Any], list[str]]:
    """The unit, comparator, limit (text, bounds and marginal band in the display unit),
    metric, window and requirements of a criterion, from its first record that has them;
    a note per field that differs in another record (a bench bug: the first is kept)."""
    meta: dict[str, Any] = {}
    notes: list[str] = []
    for rec, c in entries:
        for k in _META:
            if k not in c:
                continue
            if k not in meta:
                meta[k] = c[k]
            elif c[k] != meta[k] and not any(n.startswith(f"{cid}: {k} ") for n in notes):
                notes.append(f"{cid}: {k} differs between runs ({json.dumps(meta[k])} and "
                             f"{json.dumps(c[k])} in {rec['key'][:16]}); the first is shown")
    return meta, notes


def pass_rate(verdicts: Sequence[str], confidence: float = 0.95) -> tuple[float | None, list[float]]:
    """The share of PASS or MARGINAL among the verdicts that judged (N/A left out; None when
    none did) and its Clopper-Pearson interval."""
    judged = [v for v in verdicts if v != "N/A"]
    passed = sum(v in ("PASS", "MARGINAL") for v in judged)
    return (passed / len(judged) if judged else None), list(clopper_pearson(passed, len(judged), confidence))


def _criterion(cid: str, entries: list[tuple[Mapping[str, Any], Mapping[str, Any]]], worst_n: int,
               confidence: float) -> dict[str, Any]:
    verdicts = [c["verdict"] for _, c in entries]
    rate, interval = pass_rate(verdicts, confidence)
    values = [float(c["value"]) for _, c in entries if c.get("value") is not None]
    meta, notes = criterion_meta(cid, entries)
    out: dict[str, Any] = {
        "runs": len(entries),
        "verdicts": {v: verdicts.count(v) for v in sorted(set(verdicts))},
        "pass_rate": rate,
        "pass_rate_interval": interval,
        "measured": len(values),
        **meta,
        "notes": notes,
    }
    out.update(distribution(values, confidence))
    shown = [float(c["display"]) for _, c in entries if c.get("display") is not None]
    out["display"] = distribution(shown, confidence)
    higher = all(c.get("worse", "higher") == "higher" for _, c in entries)

    def badness(e: tuple[Mapping[str, Any], Mapping[str, Any]]) -> tuple[int, float, str]:
        rec, c = e
        v = c.get("value")
        far = -math.inf if v is None else (float(v) if higher else -float(v))
        return (-_RANK.get(c["verdict"], 0), -far, rec["key"])

    out["worst"] = [
        {"key": rec["key"], "seed": rec["seed"], "variant": rec.get("variant"), "value": c.get("value"),
         "display": c.get("display"), "verdict": c["verdict"], "recording": rec.get("recording"),
         "sweep": rec.get("sweep") or []}
        for rec, c in sorted(entries, key=badness)[:worst_n]
    ]
    return out


def _point(sweep: Any) -> str:
    """``{key=value, ...}`` of a record's sweep point (as :func:`bench.campaign.sweep.point_label`)."""
    if not sweep:
        return ""
    return "{" + ", ".join(f"{k}={json.dumps(v, sort_keys=True, ensure_ascii=False)}" for k, v in sweep) + "}"


def aggregate(records: Iterable[Mapping[str, Any]], worst_n: int = 3, confidence: float = 0.95) -> dict[str, Any]:
    """The aggregate of complete run records (see the module docstring), per case, variant
    and sweep point."""
    recs = sorted(records, key=lambda r: r["key"])
    groups: dict[tuple[str, str, str], list[Mapping[str, Any]]] = {}
    for r in recs:
        groups.setdefault((r["case_id"], r.get("variant") or "", _point(r.get("sweep"))), []).append(r)
    cases: dict[str, Any] = {}
    for (case_id, variant, point), runs in sorted(groups.items()):
        per: dict[str, list[tuple[Mapping[str, Any], Mapping[str, Any]]]] = {}
        for r in runs:
            for cid, c in sorted(r.get("criteria", {}).items()):
                per.setdefault(cid, []).append((r, c))
        run_verdicts = [r["verdict"] for r in runs]
        passed = sum(v in ("PASS", "MARGINAL") for v in run_verdicts)
        label = case_id + (f"[{variant}]" if variant else "") + point
        cases[label] = {
            "case_id": case_id, "variant": variant or None, "sweep": runs[0].get("sweep") or [], "runs": len(runs),
            "seeds": sorted(r["seed"] for r in runs),
            "verdicts": {v: run_verdicts.count(v) for v in sorted(set(run_verdicts))},
            "pass_rate": passed / len(runs),
            "pass_rate_interval": list(clopper_pearson(passed, len(runs), confidence)),
            "criteria": {cid: _criterion(cid, per[cid], worst_n, confidence) for cid in sorted(per)},
        }
    failing = sum(r["verdict"] not in ("PASS", "MARGINAL", "N/A") for r in recs)
    from bench.campaign.aggregate_sweep import sweeps

    return {"runs": len(recs), "failing": failing, "confidence": confidence, "keys": [r["key"] for r in recs],
            "cases": cases, "sweeps": sweeps(recs, confidence)}
