"""What the certification report shows, computed from a results record alone.

:func:`report_model` turns a results record (``results.json``, :mod:`bench.report.results`)
into the plain data the templates render: the identification, the summary and counts,
the requirement coverage matrix, and per case its criteria rows and runs. Every number is
the record's, formatted by :func:`fmt_num`; the exact value travels beside it (``raw``)
so a test, or a reviewer with the record, can check that the report shows the record and
nothing else. No third-party library here.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from bench.acceptance.verdict import Verdict

__all__ = ["fmt_num", "report_model", "coverage", "VERDICT_ORDER"]

#: Verdicts from best to worst, N/A first (the worst of several is the one shown; see
#: :mod:`bench.acceptance.verdict`).
VERDICT_ORDER = tuple(str(v) for v in sorted(Verdict, key=lambda v: v.rank))


def fmt_num(v: Any, digits: int = 4) -> str:
    """A record value for display: ``digits`` significant digits, ``inf`` as ∞, an
    unmeasured value (null) as an em dash. Integers stay integers."""
    if v is None:
        return "—"
    if isinstance(v, str):
        return {"inf": "∞", "-inf": "−∞"}.get(v, v)
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "—"
        if v == 0.0:
            return "0"
        text = f"{v:.{digits}g}"
        return text.replace("-", "−") if text.startswith("-") else text
    return str(v)


def _worst(verdicts: Sequence[str]) -> str:
    known = [v for v in verdicts if v in VERDICT_ORDER]
    return max(known, key=VERDICT_ORDER.index) if known else "ERROR"


def coverage(cases: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The requirement coverage matrix: per requirement (sorted), the cases that name or
    judge it with the worst verdict of its criteria there; ``judged`` False (a gap a
    reviewer must see) when a case names the requirement but no criterion judged it (a
    criterion that did not apply, N/A, judges nothing) and does not waive it; a case that
    waives it (``[case] waived``) is listed with its reason (``waived``)."""
    rows: dict[str, dict[str, Any]] = {}
    for case in cases:
        waived = {w.get("requirement"): w.get("reason", "") for w in case.get("requirements_waived", [])}
        judged: dict[str, list[str]] = {}
        for cr in case.get("criteria", []):
            if cr.get("verdict") == str(Verdict.NA):  # did not apply: judged nothing
                continue
            for req in cr.get("requirements", []):
                judged.setdefault(req, []).append(cr.get("verdict", "ERROR"))
        for req in dict.fromkeys([*case.get("requirements", []), *judged]):
            row = rows.setdefault(req, {"requirement": req, "cases": [], "judged": True})
            verdicts = judged.get(req, [])
            entry = {"case": case.get("id", "?"), "verdict": _worst(verdicts) if verdicts else None,
                     "criteria": len(verdicts), "waived": waived.get(req) if not verdicts else None}
            row["cases"].append(entry)
            if not verdicts and req not in waived:
                row["judged"] = False
    for case in cases:
        for r in case.get("requirements_text", []):
            row = rows.get(r.get("id")) if isinstance(r, Mapping) else None
            if row is not None and r.get("statement") and not row.get("statement"):
                row.update(statement=r["statement"], source=r.get("source") or "", citation=r.get("citation") or "")
    for row in rows.values():
        row.setdefault("statement", "")
        row.setdefault("source", "")
        row.setdefault("citation", "")
        verdicts = [c["verdict"] for c in row["cases"] if c["verdict"] is not None]
        if verdicts and row["judged"]:
            row["verdict"] = _worst(verdicts)
        else:
            row["verdict"] = "WAIVED" if row["judged"] else "NOT JUDGED"
    return [rows[k] for k in sorted(rows)]


#: The verdict kinds a headline counts, in its order (a requirement may also be NOT JUDGED
#: or WAIVED); a kind outside these is counted under its own name after them.
COUNTED = ("PASS", "MARGINAL", "FAIL", "ERROR", "N/A", "NOT JUDGED", "WAIVED")


def verdict_counts(verdicts: Iterable[str]) -> dict[str, int]:
    """How many of each verdict kind (every kind of :data:`COUNTED` present, zeros
    included for PASS to N/A, so a headline never leaves a kind out): ``{"PASS": 364,
    "MARGINAL": 0, ..., "N/A": 5}``; ``total`` is not a key (sum the values)."""
    out = {k: 0 for k in COUNTED[:5]}
    for v in verdicts:
        out[str(v)] = out.get(str(v), 0) + 1
    return out


def not_pass(cases: Sequence[Mapping[str, Any]], cover: Sequence[Mapping[str, Any]]) -> list[dict[str, str]]:
    """Everything a reviewer must see first, worst first: cases that could not be
    judged (their errors), criteria whose verdict is not PASS (N/A included: a criterion
    that judged nothing), requirements named and never judged. Rows: ``what`` (case,
    criterion, requirement), ``case``, ``id``, ``variant``, ``verdict``, ``detail``."""
    rank = {"ERROR": 0, "FAIL": 1, "NOT JUDGED": 2, "MARGINAL": 3, "N/A": 4}
    rows: list[dict[str, str]] = []
    for c in cases:
        for e in c.get("errors", []):
            rows.append({"what": "case", "case": c["id"], "id": c["id"], "variant": "", "verdict": c["verdict"],
                         "detail": str(e)})
        for r in c.get("criteria", []):
            if r["verdict"] != "PASS":
                shown = f"{r['value']} {r['unit']}".strip() if r.get("value_raw") is not None else ""
                limit = f"limit {r['limit']}" if r.get("limit") else ""
                detail = "; ".join(x for x in (shown and f"value {shown}", limit, r.get("reason", "")) if x)
                rows.append({"what": "criterion", "case": c["id"], "id": r["id"], "variant": r["variant"],
                             "verdict": r["verdict"], "detail": detail})
    for req in cover:
        if req["verdict"] == "NOT JUDGED":
            where = ", ".join(e["case"] for e in req["cases"] if e["verdict"] is None and not e["waived"])
            rows.append({"what": "requirement", "case": where, "id": req["requirement"], "variant": "",
                         "verdict": "NOT JUDGED", "detail": "named by the case, judged by none of its criteria"})
    return sorted(rows, key=lambda r: rank.get(r["verdict"], 5))


#: The id prefix of the default output-integrity criteria (bench.acceptance.integrity_criteria).
INTEGRITY_PREFIX = "INTEGRITY-"

#: Units shown in words where the catalogue's unit is a bare number.
UNIT_WORDS = {"1": "count", "": ""}


def integrity_summary(criteria: Sequence[Mapping[str, Any]]) -> dict[str, Any] | None:
    """The default integrity criteria of a case in one line when every one PASSes: per
    check (in order) its worst value over the variants and seeds with its unit; None when
    the case has none. A check that is not PASS stays in the criteria table (``shown``)."""
    rows = [c for c in criteria if str(c.get("id", "")).startswith(INTEGRITY_PREFIX)]
    if not rows:
        return None
    checks: dict[str, dict[str, Any]] = {}
    for c in rows:
        name = str(c["id"])[len(INTEGRITY_PREFIX):]
        entry = checks.setdefault(name, {"check": name, "values": [], "unit": _unit_word(c.get("unit", "")),
                                         "limit": c.get("limit", "")})
        for v in [c.get("value"), *[r.get("value") for r in c.get("runs", [])]]:
            if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v):
                entry["values"].append(float(v))
    passed = all(c.get("verdict") == "PASS" for c in rows)
    return {"n": len(rows), "checks": len(checks), "all_pass": passed,
            "line": ", ".join(f"{e['check']} {fmt_num(max(e['values'])) if e['values'] else '—'}"
                              f"{' ' + e['unit'] if e['unit'] and e['unit'] != 'count' else ''}"
                              for e in checks.values())}


def _unit_word(unit: Any) -> str:
    u = str(unit or "")
    return UNIT_WORDS.get(u, u)


def _shown(cr: Mapping[str, Any], runs: Sequence[Mapping[str, Any]], integrity_pass: bool) -> bool:
    """Whether a criterion has its own row: every criterion but the integrity checks of
    a case whose integrity checks all PASS (summarised in one line)."""
    return not (integrity_pass and str(cr.get("id", "")).startswith(INTEGRITY_PREFIX))


def _criterion_row(cr: Mapping[str, Any]) -> dict[str, Any]:
    seeds = cr.get("runs", [])
    return {
        "id": cr.get("id", "?"),
        "variant": cr.get("variant") or "",
        "control": bool(cr.get("control")),
        "requirements": ", ".join(cr.get("requirements", [])),
        "metric": cr.get("metric", ""),
        "window": cr.get("window_text") or cr.get("window") or "",
        "value": fmt_num(cr.get("value")),
        "value_raw": cr.get("value"),
        "unit": _unit_word(cr.get("unit", "")),
        "limit": cr.get("limit", ""),
        "margin": fmt_num(cr.get("margin")),
        "margin_raw": cr.get("margin"),
        "verdict": cr.get("verdict", "ERROR"),
        "reason": cr.get("reason", ""),
        "paper": cr.get("paper") or "",
        "limit_source": cr.get("limit_source") or "",
        "relative_to": cr.get("relative_to") or "",
        "must_fail_on": ", ".join(cr.get("must_fail_on", [])),
        "monte_carlo": cr.get("monte_carlo", ""),
        # per-seed values only where they tell something: a criterion judged over the runs
        # (a Monte Carlo statistic) or one whose runs are not all PASS
        "seeds": [{"seed": r.get("seed"), "value": fmt_num(r.get("value")), "value_raw": r.get("value"),
                   "verdict": r.get("verdict", "")} for r in seeds]
        if len(seeds) > 1 and ((cr.get("monte_carlo") or "every run") != "every run"
                               or any(r.get("verdict") != "PASS" for r in seeds)) else [],
    }


def _run_row(run: Mapping[str, Any]) -> dict[str, Any]:
    ident = run.get("identity") or {}
    return {
        "recording": run.get("recording", ""),
        "variant": run.get("variant") or "",
        "seed": run.get("seed"),
        "verdict": run.get("verdict", "ERROR"),
        "sha256": (ident.get("recording") or {}).get("sha256", ""),
        "bench_issues": list(run.get("bench_issues") or []),
        "dut_issues": list(run.get("dut_issues") or []),
        "notes": list(run.get("notes") or []),
        "timing": run.get("timing") or {},
        "identity": ident,
    }


def report_model(results: Mapping[str, Any], *, title: str = "Acceptance report") -> dict[str, Any]:
    """The report's content from a results record (see the module docstring)."""
    cases = list(results.get("cases", []))
    ident = dict(results.get("identification") or {})
    run_info = dict(results.get("run_info") or {})
    model_cases = []
    for case in cases:
        dut = case.get("dut") or {}
        model_cases.append({
            "id": case.get("id", "?"),
            "title": case.get("title", ""),
            "file": case.get("file", ""),
            "verdict": case.get("verdict", "ERROR"),
            "requirements": list(case.get("requirements", [])),
            "dut": {"kind": dut.get("kind", ""), "name": dut.get("name") or ""},
            "errors": list(case.get("errors", [])),
            "waived": list(case.get("integrity_waived", [])),
            "requirements_waived": list(case.get("requirements_waived", [])),
            "requirements_text": [dict(r) for r in case.get("requirements_text", []) if isinstance(r, Mapping)],
            "reference": str(case.get("reference") or ""),
            "assumed": [str(a) for a in case.get("assumed", [])],
            "criteria": [_criterion_row(c) for c in case.get("criteria", [])],
            "integrity": integrity_summary(case.get("criteria", [])),
            "runs": [_run_row(r) for r in case.get("runs", [])],
            "figures": [],
        })
    seeds = sorted({r["seed"] for c in model_cases for r in c["runs"] if isinstance(r["seed"], int)})
    cover = coverage(cases)
    return {
        "title": title,
        "schema": results.get("schema", ""),
        "verdict": results.get("verdict", "ERROR"),
        "counts": dict(results.get("counts", {})),
        "n_criteria": sum(len(c["criteria"]) for c in model_cases),
        "case_counts": verdict_counts(c["verdict"] for c in model_cases),
        "criterion_counts": verdict_counts(r["verdict"] for c in model_cases for r in c["criteria"]),
        "requirement_counts": verdict_counts(r["verdict"] for r in cover),
        "not_pass": not_pass(model_cases, cover),
        "identification": ident,
        "run_info": run_info,
        "seeds": seeds,
        "coverage": cover,
        "cases": model_cases,
        "interrupted": _interrupted(results.get("interrupted")),
    }


def _interrupted(block: Any) -> dict[str, Any] | None:
    """The record's ``interrupted`` block for the report's banner (None: the suite finished)."""
    if not isinstance(block, Mapping):
        return None
    return {"by": str(block.get("by") or "an interrupt"),
            **{k: [str(x) for x in block.get(k) or []] for k in ("finished", "unfinished", "not_run")}}
