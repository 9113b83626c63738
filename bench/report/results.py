"""Results as JSON: the machine-readable record of an acceptance run.

Layout (``results.json`` of ``bench accept``; ``bench score --json``), described by the
JSON Schema ``bench/report/schemas/results-1.json`` (published as
``models/schemas/results-1.json``; ``docs/results.md``)::

    {"schema": "bench.results.v1", "schema_version": 1, "schema_id": SCHEMA_ID,
     "verdict": "PASS", "counts": {...},
     "identification": {"report_id", "recordings", "cases", "seeds", "recorded_by",
                        "judged_by", "duts", "inputs", "command"},
     "cases": [{"id", "title", "file", "requirements", "verdict", "errors": [...],
                "integrity_waived": [{"check", "criterion", "reason"}],
                "criteria": [{"id", "requirements", "metric", "window", "limit",
                              "unit", "value", "margin", "verdict", "reason",
                              "paper", "variant", "relative_to", "control",
                              "must_fail_on", "monte_carlo",
                              "compare_tolerance", "compare_tolerance_relative",
                              "anees" (the ANEES mode only: runs, dof, band, t_s,
                              anees, ...),
                              "runs": [{"seed", "value", "verdict", "reason"}]}],
                "runs": [{"recording", "variant", "seed", "verdict",
                          "bench_issues", "dut_issues", "notes", "timing", "criteria",
                          "overview", "identity"}]}],
     "run_info": {"started_utc", "generated_utc", "elapsed_s", "paths"},
     "interrupted": {"by", "finished", "unfinished", "not_run"}}   (only when it was)

A suite interrupted (Ctrl-C, SIGTERM) is written with the cases that finished, judged as
usual, the case in progress ERROR ("did not finish", with the runs that had finished) and
the cases not run ERROR ("not run"); ``"interrupted"`` names them and the record's verdict
is ERROR.

A criterion has one entry per variant it judges and one per negative control
(``"control": true``, the variant it had to FAIL on; its verdict is PASS when it did).
Values are in the criterion's display unit (``value_si`` holds SI); an infinite value is
the string ``"inf"``, an unmeasured one ``null``. Times of the run (wall clock) live in
``"run_info"`` only, so two judgements of the same recordings give identical ``cases``.
A run's ``identity`` (:mod:`bench.report.identity`) comes from its recording alone.

:func:`write_json` validates a results record against the schema before writing it
(:func:`validate_results`): a record that does not validate is a bench bug, raised as
:class:`ResultsSchemaError` naming the failing path, and nothing is written.
"""

from __future__ import annotations

import datetime as _dt
import functools
import json
import math
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from bench.acceptance.interrupted import Interruption
from bench.acceptance.judge import CaseResult, CriterionResult, RunResult
from bench.acceptance.verdict import Verdict, worst
from bench.atomic import write_atomic
from bench.errors import BenchError
from bench.report.identity import identification, run_identity

__all__ = [
    "num",
    "criterion_json",
    "run_json",
    "case_json",
    "results_json",
    "write_json",
    "validate_results",
    "schema",
    "schema_errors",
    "ResultsSchemaError",
    "SCHEMA",
    "SCHEMA_VERSION",
    "SCHEMA_ID",
    "SCHEMA_FILE",
]

SCHEMA = "bench.results.v1"
SCHEMA_VERSION = 1
SCHEMA_ID = "urn:nav-hil-bench:schema:results-1"
#: The schema inside the package (``models/schemas/results-1.json`` links to it).
SCHEMA_FILE = "schemas/results-1.json"


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
        "limit_source": c.limit_source,
        "variant": cr.variant,
        "relative_to": c.relative_to,
        "control": cr.control,
        "must_fail_on": list(c.must_fail_on),
        "monte_carlo": c.monte_carlo.text(len(cr.runs)),
        "compare_tolerance": None if c.compare_tolerance is None else num(c.display(c.compare_tolerance)),
        "compare_tolerance_relative": num(c.compare_tolerance_relative),
        "runs": [
            {"seed": r.seed, "value": num(c.display(r.value)), "verdict": str(r.verdict), "reason": r.reason}
            for r in cr.runs
        ],
    } | ({"anees": _clean(a.details)} if a.details else {})


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
            "identity": run_identity(r.recording),
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
            "requirements_waived": [] if cr.case is None else
            [{"requirement": k, "reason": v} for k, v in cr.case.waived.items()],
            "dut": None if cr.case is None else {"kind": cr.case.dut.kind, "name": cr.case.dut.names},
            "requirements_text": [] if cr.case is None else [
                cr.case.requirement_texts[r].to_json() if r in cr.case.requirement_texts
                else {"id": r, "statement": None, "source": None, "citation": ""} for r in cr.requirements],
            "reference": "" if cr.case is None else cr.case.reference,
            "assumed": [] if cr.case is None else list(cr.case.assumed),
            "criteria": [criterion_json(c) for c in cr.criteria],
            "runs": [run_json(r) for r in cr.runs],
        }
    )


def counts(cases: Sequence[CaseResult]) -> dict[str, int]:
    out = {str(v): 0 for v in Verdict}
    for c in cases:
        out[str(c.verdict)] += 1
    return out


def results_json(
    cases: Sequence[CaseResult], run_info: dict[str, Any] | None = None, *, command: str | None = None,
    interrupted: Interruption | None = None,
) -> dict[str, Any]:
    """The results record of ``cases``. ``command`` (or ``run_info["command"]``, moved from
    there) is the command line that reproduces it; ``run_info`` gets ``generated_utc``.
    A suite that was ``interrupted`` is marked so (``"interrupted"``: the signal, the cases
    that finished, did not finish and were not run) and its verdict is ERROR whatever its
    cases say: an incomplete suite is never a PASS."""
    info = dict(run_info or {})
    command = command if command is not None else info.pop("command", None)
    info.pop("command", None)
    info.setdefault("generated_utc", _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"))
    case_docs = [case_json(c) for c in cases]
    verdict = worst(c.verdict for c in cases) if cases and interrupted is None else Verdict.ERROR
    return {
        "schema": SCHEMA,
        "schema_version": SCHEMA_VERSION,
        "schema_id": SCHEMA_ID,
        "verdict": str(verdict),
        "counts": counts(cases),
        "identification": identification(case_docs, None if command is None else str(command)),
        "cases": case_docs,
        "run_info": _clean(info),
        **({"interrupted": interrupted.to_json()} if interrupted is not None else {}),
    }


class ResultsSchemaError(BenchError):
    """A results record does not match its schema: a bench bug (never written)."""


@functools.cache
def schema() -> dict[str, Any]:
    """The results record's JSON Schema (package data)."""
    return json.loads(resources.files("bench.report").joinpath(SCHEMA_FILE).read_text(encoding="utf-8"))


@functools.cache
def _validator() -> Any:
    from jsonschema import Draft202012Validator

    Draft202012Validator.check_schema(schema())
    return Draft202012Validator(schema())


def _path(parts: Sequence[Any]) -> str:
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(the record)"


def schema_errors(obj: Any, limit: int = 5) -> list[str]:
    """``path: message`` of the first ``limit`` schema violations of ``obj`` (none: [])."""
    from jsonschema.exceptions import best_match

    found = []
    for err in sorted(_validator().iter_errors(obj), key=lambda e: [str(p) for p in e.absolute_path]):
        if err.context and all(not c.relative_path for c in err.context):  # alternatives for this value
            why = " / ".join(dict.fromkeys(c.message for c in err.context))
            found.append(f"{_path(list(err.absolute_path))}: {why}")
            continue
        best = best_match([err]) if err.context else err
        found.append(f"{_path(list(best.absolute_path))}: {best.message}")
        if len(found) >= limit:
            break
    return found


def validate_results(obj: Any) -> None:
    """Raise :class:`ResultsSchemaError` naming the failing path(s) when ``obj`` is not
    a valid results record (``cases[2].criteria[4].value: 'abc' is not valid...``)."""
    errors = schema_errors(obj)
    if errors:
        raise ResultsSchemaError(f"the results record does not match its schema {SCHEMA_ID}: " + "; ".join(errors))


def write_json(obj: Any, path: str | Path) -> Path:
    """Write ``obj`` as strict JSON (a results record is validated first, as written),
    whole or not at all (:mod:`bench.atomic`)."""
    text = json.dumps(obj, indent=1, allow_nan=False) + "\n"
    if isinstance(obj, dict) and obj.get("schema") == SCHEMA:
        validate_results(json.loads(text))
    return write_atomic(path, text)
