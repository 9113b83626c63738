"""Results as JSON: the machine-readable record of an acceptance run.

Layout (``results.json`` of ``bench accept``; ``bench score --json``)::

    {"schema": "bench.results.v1", "verdict": "PASS", "counts": {...},
     "cases": [{"id", "title", "file", "requirements", "verdict", "errors": [...],
                "integrity_waived": [{"check", "criterion", "reason"}],
                "criteria": [{"id", "requirements", "metric", "window", "limit",
                              "unit", "value", "margin", "verdict", "reason",
                              "paper", "variant", "relative_to", "control",
                              "must_fail_on", "monte_carlo",
                              "compare_tolerance", "compare_tolerance_relative",
                              "runs": [{"seed", "value", "verdict", "reason"}]}],
                "runs": [{"recording", "variant", "seed", "verdict",
                          "bench_issues", "dut_issues", "notes", "timing", "overview"}]}]}

A criterion has one entry per variant it judges and one per negative control
(``"control": true``, the variant it had to FAIL on; its verdict is PASS when it did).
Values are in the criterion's display unit (``value_si`` holds SI); an infinite value is
the string ``"inf"``, an unmeasured one ``null``. Times of the run (wall clock) live in
``"run_info"`` only, so two judgements of the same recordings give identical ``cases``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench.acceptance.judge import CaseResult, CriterionResult, RunResult
from bench.acceptance.verdict import Verdict, worst

__all__ = ["num", "criterion_json", "run_json", "case_json", "results_json", "write_json", "SCHEMA"]

SCHEMA = "bench.results.v1"


def num(x: float | None) -> float | str | None:
    """A float for JSON: finite as is, infinities as strings, NaN as null."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return None
    if isinstance(x, float) and math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return float(x)


def _clean(obj: Any) -> Any:
    if isinstance(obj, float):
        return num(obj)
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalars
        return _clean(obj.item())
    return obj


def criterion_json(cr: CriterionResult) -> dict[str, Any]:
    c = cr.criterion
    a = cr.aggregate
    return {
        "id": c.id,
        "requirements": list(c.requirements),
        "metric": c.metric,
        "description": c.description,
        "window": c.window.name,
        "window_text": c.window.describe(),
        "limit": c.limit.text(c.unit),
        "comparator": c.limit.comparator,
        "limit_si": {"low": num(c.limit.low), "high": num(c.limit.high)},
        "unit": c.unit,
        "marginal_band": num(c.display(c.band())) if c.band() else None,
        "value": num(c.display(a.value)),
        "value_si": num(a.value),
        "margin": num(c.display(a.margin)) if not math.isnan(a.margin) else None,
        "verdict": str(a.verdict),
        "reason": a.reason,
        "paper": c.paper,
        "variant": cr.variant,
        "relative_to": c.relative_to,
        "control": cr.control,
        "must_fail_on": list(c.must_fail_on),
        "monte_carlo": c.monte_carlo.text(),
        "compare_tolerance": None if c.compare_tolerance is None else num(c.display(c.compare_tolerance)),
        "compare_tolerance_relative": num(c.compare_tolerance_relative),
        "runs": [
            {"seed": r.seed, "value": num(c.display(r.value)), "verdict": str(r.verdict), "reason": r.reason}
            for r in cr.runs
        ],
    }


def run_json(r: RunResult) -> dict[str, Any]:
    return _clean(
        {
            "recording": Path(r.recording).name,
            "variant": r.variant,
            "seed": r.seed,
            "verdict": str(r.verdict),
            "bench_issues": r.bench_issues,
            "dut_issues": r.dut_issues,
            "notes": r.notes,
            "timing": r.timing,
            "criteria": {
                k: {"value_si": v.value, "verdict": str(v.verdict), "reason": v.reason, "details": v.details}
                for k, v in {**r.values, **r.raw}.items()
            },
            "overview": r.overview,
        }
    )


def case_json(cr: CaseResult) -> dict[str, Any]:
    return _clean(
        {
            "id": cr.case_id,
            "title": cr.title,
            "file": cr.file,
            "requirements": list(cr.requirements),
            "verdict": str(cr.verdict),
            "errors": cr.errors,
            "integrity_waived": cr.waived,
            "dut": None if cr.case is None else {"kind": cr.case.dut.kind, "name": cr.case.dut.name},
            "criteria": [criterion_json(c) for c in cr.criteria],
            "runs": [run_json(r) for r in cr.runs],
        }
    )


def counts(cases: Sequence[CaseResult]) -> dict[str, int]:
    out = {str(v): 0 for v in Verdict}
    for c in cases:
        out[str(c.verdict)] += 1
    return out


def results_json(cases: Sequence[CaseResult], run_info: dict[str, Any] | None = None) -> dict[str, Any]:
    return {
        "schema": SCHEMA,
        "verdict": str(worst(c.verdict for c in cases)) if cases else str(Verdict.ERROR),
        "counts": counts(cases),
        "cases": [case_json(c) for c in cases],
        "run_info": _clean(run_info or {}),
    }


def write_json(obj: Any, path: str | Path) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(obj, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return p
