"""Acceptance criteria: a metric over a window, against a limit, for a requirement.

A criterion states its limit by meaning -- ``at_most``, ``at_least``, ``within`` (the
absolute value at most) or ``in_range`` ``[low, high]`` -- with units checked against
the metric's dimension. An optional band next to the limit turns a pass into MARGINAL:
``marginal`` (absolute, in the metric's units) or ``marginal_relative`` (a fraction of
the limit's magnitude). ``relative_to`` makes the criterion a comparison of two variants
of the DUT run with the same seeds: the value is the metric of this variant divided by the
same metric of the named one (dimensionless). ``must_fail_on`` names negative controls:
variants run without what the criterion checks (a compensation switched off), on which the
criterion must FAIL on every run -- proof that it can tell the DUT from one without it.

Over Monte Carlo runs (``[monte_carlo]``):

* ``each`` (default) -- every run must meet the limit; the verdict is the worst;
* ``pass_runs = k`` -- at least k runs must meet it (the value shown is the k-th best
  run's);
* ``percentile = p`` with ``confidence = c`` -- a distribution-free confidence bound of
  the p-th percentile over the runs (an order statistic chosen by the binomial law) must
  meet it: the upper bound for ``at_most``/``within``, the lower for ``at_least``;
  too few runs for the confidence asked is ERROR;
* ``aggregate = mean | median | max | min`` -- that statistic of the runs' values;
* ``anees = c`` (consistency ``within``/``above``/``below`` only) -- the Monte Carlo
  consistency test over the runs (:mod:`bench.acceptance.anees`): at each time of a 1 s
  grid, the NEES per degree of freedom averaged over the N runs (ANEES) against the
  two-sided interval of probability ``c`` of chi-square(N) / N (whatever the correlation
  between the axes); the value is the share of grid times in (above, below) that band.
  N = 1 is the per-run test.

:class:`Limit`, :class:`MonteCarlo` and :class:`Criterion` check themselves when built
(finite bounds, a known comparator, ``low < high``, a non-negative band, a percentile in
(0, 100), a confidence in (0, 1)) and raise :class:`~bench.errors.ConfigError` naming the
field, so a ``nan``, an ``inf`` or a misspelt comparator never reaches judging, whether the
criterion comes from a file or from Python. :func:`judge_value` still gives ERROR, never
PASS, for a margin that is not a number.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import binom

from bench.acceptance.verdict import Verdict
from bench.errors import ConfigError
from bench.scoring.windows import WindowSpec
from bench.units import to_unit

__all__ = [
    "COMPARATORS",
    "Limit",
    "MonteCarlo",
    "Criterion",
    "judge_value",
    "RunValue",
    "Aggregate",
    "aggregate_runs",
    "order_statistic_bound",
    "runs_needed",
]

COMPARATORS = ("at_most", "at_least", "within", "in_range")
AGGREGATES = ("mean", "median", "max", "min")
MC_MODES = ("each", "pass_runs", "percentile", "aggregate", "anees")
#: consistency statistics the ``anees`` mode judges (the share of grid times in, above or
#: below the band); ``nees`` (a run's mean) is judged run by run
ANEES_STATS = ("within", "above", "below")


def _finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@dataclass(frozen=True)
class Limit:
    """``comparator`` with SI bounds (``low``/``high``; one of them for one-sided).

    ``at_most`` and ``within`` take ``high`` only (``within``: a tolerance >= 0),
    ``at_least`` ``low`` only, ``in_range`` both with ``low < high``; all finite.
    ConfigError otherwise, its key the comparator.
    """

    comparator: str
    low: float | None = None
    high: float | None = None

    def __post_init__(self) -> None:
        c = self.comparator
        if c not in COMPARATORS:
            raise ConfigError(f"unknown comparator {c!r}; expected one of {', '.join(COMPARATORS)}", key="comparator")
        need = {"at_most": (False, True), "within": (False, True), "at_least": (True, False), "in_range": (True, True)}
        for side, value, wanted in (("low", self.low, need[c][0]), ("high", self.high, need[c][1])):
            if not wanted and value is not None:
                raise ConfigError(f"{c} takes no {side} bound, found {value!r}", key=c)
            if wanted and not _finite(value):
                raise ConfigError(f"expected a finite {side} bound, found {value!r}", key=c)
        if c == "within" and self.high < 0:  # type: ignore[operator]
            raise ConfigError(f"expected a non-negative tolerance, found {self.high!r}", key=c)
        if c == "in_range" and not self.low < self.high:  # type: ignore[operator]
            raise ConfigError(f"expected low < high, found [{self.low!r}, {self.high!r}]", key=c)

    def text(self, unit: str) -> str:
        def f(x: float | None) -> str:
            if x is None:
                return "?"
            return _num(float(to_unit(x, unit))) + ("" if unit == "1" else f" {unit}")

        if self.comparator == "at_most":
            return f"<= {f(self.high)}"
        if self.comparator == "at_least":
            return f">= {f(self.low)}"
        if self.comparator == "within":
            return f"|x| <= {f(self.high)}"
        return f"{f(self.low)} .. {f(self.high)}"


@dataclass(frozen=True)
class MonteCarlo:
    """How per-run values combine (see the module docstring)."""

    mode: str = "each"
    pass_runs: int | None = None
    percentile: float | None = None
    confidence: float | None = None
    aggregate: str | None = None
    anees: float | None = None  # the band's confidence, a probability

    def __post_init__(self) -> None:
        k = "monte_carlo"
        if self.mode not in MC_MODES:
            raise ConfigError(f"unknown mode {self.mode!r}; expected one of {', '.join(MC_MODES)}", key=k)
        given = {n: getattr(self, n) is not None
                 for n in ("pass_runs", "percentile", "confidence", "aggregate", "anees")}
        wants = {"each": (), "pass_runs": ("pass_runs",), "percentile": ("percentile", "confidence"),
                 "aggregate": ("aggregate",), "anees": ("anees",)}[self.mode]
        for name, present in given.items():
            if present != (name in wants):
                state = "needs" if not present else "takes no"
                raise ConfigError(f"a {self.mode} criterion {state} {name}", key=f"{k}.{name}")
        if self.mode == "pass_runs" and (
            not isinstance(self.pass_runs, int) or isinstance(self.pass_runs, bool) or self.pass_runs < 1
        ):
            raise ConfigError(f"expected an integer >= 1, found {self.pass_runs!r}", key=f"{k}.pass_runs")
        if self.mode == "percentile":
            if not (_finite(self.percentile) and 0.0 < self.percentile < 100.0):  # type: ignore[operator]
                raise ConfigError(
                    f"expected a percentile between 0 and 100, found {self.percentile!r}", key=f"{k}.percentile"
                )
            if not (_finite(self.confidence) and 0.0 < self.confidence < 1.0):  # type: ignore[operator]
                raise ConfigError(
                    f"expected a probability between 0 and 1 (or %), found {self.confidence!r}", key=f"{k}.confidence"
                )
        if self.mode == "anees" and not (_finite(self.anees) and 0.0 < self.anees < 1.0):  # type: ignore[operator]
            raise ConfigError(
                f"expected the band's confidence, a probability between 0 and 1 (or %), found {self.anees!r}",
                key=f"{k}.anees",
            )
        if self.mode == "aggregate" and self.aggregate not in AGGREGATES:
            raise ConfigError(
                f"expected one of {', '.join(AGGREGATES)}, found {self.aggregate!r}", key=f"{k}.aggregate"
            )

    def text(self, runs: int | None = None) -> str:
        """How the runs combine, for a summary; ``runs``: how many were judged (the ANEES
        mode names them)."""
        if self.mode == "anees":
            over = f"{runs} run{'s' if runs != 1 else ''}" if runs is not None else "the runs"
            return f"ANEES over {over} in its {_num(100 * (self.anees or 0))} % band"
        if self.mode == "pass_runs":
            return f"at least {self.pass_runs} runs"
        if self.mode == "percentile":
            return f"p{_num(self.percentile or 0)} at {_num(100 * (self.confidence or 0))} % confidence"
        if self.mode == "aggregate":
            return f"{self.aggregate} of runs"
        return "every run"


@dataclass(frozen=True)
class Criterion:
    """One acceptance criterion of a test case (limits and band in SI)."""

    id: str
    requirements: tuple[str, ...]
    metric: str
    window: WindowSpec
    limit: Limit
    unit: str
    dimension: str
    marginal: float | None = None
    marginal_relative: float | None = None
    paper: str = ""
    description: str = ""
    variant: str | None = None
    #: where the limit comes from: "paper", "standard" or "bench" ("" until the case's
    #: requirements are read: bench.acceptance.requirements.resolve_limit_sources)
    limit_source: str = ""
    relative_to: str | None = None
    must_fail_on: tuple[str, ...] = ()
    options: dict[str, Any] = field(default_factory=dict, hash=False, compare=False)
    monte_carlo: MonteCarlo = field(default_factory=MonteCarlo)
    compare_tolerance: float | None = None  # SI, for ``bench compare``
    compare_tolerance_relative: float | None = None  # a fraction of the earlier value

    def __post_init__(self) -> None:
        if not isinstance(self.limit, Limit):
            raise ConfigError(f"expected a Limit, found {self.limit!r}", key="limit")
        if not isinstance(self.monte_carlo, MonteCarlo):
            raise ConfigError(f"expected a MonteCarlo, found {self.monte_carlo!r}", key="monte_carlo")
        if self.marginal is not None and self.marginal_relative is not None:
            raise ConfigError("give either 'marginal' or 'marginal_relative', not both", key="marginal")
        for name in ("marginal", "marginal_relative", "compare_tolerance", "compare_tolerance_relative"):
            band = getattr(self, name)
            if band is not None and not (_finite(band) and band >= 0.0):
                what = "band" if name.startswith("marginal") else "tolerance"
                raise ConfigError(f"expected a finite non-negative {what}, found {band!r}", key=name)
        if self.monte_carlo.mode == "anees":
            parts = self.metric.split(".")
            if parts[0] != "consistency" or len(parts) != 3 or parts[2] not in ANEES_STATS:
                raise ConfigError(
                    f"the anees mode judges consistency.<quantity>.{'|'.join(ANEES_STATS)} (the share of grid times "
                    f"whose ANEES is in, above or below its band), not {self.metric}; a run's mean NEES "
                    "(consistency.<quantity>.nees) is judged run by run", key="monte_carlo.anees")
            if self.relative_to is not None:
                raise ConfigError("a comparison (relative_to) cannot be judged by ANEES", key="monte_carlo.anees")
        if self.monte_carlo.mode == "percentile" and self.limit.comparator == "in_range":
            raise ConfigError(
                "a percentile bound applies to at_most, at_least or within, not in_range", key="monte_carlo.percentile"
            )
        if self.relative_to is not None and (self.variant is None or self.relative_to == self.variant):
            raise ConfigError("a comparison (relative_to) names another variant it judges", key="relative_to")
        if self.must_fail_on and self.relative_to is not None:
            raise ConfigError("a comparison (relative_to) takes no negative control", key="must_fail_on")
        if self.variant is not None and self.variant in self.must_fail_on:
            raise ConfigError(f"variant {self.variant!r} cannot be both judged and a negative control",
                              key="must_fail_on")
        if len(set(self.must_fail_on)) != len(self.must_fail_on):
            raise ConfigError(f"a variant listed twice: {list(self.must_fail_on)}", key="must_fail_on")

    def band(self) -> float:
        """The marginal band, SI (0 without one)."""
        if self.marginal is not None:
            return self.marginal
        if self.marginal_relative is not None:
            ref = self.limit.high if self.limit.high is not None else self.limit.low
            return abs(ref or 0.0) * self.marginal_relative
        return 0.0

    def display(self, value: float) -> float:
        """An SI value in the criterion's display unit."""
        return float(to_unit(value, self.unit)) if math.isfinite(value) else value


def _num(x: float) -> str:
    return f"{x:.6g}"


def judge_value(limit: Limit, band: float, value: float) -> tuple[Verdict, float]:
    """Verdict of one value against a limit with a marginal band, and the margin (SI,
    positive inside the limit). NaN is ERROR (the metric is undefined)."""
    if math.isnan(value):
        return Verdict.ERROR, math.nan
    c = limit.comparator
    if c == "at_most":
        margin = limit.high - value  # type: ignore[operator]
    elif c == "at_least":
        margin = value - limit.low  # type: ignore[operator]
    elif c == "within":
        margin = limit.high - abs(value)  # type: ignore[operator]
    else:
        margin = min(value - limit.low, limit.high - value)  # type: ignore[operator]
    if math.isnan(margin):  # cannot happen with a checked Limit; never a PASS
        return Verdict.ERROR, math.nan
    if margin < 0:
        return Verdict.FAIL, margin
    if band > 0 and margin < band:
        return Verdict.MARGINAL, margin
    return Verdict.PASS, margin


@dataclass
class RunValue:
    """A criterion's outcome in one run: value (SI, NaN if unmeasured), verdict, why."""

    seed: int
    value: float
    verdict: Verdict
    reason: str = ""
    details: dict[str, Any] = field(default_factory=dict)


@dataclass
class Aggregate:
    """A criterion's outcome over the runs of a case variant."""

    value: float
    verdict: Verdict
    margin: float
    reason: str = ""
    details: dict[str, Any] = field(default_factory=dict)  # the ANEES mode: its series and band


def order_statistic_bound(n: int, p: float, confidence: float, upper: bool) -> int | None:
    """1-based rank r of the order statistic bounding the p-quantile (0<p<1) of n runs
    with at least ``confidence``: ``P(X_(r) >= q_p) >= c`` (upper, the smallest such r)
    or ``P(X_(r) <= q_p) >= c`` (lower, the largest such r). None if n runs cannot give
    that confidence."""
    if n < 1:
        return None
    below = binom.cdf(np.arange(n), n, p)  # P(at most r-1 of n runs below q_p), r = 1..n
    if upper:
        ok = np.flatnonzero(below >= confidence)
        return int(ok[0]) + 1 if len(ok) else None
    ok = np.flatnonzero(1.0 - below >= confidence)
    return int(ok[-1]) + 1 if len(ok) else None


def runs_needed(p: float, confidence: float, upper: bool) -> int:
    """Fewest runs whose extreme order statistic bounds the p-quantile at ``confidence``."""
    q = p if upper else 1.0 - p
    return math.ceil(math.log(1.0 - confidence) / math.log(q) - 1e-12)


def _worst_value(criterion: Criterion, values: Sequence[float]) -> float:
    c = criterion.limit.comparator
    if c == "at_most":
        return max(values)
    if c == "at_least":
        return min(values)
    if c == "within":
        return max(values, key=abs)
    lo, hi = criterion.limit.low, criterion.limit.high
    return min(values, key=lambda v: min(v - lo, hi - v))  # type: ignore[operator]


def aggregate_runs(criterion: Criterion, runs: Sequence[RunValue]) -> Aggregate:
    """Combine the per-run outcomes of one criterion per its Monte Carlo mode."""
    if not runs:
        return Aggregate(math.nan, Verdict.ERROR, math.nan, "no run to judge")
    applies = [r for r in runs if r.verdict is not Verdict.NA]
    if not applies:  # not applicable to any run (a latency in lockstep)
        return Aggregate(math.nan, Verdict.NA, math.nan, runs[0].reason)
    runs = applies
    mc = criterion.monte_carlo
    band = criterion.band()
    errors = [r for r in runs if r.verdict is Verdict.ERROR]
    measured = [r.value for r in runs if not math.isnan(r.value)]
    if mc.mode == "each":
        worst_run = max(runs, key=lambda r: r.verdict.rank)
        if worst_run.verdict is Verdict.ERROR:
            return Aggregate(math.nan, Verdict.ERROR, math.nan, worst_run.reason or "not measured")
        if not measured:
            return Aggregate(math.nan, worst_run.verdict, math.nan, worst_run.reason)
        v = _worst_value(criterion, measured)
        verdict, margin = judge_value(criterion.limit, band, v)
        reason = ""
        if worst_run.verdict.rank > verdict.rank:  # a DUT failure without a value
            verdict, reason = worst_run.verdict, worst_run.reason
        return Aggregate(v, verdict, margin, reason)
    if mc.mode == "pass_runs":
        need = int(mc.pass_runs or 0)
        if len(runs) < need:
            return Aggregate(
                math.nan, Verdict.ERROR, math.nan, f"{len(runs)} runs cannot show {need} passing runs; run more seeds"
            )
        ok = [r for r in runs if r.verdict.passed]
        text = f"{len(ok)} of {len(runs)} runs met the limit, {need} required"
        ranked = sorted(measured, key=lambda v: -judge_value(criterion.limit, 0.0, v)[1])
        v = ranked[need - 1] if len(ranked) >= need else math.nan  # the need-th best run
        margin = judge_value(criterion.limit, band, v)[1] if not math.isnan(v) else math.nan
        if len(ok) >= need:
            marginal = sum(r.verdict is Verdict.MARGINAL for r in ok)
            verdict = Verdict.MARGINAL if len(ok) - marginal < need else Verdict.PASS
            return Aggregate(v, verdict, margin, text)
        if len(ok) + len(errors) >= need:
            return Aggregate(v, Verdict.ERROR, margin, f"{text}; {len(errors)} runs could not be judged")
        return Aggregate(v, Verdict.FAIL, margin, text)
    if errors:
        return Aggregate(math.nan, Verdict.ERROR, math.nan, f"{len(errors)} of {len(runs)} runs could not be judged")
    if len(measured) < len(runs):
        bad = next(r for r in runs if math.isnan(r.value))
        return Aggregate(math.nan, bad.verdict, math.nan, bad.reason)
    if mc.mode == "anees":
        return _anees(criterion, runs)
    x = np.sort(np.array(measured))
    if mc.mode == "aggregate":
        fn = {"mean": np.mean, "median": np.median, "max": np.max, "min": np.min}[mc.aggregate or "mean"]
        v = float(fn(x))
        verdict, margin = judge_value(criterion.limit, band, v)
        return Aggregate(v, verdict, margin, f"{mc.aggregate} of {len(x)} runs")
    # percentile with confidence
    p = float(mc.percentile or 50.0) / 100.0
    conf = float(mc.confidence or 0.5)
    upper = criterion.limit.comparator in ("at_most", "within")
    values = np.sort(np.abs(x)) if criterion.limit.comparator == "within" else x
    r = order_statistic_bound(len(values), p, conf, upper)
    if r is None:
        need = runs_needed(p, conf, upper)
        return Aggregate(
            math.nan,
            Verdict.ERROR,
            math.nan,
            f"{len(values)} runs cannot bound the {100 * p:g}th percentile at {100 * conf:g} % confidence; "
            f"at least {need} are needed",
        )
    v = float(values[r - 1])
    verdict, margin = judge_value(criterion.limit, band, v)
    side = "upper" if upper else "lower"
    return Aggregate(v, verdict, margin, f"{side} {100 * conf:g} % bound of p{100 * p:g}: run value #{r} of {len(x)}")


def _anees(criterion: Criterion, runs: Sequence[RunValue]) -> Aggregate:
    """The ``anees`` mode (:mod:`bench.acceptance.anees`): the share of grid times whose
    ANEES over the runs is in (above, below) its band, against the limit."""
    from bench.acceptance.anees import AneesError, anees_test, series_of

    try:
        res = anees_test([series_of(r.details, r.seed) for r in runs], float(criterion.monte_carlo.anees or 0.0))
    except AneesError as exc:
        return Aggregate(math.nan, Verdict.ERROR, math.nan, str(exc))
    v = res.share(criterion.metric.split(".")[2])
    verdict, margin = judge_value(criterion.limit, criterion.band(), v)
    return Aggregate(v, verdict, margin, res.text(criterion.window.name), res.as_dict())
