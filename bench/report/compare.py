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

Only like is compared with like (issue 34). Cases are matched by id, variants by name: a
case or a variant on one side only is NOT COMPARED (listed, never a regression). The seeds
of a case's variant are those of its runs; when both sides ran it on seeds and the sets
differ, its criteria are judged on the ``basis``:

* ``common seeds`` -- the seeds both ran: each such run's value and verdict compared as
  above (REGRESSION when one of them is worse); the other seeds are not compared;
* ``over runs`` -- no seed in common and at least :data:`MIN_RUNS` runs on each side: a
  REGRESSION when B's runs are worse with significance ``alpha`` (one-sided Mann-Whitney
  on the values, and the median moved by more than the tolerance; or Fisher's exact test
  on the proportion of runs not PASS), an IMPROVEMENT the other way, else SAME
  (:mod:`bench.report.compare_stats`);
* ``not comparable`` -- otherwise (one run against one run of another seed): shown, never
  judged.

A criterion with the same seeds (or no seeds recorded, or none run on a side -- a case that
ran nothing is judged, its criteria unmeasured) is compared on its ``value``. A case's
verdict change is judged only when its variants and seeds match.

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
from bench.report.compare_stats import fisher_greater, mann_whitney_greater, median
from bench.units import to_unit

__all__ = [
    "SCHEMA",
    "DEFAULT_REL_TOL",
    "DEFAULT_FLOOR",
    "DEFAULT_ALPHA",
    "MIN_RUNS",
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
DEFAULT_ALPHA = 0.05
#: Runs each side needs for a criterion judged over runs (3 + 3 can reach p = 0.05).
MIN_RUNS = 3
REGRESSION, IMPROVEMENT, SAME, CHANGED, MISSING, NEW = "REGRESSION", "IMPROVEMENT", "SAME", "CHANGED", "MISSING", "NEW"
NOT_COMPARABLE, NOT_COMPARED = "NOT COMPARABLE", "NOT COMPARED"
#: What a row was judged on (``Row.basis``); the first three are like with like.
VALUE, COMMON, RUNS, INCOMPARABLE, ONE_SIDE = "value", "common seeds", "over runs", "not comparable", "not compared"
JUDGED = (VALUE, COMMON, RUNS)

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
    """One matched (or unmatched) criterion; ``basis``: what it was judged on (module
    docstring), ``seeds_a``/``seeds_b``: the seeds of its case's variant on each side."""

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
    basis: str = VALUE
    seeds_a: list[int] = field(default_factory=list)
    seeds_b: list[int] = field(default_factory=list)
    p_value: float | None = None
    p_verdicts: float | None = None
    note: str = ""

    @property
    def regression(self) -> bool:
        return self.status in (REGRESSION, MISSING) or (self.basis == VALUE and self.verdict_change == "worse")

    @property
    def judged(self) -> bool:
        """Compared like with like (same case, variant and seeds, or common seeds, or over runs)."""
        return self.basis in JUDGED

    @property
    def label(self) -> str:
        v = f"/{self.variant}" if self.variant else ""
        return f"{self.case} {self.criterion}{v}{' (control)' if self.control else ''}"


@dataclass
class CaseRow:
    """One case: its verdicts in A and B; status SAME (in both) or NOT COMPARED (``side``:
    ``A only``/``B only``). ``seeds``: ``[variant, seeds in A, seeds in B, basis]`` of each
    variant whose seed sets differ; ``variants``: ``[variant, side]`` of the variants on one
    side only. ``like``: same variants and seeds, so its verdict change is judged."""

    case: str
    title: str
    verdict_a: str | None
    verdict_b: str | None
    verdict_change: str | None
    status: str
    dut_a: str = ""
    dut_b: str = ""
    side: str = ""
    like: bool = True
    seeds: list[list[Any]] = field(default_factory=list)
    variants: list[list[Any]] = field(default_factory=list)

    @property
    def regression(self) -> bool:
        return self.like and self.status == SAME and self.verdict_change == "worse"


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

    @property
    def compared(self) -> int:
        """Criteria compared like with like."""
        return sum(r.judged for r in self.rows)

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.rows)

    def summary(self) -> dict[str, int]:
        """Counts: ``regressions`` (criteria and cases), then criteria by status, verdict
        changes, what was not compared, cases on one side only, seed sets that differ."""
        return {
            "regressions": len(self.regressions) + sum(c.regression for c in self.cases),
            "criteria": len(self.rows),
            "compared": self.compared,
            "worse": self.count(REGRESSION),
            "better": self.count(IMPROVEMENT),
            "same": self.count(SAME),
            "controls_changed": self.count(CHANGED),
            "missing_in_b": self.count(MISSING),
            "new_in_b": self.count(NEW),
            "not_comparable": self.count(NOT_COMPARABLE),
            "not_compared": self.count(NOT_COMPARED),
            "verdict_changes": sum(r.verdict_change is not None for r in self.rows),
            "verdicts_worse": sum(r.verdict_change == "worse" and r.regression for r in self.rows),
            "cases_not_compared": sum(c.status == NOT_COMPARED for c in self.cases),
            "cases_missing_in_b": sum(c.side == "A only" for c in self.cases),
            "cases_new_in_b": sum(c.side == "B only" for c in self.cases),
            "case_verdicts_worse": sum(c.regression for c in self.cases),
            "seed_sets_differ": sum(len(c.seeds) for c in self.cases),
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


def _int(x: Any) -> int | None:
    return x if isinstance(x, int) and not isinstance(x, bool) else None


def _runs(c: dict[str, Any] | None) -> dict[int, dict[str, Any]]:
    """A criterion's runs by seed (runs without an integer seed are left out)."""
    out = {}
    for r in (c or {}).get("runs") or []:
        if isinstance(r, dict) and _int(r.get("seed")) is not None:
            out[r["seed"]] = r
    return out


def _run_value(r: dict[str, Any] | None) -> float | None:
    if r is None:
        return None
    try:
        return value_of(r.get("value"))
    except (TypeError, ValueError):
        return None


def _variants(rec: Record, cid: str) -> set[str | None]:
    return {k[2] for k in rec.criteria if k[0] == cid}


def _seeds(rec: Record, cid: str, variant: str | None) -> list[int]:
    """The seeds case ``cid`` ran variant ``variant`` on: those of its runs and of its
    criteria's runs."""
    seeds = set()
    for r in rec.cases[cid].get("runs") or []:
        if isinstance(r, dict) and r.get("variant") == variant and _int(r.get("seed")) is not None:
            seeds.add(r["seed"])
    for k, c in rec.criteria.items():
        if k[0] == cid and k[2] == variant:
            seeds.update(_runs(c))
    return sorted(seeds)


def _basis(sa: list[int], sb: list[int]) -> str:
    """What a criterion of a variant run on seeds ``sa`` in A and ``sb`` in B is judged on."""
    if not sa or not sb or sa == sb:
        return VALUE  # the same seeds, or none recorded, or nothing run on a side: judged
    if set(sa) & set(sb):
        return COMMON
    return RUNS if min(len(sa), len(sb)) >= MIN_RUNS else INCOMPARABLE


def _seed_text(seeds: list[int]) -> str:
    return ", ".join(map(str, seeds)) or "none"


def _by_common_seeds(row: Row, ca: dict[str, Any], cb: dict[str, Any], tol: Tolerance, floor: float,
                     bad: Any, scale: float) -> None:
    """Judge ``row`` on the seeds both sides ran (:func:`value_status` and the verdicts of
    each such run); the worst seed decides."""
    ra, rb = _runs(ca), _runs(cb)
    common = sorted(set(row.seeds_a) & set(row.seeds_b) & (set(ra) | set(rb)))
    statuses, notes = [], []
    for s in common:
        a, b = _run_value(ra.get(s)), _run_value(rb.get(s))
        t = tol.at(a if a is not None else math.nan)
        if tol.source == "default":
            t = max(t, floor * scale)
        st = value_status(a, b, bad, t, row.control)
        va = None if s not in ra else str(ra[s].get("verdict"))
        vb = None if s not in rb else str(rb[s].get("verdict"))
        if s not in rb:
            st = REGRESSION  # the run of a common seed lost this criterion
        elif verdict_change(va, vb) == "worse":
            st = REGRESSION
        statuses.append(st)
        if st != SAME:
            d = "" if a is None or b is None else f" ({b - a:+.4g})" if math.isfinite(b - a) else ""
            notes.append(f"seed {s} {st.lower()}{d}")
    order = (REGRESSION, CHANGED, IMPROVEMENT, SAME)
    row.status = min(statuses, key=order.index) if statuses else SAME
    row.note = f"on seeds {_seed_text(common)}" + (f": {'; '.join(notes)}" if notes else "")
    row.delta = row.relative_delta = row.tolerance = None  # each seed had its own


def _over_runs(row: Row, ca: dict[str, Any], cb: dict[str, Any], tol: float, alpha: float, bad: Any) -> None:
    """Judge ``row`` on two sets of runs of different seeds (module docstring)."""
    ra, rb = list(_runs(ca).values()), list(_runs(cb).values())
    xa = [v for v in map(_run_value, ra) if v is not None]
    xb = [v for v in map(_run_value, rb) if v is not None]
    ba, bb = [bad(x) for x in xa], [bad(x) for x in xb]
    p_worse, p_better = mann_whitney_greater(ba, bb), mann_whitney_greater(bb, ba)
    effect = median(bb) - median(ba) if ba and bb else math.nan
    ja = [str(r.get("verdict")) for r in ra if str(r.get("verdict")) != str(Verdict.NA)]
    jb = [str(r.get("verdict")) for r in rb if str(r.get("verdict")) != str(Verdict.NA)]
    pass_ = str(Verdict.PASS)
    p_verdicts = fisher_greater(sum(v != pass_ for v in ja), len(ja), sum(v != pass_ for v in jb), len(jb))
    beyond = not math.isnan(effect) and abs(effect) > tol
    if p_verdicts <= alpha:
        row.status = REGRESSION
    elif p_worse <= alpha and beyond and effect > 0:
        row.status = CHANGED if row.control else REGRESSION
    elif p_better <= alpha and beyond and effect < 0:
        row.status = CHANGED if row.control else IMPROVEMENT
    else:
        row.status = SAME
    row.p_value = p_better if effect < 0 else p_worse
    row.p_verdicts = p_verdicts
    row.delta = median(xb) - median(xa) if xa and xb else None
    if row.delta is not None and not math.isfinite(row.delta):
        row.delta = None
    row.relative_delta = None
    row.note = (f"over {len(ra)} + {len(rb)} runs: medians {median(xa) if xa else math.nan:.4g} -> "
                f"{median(xb) if xb else math.nan:.4g}, p = {row.p_value:.2g} (values), "
                f"{sum(v != pass_ for v in ja)}/{len(ja)} -> {sum(v != pass_ for v in jb)}/{len(jb)} "
                f"runs not PASS, p = {p_verdicts:.2g}")


def _row(key: Key, ca: dict[str, Any] | None, cb: dict[str, Any] | None, tol: Tolerance, floor: float,
         seeds: tuple[list[int], list[int]] = ([], []), alpha: float = DEFAULT_ALPHA) -> Row:
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

    def bad(x: float) -> float:
        return badness(x, comparator, low, high)

    basis = VALUE if ca is None or cb is None else _basis(*seeds)
    if ca is None or cb is None:
        status = NEW if ca is None else MISSING
    else:
        tolerance = tol.at(a if a is not None else math.nan)
        if tol.source == "default":
            tolerance = max(tolerance, floor * _scale(comparator, low, high))
        status = value_status(a, b, bad, tolerance, key[3]) if basis == VALUE else NOT_COMPARABLE
    va, vb = (None if x is None else str(x["verdict"]) for x in (ca, cb))
    row = Row(
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
        basis=basis, seeds_a=list(seeds[0]), seeds_b=list(seeds[1]),
    )
    if ca is not None and cb is not None and tolerance is not None:
        if basis == COMMON:
            _by_common_seeds(row, ca, cb, tol, floor, bad, _scale(comparator, low, high))
        elif basis == RUNS:
            _over_runs(row, ca, cb, tolerance, alpha, bad)
        elif basis == INCOMPARABLE:
            row.note = f"seeds differ (A {_seed_text(seeds[0])}; B {_seed_text(seeds[1])}): not comparable"
            row.delta = row.relative_delta = row.tolerance = None
    return row


def _one_side(key: Key, c: dict[str, Any], side: str, seeds: list[int]) -> Row:
    """A criterion of a variant that one side only ran: listed, not compared."""
    x = value_of(c["value"])
    in_a = side == "A only"
    return Row(
        case=key[0], criterion=key[1], variant=key[2], control=key[3], metric=str(c.get("metric", "")),
        unit=c["unit"], comparator=c["comparator"], limit_a=str(c.get("limit", "")) if in_a else None,
        limit_b=None if in_a else str(c.get("limit", "")), a=x if in_a else None, b=None if in_a else x,
        delta=None, relative_delta=None, tolerance=None, tolerance_source="", status=NOT_COMPARED,
        verdict_a=str(c["verdict"]) if in_a else None, verdict_b=None if in_a else str(c["verdict"]),
        verdict_change=None, requirements=[str(r) for r in c.get("requirements", []) if isinstance(r, str)],
        basis=ONE_SIDE, seeds_a=seeds if in_a else [], seeds_b=[] if in_a else seeds,
        note=f"variant {key[2]} in {side}",
    )


def compare(
    a: Record,
    b: Record,
    tolerances: dict[str, Tolerance] | None = None,
    rel_tol: float = DEFAULT_REL_TOL,
    floor: float = DEFAULT_FLOOR,
    alpha: float = DEFAULT_ALPHA,
) -> Comparison:
    """Compare B with A, like with like (module docstring). ``tolerances`` maps a criterion
    id (every case) or ``CASE:CRITERION`` to a command-line tolerance; an id matching no
    criterion is a ConfigError (a misspelt id would otherwise silently tolerate nothing).
    ``alpha``: the significance of a criterion judged over runs."""
    tolerances = dict(tolerances or {})
    for name in tolerances:
        if not any(name in (k[1], f"{k[0]}:{k[1]}") for k in (*a.criteria, *b.criteria)):
            raise ConfigError(f"no criterion {name!r} in either record", key="--tol")
    default = Tolerance(None, rel_tol, "default")
    both = [c for c in a.cases if c in b.cases]
    variants = {cid: (_variants(a, cid), _variants(b, cid)) for cid in both}
    seeds = {(cid, v): (_seeds(a, cid, v), _seeds(b, cid, v)) for cid in both for v in set().union(*variants[cid])}
    rows = []
    for key in [*a.criteria, *(k for k in b.criteria if k not in a.criteria)]:
        if key[0] not in variants:
            continue  # a case on one side only is listed as a case
        ca, cb = a.criteria.get(key), b.criteria.get(key)
        va, vb = variants[key[0]]
        sa, sb = seeds[(key[0], key[2])]
        if key[2] not in va and va:
            rows.append(_one_side(key, cb, "B only", sb))  # type: ignore[arg-type]
            continue
        if key[2] not in vb and vb:
            rows.append(_one_side(key, ca, "A only", sa))  # type: ignore[arg-type]
            continue
        tol = tolerances.get(f"{key[0]}:{key[1]}") or tolerances.get(key[1]) or _case_tolerance(ca, cb) or default
        rows.append(_row(key, ca, cb, tol, floor, (sa, sb), alpha))
    cases = []
    for cid in [*a.cases, *(c for c in b.cases if c not in a.cases)]:
        x, y = a.cases.get(cid), b.cases.get(cid)
        va_, vb_ = (None if c is None else str(c["verdict"]) for c in (x, y))
        title = str((y or x or {}).get("title", ""))
        if x is None or y is None:
            cases.append(CaseRow(cid, title, va_, vb_, None, NOT_COMPARED, _dut(x), _dut(y),
                                 side="B only" if x is None else "A only", like=False))
            continue
        in_a, in_b = variants[cid]
        one_side = [[v, "A only" if v in in_a else "B only"] for v in sorted(in_a ^ in_b, key=str)
                    if in_a and in_b]
        differ = []
        for v in sorted(in_a & in_b, key=str):
            sa, sb = seeds[(cid, v)]
            basis = _basis(sa, sb)
            if basis != VALUE:
                differ.append([v, sa, sb, basis])
        cases.append(CaseRow(cid, title, va_, vb_, verdict_change(va_, vb_), SAME, _dut(x), _dut(y),
                             like=not one_side and not differ, seeds=differ, variants=one_side))
    settings = {"rel_tol": rel_tol, "floor": floor, "alpha": alpha, "min_runs": MIN_RUNS,
                "tolerances": {k: {"absolute": v.absolute, "relative": v.relative} for k, v in tolerances.items()}}
    return Comparison(a, b, rows, cases, settings)
