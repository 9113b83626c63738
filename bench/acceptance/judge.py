"""Judging: criteria applied to recordings, runs combined into a case verdict.

:func:`score_recording` judges one recording against its test case (the one attached to
the recording unless another is given): integrity first (a run the bench could not finish
-- its own failures, and ``dut_error``, a DUT ending it cannot pin on the DUT -- makes every
criterion ERROR with the reason; a DUT's failure, the ``dut_failed`` ending of any DUT kind,
:data:`bench.scoring.integrity.DUT_STATUSES`, makes the run FAIL and what it leaves
unmeasurable FAIL with the reason; a failed output-integrity criterion makes what the DUT's
output leaves unmeasurable FAIL), then every criterion of the
run's variant from the recording alone -- the case's own criteria and the default output
integrity criteria (:mod:`bench.acceptance.integrity_criteria`) it was loaded with.
:func:`judge_case` combines the runs of a case (variants, Monte Carlo seeds, variant
comparisons, negative controls) into criterion and case verdicts.

A criterion's negative controls (``must_fail_on``: variants run without what it checks)
are measured like any run but judged the other way round: the criterion must FAIL on every
run of the control, beyond its marginal band; a control that passes (or only just fails)
is a FAIL of the criterion -- it cannot tell the DUT from one without what it checks -- and
a control the bench could not measure is an ERROR. A control never turns a FAIL of the DUT
into a PASS: it only adds a result of its own.

Live runs are judged by scoring their finished recording with the very same functions,
so ``bench score`` reproduces a live verdict bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from bench.acceptance.case import TestCase, parse_case, with_requirements
from bench.acceptance.criteria import Aggregate, Criterion, RunValue, aggregate_runs, judge_value
from bench.acceptance.integrity_criteria import PREFIX, waivers
from bench.acceptance.requirements import ATTACHMENT, parse_requirements, stated
from bench.acceptance.verdict import Verdict, worst
from bench.errors import ConfigError, RecordingError
from bench.scoring.consistency import GRID_NS
from bench.scoring.data import DutDataError, NoDataError, RunData, load_run
from bench.scoring.metrics import Scorer

__all__ = [
    "RunResult",
    "CriterionResult",
    "CaseResult",
    "score_recording",
    "score_run",
    "judge_case",
    "case_of",
    "NOT_IN_LOCKSTEP",
    "unjudged_requirements",
]

#: Metrics that do not apply to a lockstep run (verdict N/A): the DUT's output latency,
#: arrival minus time of validity, is set there by the bench's wait for DUT_READY.
NOT_IN_LOCKSTEP = ("output.latency_mean", "output.latency_p95", "output.latency_max")
_NA_LOCKSTEP = "not applicable in lockstep (the bench waits for each answer): judged in real-time runs only"


@dataclass
class RunResult:
    """One run judged: its identity, verdict, issues and per-criterion outcomes."""

    recording: str
    case_id: str
    variant: str | None
    seed: int
    verdict: Verdict
    bench_issues: list[str] = field(default_factory=list)
    dut_issues: list[str] = field(default_factory=list)
    values: dict[str, RunValue] = field(default_factory=dict)
    raw: dict[str, RunValue] = field(default_factory=dict)  # metrics of comparison criteria
    overview: dict[str, Any] = field(default_factory=dict)
    timing: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # for the record (a damaged source accepted by the user)


@dataclass
class CriterionResult:
    """A criterion judged over the runs of one variant."""

    criterion: Criterion
    variant: str | None
    aggregate: Aggregate
    runs: list[RunValue]
    control: bool = False  # a negative control (must_fail_on): the criterion had to FAIL

    @property
    def label(self) -> str:
        """``ID``, ``ID[variant]``, or ``ID[variant, must FAIL]`` for a negative control."""
        if not self.variant:
            return self.criterion.id
        return f"{self.criterion.id}[{self.variant}{', must FAIL' if self.control else ''}]"

    @property
    def verdict(self) -> Verdict:
        return self.aggregate.verdict


@dataclass
class CaseResult:
    """A test case judged: verdict, criteria, runs, and why it could not be judged."""

    case_id: str
    title: str
    file: str
    requirements: tuple[str, ...]
    verdict: Verdict
    criteria: list[CriterionResult] = field(default_factory=list)
    runs: list[RunResult] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    case: TestCase | None = None
    elapsed_s: float = 0.0
    waived: list[dict[str, str]] = field(default_factory=list)  # integrity checks the case switched off


def case_of(run: RunData) -> TestCase:
    """The test case attached to a recording."""
    att = run.case_attachment()
    if att is None:
        raise RecordingError(f"{run.path}: no test case attached (case/<file>); give one with --case")
    name, data = att
    case = parse_case(data.decode("utf-8"), file=f"{run.path}:case/{name}", check_files=False)
    req = run.attachments.get(ATTACHMENT)
    given = None
    if req is not None:
        given = parse_requirements(req.decode("utf-8", "replace"), file=f"{run.path}:{ATTACHMENT}")
    texts = stated(case.requirements, given, file=f"{run.path}:{ATTACHMENT}", case_file=f"{run.path}:case/{name}")
    return with_requirements(case, texts, req.decode("utf-8", "replace") if req is not None else "")


def _applies(c: Criterion, variant: str | None) -> bool:
    return (c.variant is None and variant not in c.must_fail_on) or c.variant == variant


def _judged(c: Criterion, variant: str | None) -> bool:
    """Whether a run of ``variant`` measures ``c`` (a comparison: both its variants; a
    negative control: its control variants too)."""
    if c.relative_to is not None:
        return variant in (c.variant, c.relative_to)
    return _applies(c, variant) or variant in c.must_fail_on


def score_run(run: RunData, case: TestCase) -> RunResult:
    """Judge one loaded recording against ``case``."""
    variant = run.run_start.get("variant") or None
    if variant is not None and variant not in case.dut.variants:
        raise ConfigError(
            f"the recording is of variant {variant!r}, which the case does not define", file=case.file, key="dut"
        )
    try:
        seed = int(run.run_start.get("seed", "0"))
    except ValueError:
        seed = 0
    # the clock the run really used (a command line may have overridden the case's)
    mode = run.run_start.get("clock_mode") or case.clock.mode
    budget = case.clock.budget_ns if mode == "realtime" else None
    scorer = Scorer(run, replace(case.scoring, budget_ns=budget))
    integ = scorer.integrity()
    result = RunResult(str(run.path), case.id, variant, seed, Verdict.PASS, integ.bench, integ.dut, timing=integ.timing)
    result.notes = list(integ.notes)
    criteria = [c for c in case.criteria if _judged(c, variant)]
    # the output-integrity defaults first: what a DUT's broken output keeps the bench from
    # measuring is the DUT's failure (FAIL), not the bench's (ERROR)
    checked = {c.id: _measure(scorer, c, seed, integ.bench, integ.dut) for c in criteria if c.id.startswith(PREFIX)}
    broken = [f"its output failed {k}" for k, v in checked.items() if v.verdict is Verdict.FAIL]
    for c in criteria:
        compared = c.relative_to is not None or variant in c.must_fail_on  # not this run's own verdict
        if mode != "realtime" and c.metric in NOT_IN_LOCKSTEP:
            rv = RunValue(seed, math.nan, Verdict.NA, _NA_LOCKSTEP)
        else:
            rv = checked[c.id] if c.id in checked else _measure(scorer, c, seed, integ.bench, integ.dut + broken)
        if compared:
            result.raw[c.id] = rv
        else:
            result.values[c.id] = rv
    try:
        result.overview = scorer.overview() if not integ.bench else {}
    except (NoDataError, DutDataError):
        result.overview = {}
    # a run's own verdict: the criteria judged run by run (Monte Carlo mode "each"); a value
    # that only feeds a statistic over the runs (pass_runs, percentile, aggregate) is judged
    # there, in the criterion's verdict, not here
    own = [result.values[c.id].verdict for c in criteria
           if c.id in result.values and c.monte_carlo.mode == "each"]
    if integ.bench:
        result.verdict = Verdict.ERROR
    elif integ.dut:
        result.verdict = worst([Verdict.FAIL, *own])
    else:
        result.verdict = worst(own)
    return result


def _measure(scorer: Scorer, c: Criterion, seed: int, bench: list[str], dut: list[str]) -> RunValue:
    options = c.options
    if c.monte_carlo.mode == "anees":  # the NEES sampled on the grid, for the test over the runs
        options = {**options, "nees_grid_ns": GRID_NS}
    try:
        mv = scorer.metric(c.metric, c.window, options)
    except NoDataError as exc:
        if dut and not bench:
            return RunValue(seed, math.nan, Verdict.FAIL, f"{exc} (the DUT failed: {'; '.join(dut)})")
        return RunValue(seed, math.nan, Verdict.ERROR, str(exc) if not bench else "; ".join(bench))
    except DutDataError as exc:
        verdict = Verdict.ERROR if bench else Verdict.FAIL
        return RunValue(seed, math.nan, verdict, str(exc) if not bench else "; ".join(bench))
    if c.relative_to is not None:
        return RunValue(seed, mv.value, Verdict.PASS, "", mv.details)
    verdict, _ = judge_value(c.limit, c.band(), mv.value)
    reason = "metric undefined (NaN)" if verdict is Verdict.ERROR else ""
    if bench:
        verdict, reason = Verdict.ERROR, "; ".join(bench)
    return RunValue(seed, mv.value, verdict, reason, mv.details)


def score_recording(path: str | Path, case: TestCase | None = None) -> tuple[TestCase, RunResult]:
    """Judge a recording file (against its attached case unless ``case`` is given)."""
    run = load_run(path)
    case = case or case_of(run)
    return case, score_run(run, case)


def _ratio(c: Criterion, mine: RunValue, base: RunValue) -> RunValue:
    if Verdict.NA in (mine.verdict, base.verdict):
        return RunValue(mine.seed, math.nan, Verdict.NA, mine.reason or base.reason)
    if mine.verdict is Verdict.ERROR or base.verdict is Verdict.ERROR:
        return RunValue(mine.seed, math.nan, Verdict.ERROR, mine.reason or base.reason)
    if math.isnan(mine.value) or math.isnan(base.value):
        return RunValue(mine.seed, math.nan, Verdict.FAIL, mine.reason or base.reason)
    value = mine.value / base.value if base.value != 0.0 else (0.0 if mine.value == 0.0 else math.inf)
    verdict, _ = judge_value(c.limit, c.band(), value)
    return RunValue(mine.seed, value, verdict, "", {"value": mine.value, "baseline": base.value})


_CANNOT_TELL = "meets the limit on the negative control: the criterion cannot tell the DUT from one without " \
    "what it checks"


def _inverted(c: Criterion, margin: float) -> tuple[Verdict, str]:
    """A control's verdict from its margin against the limit (positive: meets it)."""
    if margin >= 0.0:
        return Verdict.FAIL, _CANNOT_TELL
    if -margin < c.band():
        return Verdict.MARGINAL, "fails on the negative control only inside the marginal band"
    return Verdict.PASS, "fails on the negative control, as it must"


def _control(c: Criterion, rv: RunValue) -> RunValue:
    """A negative control's run judged the other way round (module docstring)."""
    if rv.verdict in (Verdict.NA, Verdict.ERROR):
        return rv
    if math.isnan(rv.value):  # its output could not be measured: no evidence either way
        return RunValue(rv.seed, rv.value, Verdict.FAIL, f"the control could not be measured: {rv.reason}")
    _, margin = judge_value(c.limit, 0.0, rv.value)
    if math.isnan(margin):
        return RunValue(rv.seed, rv.value, Verdict.ERROR, "metric undefined (NaN)")
    verdict, reason = _inverted(c, margin)
    return RunValue(rv.seed, rv.value, verdict, reason, rv.details)


def _controls(c: Criterion, values: list[RunValue], runs: list[RunValue] | None = None) -> Aggregate:
    """A negative control's runs judged together (module docstring); ``runs``: each of
    ``values`` as :func:`_control` judged it, if the caller has them.

    In Monte Carlo mode ``each`` every run of the control must FAIL the limit beyond the
    band: the worst control run decides, and the value shown is the control run nearest to
    passing. In the other modes the control's aggregate over its runs (the mean, the
    percentile bound, the passing count), computed as for the DUT, must FAIL. The margin
    is how far the control fails (positive when it does)."""
    if not values:
        return Aggregate(math.nan, Verdict.ERROR, math.nan, "no run of the negative control to judge")
    if c.monte_carlo.mode != "each":
        agg = aggregate_runs(c, values)
        if agg.verdict in (Verdict.ERROR, Verdict.NA):
            return agg
        if not agg.verdict.passed and (math.isnan(agg.value) or math.isnan(agg.margin)):
            return Aggregate(agg.value, Verdict.FAIL, math.nan, f"the control could not be measured: {agg.reason}")
        verdict, reason = _inverted(c, agg.margin)
        if verdict is Verdict.FAIL:
            reason = f"{reason} ({c.monte_carlo.text(len(values))})"
        if agg.details:  # the ANEES mode: what it measured on the control
            reason = f"{reason}; {agg.reason}"
        return Aggregate(agg.value, verdict, -agg.margin, reason, agg.details)
    if runs is None:
        runs = [_control(c, rv) for rv in values]
    judged = [r for r in runs if r.verdict is not Verdict.NA]
    if not judged:  # not applicable to any run (a latency in lockstep)
        return Aggregate(math.nan, Verdict.NA, math.nan, values[0].reason)
    worst_run = max(judged, key=lambda r: r.verdict.rank)
    measured = [r for r in judged if not math.isnan(r.value)]
    if worst_run.verdict is Verdict.ERROR or not measured:
        return Aggregate(math.nan, worst_run.verdict, math.nan, worst_run.reason or "not measured")
    nearest = max(measured, key=lambda r: judge_value(c.limit, 0.0, r.value)[1])
    margin = -judge_value(c.limit, 0.0, nearest.value)[1]
    return Aggregate(nearest.value, worst_run.verdict, margin, worst_run.reason)


def unjudged_requirements(case: TestCase, criteria: list[CriterionResult]) -> list[str]:
    """Why the case cannot PASS for its coverage: each requirement it names that no
    criterion judged -- none names it, or every result of the criteria that do is N/A (a
    negative control judges the criterion, not the DUT: it does not count) -- and the case
    does not waive (``[case] waived``)."""
    out = []
    for req in case.requirements:
        if req in case.waived:
            continue
        mine = [cr for cr in criteria if req in cr.criterion.requirements and not cr.control]
        if any(cr.verdict is not Verdict.NA for cr in mine):
            continue
        if not mine:
            why = "no criterion of the case names it"
        else:
            ids = ", ".join(dict.fromkeys(cr.label for cr in mine))
            reason = next((cr.aggregate.reason for cr in mine if cr.aggregate.reason), "")
            why = f"its criteria ({ids}) were all N/A" + (f": {reason}" if reason else "")
        out.append(f"requirement {req} not judged: {why} (judge it, or waive it in [case] waived with the reason)")
    return out


def judge_case(case: TestCase, runs: list[RunResult], errors: list[str] | None = None) -> CaseResult:
    """Combine the runs of a case into per-criterion and case verdicts."""
    out = CaseResult(case.id, case.title, case.file_name, case.requirements, Verdict.PASS, runs=runs, case=case)
    out.errors = list(errors or [])
    out.waived = waivers(case.scoring)
    variants = case.variants()
    for c in case.criteria:
        targets = [c.variant] if c.variant is not None else [v for v in variants if v not in c.must_fail_on]
        for v in targets:
            mine = [r for r in runs if r.variant == v]
            if c.relative_to is None:
                values = [r.values[c.id] for r in mine if c.id in r.values]
            else:
                base = {r.seed: r for r in runs if r.variant == c.relative_to}
                values = []
                for r in mine:
                    if r.seed in base and c.id in r.raw and c.id in base[r.seed].raw:
                        values.append(_ratio(c, r.raw[c.id], base[r.seed].raw[c.id]))
                    else:
                        why = f"no {c.relative_to} run with seed {r.seed}"
                        values.append(RunValue(r.seed, math.nan, Verdict.ERROR, why))
            out.criteria.append(CriterionResult(c, v, aggregate_runs(c, values), values))
        for v in c.must_fail_on:
            values = [r.raw[c.id] for r in runs if r.variant == v and c.id in r.raw]
            judged = [_control(c, rv) for rv in values]
            out.criteria.append(CriterionResult(c, v, _controls(c, values, judged), judged, control=True))
    out.errors += unjudged_requirements(case, out.criteria) if runs else []
    verdicts = [cr.verdict for cr in out.criteria] + [r.verdict for r in runs]
    if out.errors or not runs:
        verdicts.append(Verdict.ERROR)
    out.verdict = worst(verdicts)
    own = [cr.verdict for cr in out.criteria if not cr.criterion.id.startswith(PREFIX)]
    if out.verdict is Verdict.NA or (own and all(v is Verdict.NA for v in own)):
        # nothing the case asks for was judged (the bench's integrity defaults are no
        # verdict on the case's requirements): never a PASS
        out.errors.append("no criterion of the case applies to its runs (all N/A)")
        out.verdict = Verdict.ERROR
    return out
