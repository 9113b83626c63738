"""Two results records side by side: what ``bench compare A B`` judges.

A and B are results records (``results.json`` of ``bench accept``, ``bench score --json``;
layout in :mod:`bench.report.results`). Criteria are matched by (case id, criterion id,
variant, control); for each match the values of A and B (in the criterion's display unit),
their delta ``B - A`` and relative delta, and a status:

* REGRESSION -- B is worse than A by more than the tolerance; *worse* follows the
  comparator: a larger value for ``at_most``, a smaller one for ``at_least``, a larger
  ``|x|`` for ``within``, farther from the band's centre for ``in_range``. A value A
  measured and B not (``null``) is a regression; between an infinite and a finite value
  the change is beyond any tolerance;
* IMPROVEMENT -- better by more than the tolerance (or measured in B only);
* SAME -- within the tolerance (a change equal to it is SAME);
* CHANGED -- a negative control's value moved beyond the tolerance: a control is the DUT
  with something switched off, its value has no better or worse (its verdict does);
* MISSING -- in A only: a regression; NEW -- in B only: noted.

Independently, a verdict change to a worse verdict (PASS -> MARGINAL -> FAIL -> ERROR) is
a regression whatever the tolerance; changes to or from N/A are listed, not judged.
Cases are matched by id the same way (a case missing in B is a regression).

Tolerances, in order: the command line (:class:`Tolerance` per criterion id), the case's
``compare_tolerance``/``compare_tolerance_relative`` (B's record, else A's), else the
default: ``rel_tol`` of ``|A|``, at least ``floor`` times the limit's magnitude. With an
absolute and a relative part the larger applies. Unknown fields of a record are ignored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from bench.acceptance.verdict import Verdict
from bench.errors import ConfigError
from bench.report.compare_record import Key, Record, load_record, value_of
from bench.units import to_unit

__all__ = [
    "SCHEMA",
    "DEFAULT_REL_TOL",
    "DEFAULT_FLOOR",
    "Record",  # with load_record, from bench.report.compare_record
    "Tolerance",
    "Row",
    "CaseRow",
    "Comparison",
    "load_record",
    "badness",
    "value_status",
    "verdict_change",
    "compare",
]


SCHEMA = "bench.compare.v1"
DEFAULT_REL_TOL = 0.05
DEFAULT_FLOOR = 0.01
REGRESSION, IMPROVEMENT, SAME, CHANGED, MISSING, NEW = "REGRESSION", "IMPROVEMENT", "SAME", "CHANGED", "MISSING", "NEW"

# -- direction and tolerance ---------------------------------------------------------------
def _limits(c: dict[str, Any]) -> tuple[float | None, float | None]:
    """The limit's low and high in the criterion's display unit."""
    lim, unit = c["limit_si"], c["unit"]
    out = []
    for s in ("low", "high"):
        x = value_of(lim.get(s))
        out.append(None if x is None else float(to_unit(x, unit)) if math.isfinite(x) else x)
    return out[0], out[1]


def badness(value: float, comparator: str, low: float | None, high: float | None) -> float:
    """How bad ``value`` is under ``comparator``: larger is worse (the value for
    ``at_most``, its negative for ``at_least``, ``|x|`` for ``within``, the distance from
    the band's centre for ``in_range``)."""
    if comparator == "at_most":
        return value
    if comparator == "at_least":
        return -value
    if comparator == "within":
        return abs(value)
    if low is None or high is None:
        raise ValueError(f"in_range needs both bounds, found [{low}, {high}]")
    return abs(value - 0.5 * (low + high))


def _scale(comparator: str, low: float | None, high: float | None) -> float:
    """The limit's magnitude (the half-width of an ``in_range`` band)."""
    if comparator == "in_range" and low is not None and high is not None:
        return 0.5 * abs(high - low)
    x = high if comparator in ("at_most", "within") else low
    return abs(x) if x is not None and math.isfinite(x) else 0.0


@dataclass(frozen=True)
class Tolerance:
    """A tolerance: ``absolute`` (display unit) and/or ``relative`` (a fraction of
    ``|A|``); the larger applies. ``source``: ``command line``, ``case`` or ``default``."""

    absolute: float | None = None
    relative: float | None = None
    source: str = "default"

    def at(self, reference: float) -> float:
        parts = [self.absolute or 0.0]
        if self.relative is not None and math.isfinite(reference):
            parts.append(self.relative * abs(reference))
        return max(parts)

    def text(self) -> str:
        parts = [f"{self.absolute:.4g}"] if self.absolute is not None else []
        if self.relative is not None:
            parts.append(f"{100 * self.relative:.4g} %")
        return " | ".join(parts) or "0"


def value_status(a: float | None, b: float | None, bad: Any, tol: float, control: bool = False) -> str:
    """REGRESSION, IMPROVEMENT, SAME or (a control) CHANGED for values A and B (None:
    unmeasured); ``bad`` maps a value to its badness (:func:`badness`)."""
    if a is None and b is None:
        return SAME
    if a is None or b is None:
        return CHANGED if control else REGRESSION if b is None else IMPROVEMENT
    if a == b:
        return SAME
    d = bad(b) - bad(a)
    if math.isnan(d) or (math.isfinite(d) and abs(d) <= tol):
        return SAME
    if control:
        return CHANGED
    return REGRESSION if d > 0 else IMPROVEMENT


def _verdict(text: str | None) -> Verdict | None:
    try:
        return Verdict(text)
    except ValueError:
        return None


def verdict_change(a: str | None, b: str | None) -> str | None:
    """``worse``, ``better``, ``changed`` (to or from N/A, or an unknown verdict) or None."""
    if a == b:
        return None
    va, vb = _verdict(a), _verdict(b)
    if va is None or vb is None or Verdict.NA in (va, vb):
        return "changed"
    return "worse" if vb.rank > va.rank else "better"


# -- comparison ----------------------------------------------------------------------------
@dataclass
class Row:
    """One matched (or unmatched) criterion."""

    case: str
    criterion: str
    variant: str | None
    control: bool
    metric: str
    unit: str
    comparator: str
    limit_a: str | None
    limit_b: str | None
    a: float | None
    b: float | None
    delta: float | None
    relative_delta: float | None
    tolerance: float | None
    tolerance_source: str
    status: str
    verdict_a: str | None
    verdict_b: str | None
    verdict_change: str | None
    reason_a: str = ""
    reason_b: str = ""
    requirements: list[str] = field(default_factory=list)

    @property
    def regression(self) -> bool:
        return self.status in (REGRESSION, MISSING) or self.verdict_change == "worse"

    @property
    def label(self) -> str:
        v = f"/{self.variant}" if self.variant else ""
        return f"{self.case} {self.criterion}{v}{' (control)' if self.control else ''}"


@dataclass
class CaseRow:
    """One case: its verdicts in A and B; status SAME, MISSING (A only) or NEW (B only)."""

    case: str
    title: str
    verdict_a: str | None
    verdict_b: str | None
    verdict_change: str | None
    status: str
    dut_a: str = ""
    dut_b: str = ""

    @property
    def regression(self) -> bool:
        return self.status == MISSING or self.verdict_change == "worse"


@dataclass
class Comparison:
    """The comparison of record ``a`` (earlier) with ``b`` (later)."""

    a: Record
    b: Record
    rows: list[Row]
    cases: list[CaseRow]
    settings: dict[str, Any]

    @property
    def regressions(self) -> list[Row]:
        return [r for r in self.rows if r.regression]

    @property
    def regressed(self) -> bool:
        return any(r.regression for r in self.rows) or any(c.regression for c in self.cases)

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.rows)

    def summary(self) -> dict[str, int]:
        """Counts: ``regressions`` (criteria and cases), then criteria by status, verdict
        changes, cases on one side only."""
        return {
            "regressions": len(self.regressions) + sum(c.regression for c in self.cases),
            "criteria": len(self.rows),
            "worse": self.count(REGRESSION),
            "better": self.count(IMPROVEMENT),
            "same": self.count(SAME),
            "controls_changed": self.count(CHANGED),
            "missing_in_b": self.count(MISSING),
            "new_in_b": self.count(NEW),
            "verdict_changes": sum(r.verdict_change is not None for r in self.rows),
            "verdicts_worse": sum(r.verdict_change == "worse" for r in self.rows),
            "cases_missing_in_b": sum(c.status == MISSING for c in self.cases),
            "cases_new_in_b": sum(c.status == NEW for c in self.cases),
            "case_verdicts_worse": sum(c.verdict_change == "worse" for c in self.cases),
        }


def _dut(case: dict[str, Any] | None) -> str:
    d = (case or {}).get("dut")
    if not isinstance(d, dict):
        return ""
    return str(d.get("name") or d.get("kind") or "")


def _case_tolerance(ca: dict[str, Any] | None, cb: dict[str, Any] | None) -> Tolerance | None:
    for c in (cb, ca):
        if c is None:
            continue
        absolute, relative = value_of(c.get("compare_tolerance")), value_of(c.get("compare_tolerance_relative"))
        if absolute is not None or relative is not None:
            return Tolerance(absolute, relative, "case")
    return None


def _row(key: Key, ca: dict[str, Any] | None, cb: dict[str, Any] | None, tol: Tolerance, floor: float) -> Row:
    c = cb if cb is not None else ca
    assert c is not None
    comparator = c["comparator"]
    low, high = _limits(c)
    a = None if ca is None else value_of(ca["value"])
    b = None if cb is None else value_of(cb["value"])
    delta = rel = tolerance = None
    if a is not None and b is not None:
        delta = 0.0 if a == b else b - a
        rel = delta / abs(a) if math.isfinite(delta) and math.isfinite(a) and a != 0 else None
    if ca is None or cb is None:
        status = NEW if ca is None else MISSING
    else:
        tolerance = tol.at(a if a is not None else math.nan)
        if tol.source == "default":
            tolerance = max(tolerance, floor * _scale(comparator, low, high))
        status = value_status(a, b, lambda x: badness(x, comparator, low, high), tolerance, key[3])
    va, vb = (None if x is None else str(x["verdict"]) for x in (ca, cb))
    return Row(
        case=key[0], criterion=key[1], variant=key[2], control=key[3], metric=str(c.get("metric", "")),
        unit=c["unit"], comparator=comparator,
        limit_a=None if ca is None else str(ca.get("limit", "")),
        limit_b=None if cb is None else str(cb.get("limit", "")),
        a=a, b=b, delta=delta, relative_delta=rel, tolerance=tolerance, tolerance_source=tol.source, status=status,
        verdict_a=va, verdict_b=vb,
        verdict_change=verdict_change(va, vb) if ca is not None and cb is not None else None,
        reason_a="" if ca is None else str(ca.get("reason") or ""),
        reason_b="" if cb is None else str(cb.get("reason") or ""),
        requirements=[str(r) for r in c.get("requirements", []) if isinstance(r, str)],
    )


def compare(
    a: Record,
    b: Record,
    tolerances: dict[str, Tolerance] | None = None,
    rel_tol: float = DEFAULT_REL_TOL,
    floor: float = DEFAULT_FLOOR,
) -> Comparison:
    """Compare B with A. ``tolerances`` maps a criterion id (every case) or
    ``CASE:CRITERION`` to a command-line tolerance; an id matching no criterion is a
    ConfigError (a misspelt id would otherwise silently tolerate nothing)."""
    tolerances = dict(tolerances or {})
    for name in tolerances:
        if not any(name in (k[1], f"{k[0]}:{k[1]}") for k in (*a.criteria, *b.criteria)):
            raise ConfigError(f"no criterion {name!r} in either record", key="--tol")
    default = Tolerance(None, rel_tol, "default")
    rows = []
    for key in [*a.criteria, *(k for k in b.criteria if k not in a.criteria)]:
        if key[0] not in a.cases or key[0] not in b.cases:
            continue  # a case on one side only is listed as a case
        ca, cb = a.criteria.get(key), b.criteria.get(key)
        tol = tolerances.get(f"{key[0]}:{key[1]}") or tolerances.get(key[1]) or _case_tolerance(ca, cb) or default
        rows.append(_row(key, ca, cb, tol, floor))
    cases = []
    for cid in [*a.cases, *(c for c in b.cases if c not in a.cases)]:
        x, y = a.cases.get(cid), b.cases.get(cid)
        va, vb = (None if c is None else str(c["verdict"]) for c in (x, y))
        status = MISSING if y is None else NEW if x is None else SAME
        cases.append(CaseRow(cid, str((y or x or {}).get("title", "")), va, vb,
                             verdict_change(va, vb) if status == SAME else None, status, _dut(x), _dut(y)))
    settings = {"rel_tol": rel_tol, "floor": floor,
                "tolerances": {k: {"absolute": v.absolute, "relative": v.relative} for k, v in tolerances.items()}}
    return Comparison(a, b, rows, cases, settings)
