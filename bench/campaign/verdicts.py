"""The verdict of each case of a campaign, judged over its runs as ``bench accept`` judges.

A run's own verdict (its record) is only part of a case's: a criterion's Monte Carlo mode
(at least k runs, a percentile at a confidence, the mean of the runs) is judged over the
runs, a comparison of two variants (``relative_to``) over the pairs of runs with the same
seed, a negative control (``must_fail_on``) the other way round. :func:`judge_groups`
rebuilds each run's outcomes from its record and judges every case (at every sweep point)
with :func:`bench.acceptance.judge.judge_case`, the function ``bench accept`` uses, over
every run the campaign planned for it: a run without a record, or a record without a
criterion its run judges, makes the case ERROR (never a verdict on fewer runs than asked).
A case judged ERROR says why in its ``errors`` (:func:`error_reasons`): besides those
reasons, its runs recorded ERROR with their reasons and its criteria judged ERROR with
theirs.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

from bench.acceptance.case import TestCase
from bench.acceptance.criteria import RunValue
from bench.acceptance.judge import RunResult, judge_case
from bench.acceptance.verdict import Verdict
from bench.campaign.plan import PlannedRun
from bench.campaign.sweep import case_at, point_label

__all__ = ["judge_groups", "run_result", "missing_criteria", "error_reasons"]


def _value(c: Mapping[str, Any], seed: int) -> RunValue:
    v = c.get("value")
    series = c.get("series")  # the sampled NEES of a criterion judged by ANEES over the runs
    return RunValue(seed, math.nan if v is None else float(v), Verdict(c["verdict"]), c.get("reason") or "",
                    dict(series) if isinstance(series, Mapping) else {})


def run_result(rec: Mapping[str, Any]) -> RunResult:
    """A run's outcomes as :func:`bench.acceptance.judge.score_run` gave them, from its record
    (values SI; ``raw``: the values that feed comparisons and negative controls)."""
    seed = int(rec["seed"])
    return RunResult(
        str(rec.get("recording") or ""), rec["case_id"], rec.get("variant"), seed, Verdict(rec["verdict"]),
        list(rec.get("bench_issues") or []), list(rec.get("dut_issues") or []),
        values={cid: _value(c, seed) for cid, c in (rec.get("criteria") or {}).items()},
        raw={cid: _value(c, seed) for cid, c in (rec.get("raw") or {}).items()},
    )


def missing_criteria(case: TestCase, rec: Mapping[str, Any]) -> list[str]:
    """The criteria a judged run of its variant has that the record lacks (a damaged or
    foreign record: judging without them would judge the case on fewer runs)."""
    if rec.get("verdict") == "ERROR":
        return []  # a run that could not be judged has none, and makes its case ERROR anyway
    variant = rec.get("variant")
    values, raw = rec.get("criteria") or {}, rec.get("raw") or {}
    out = []
    for c in case.criteria:
        if c.relative_to is not None:
            wanted = raw if variant in (c.variant, c.relative_to) else None
        elif variant in c.must_fail_on:
            wanted = raw
        else:
            wanted = values if c.variant in (None, variant) else None
        if wanted is not None and c.id not in wanted:
            out.append(c.id)
    return out


def _seeds(seeds: list[int]) -> str:
    shown = ", ".join(map(str, seeds[:10]))
    return f"seed {shown}" if len(seeds) == 1 else f"seeds {shown}" + (f" and {len(seeds) - 10} more"
                                                                        if len(seeds) > 10 else "")


def error_reasons(cr: Any, recs: Iterable[Mapping[str, Any]]) -> list[str]:
    """What made a case ERROR besides the reasons it was given (``cr.errors``): its runs
    recorded ERROR, grouped by variant and reason (``run ERROR [variant] (seeds 1, 4):
    reason``), then its criteria judged ERROR (``criterion X [variant]: ERROR: reason``) for
    another reason than an ERROR run's."""
    runs: dict[tuple[str, str], list[int]] = {}
    for r in recs:
        if r.get("verdict") == "ERROR":
            why = "; ".join([*(r.get("bench_issues") or []), *(r.get("dut_issues") or [])]) or "no reason recorded"
            runs.setdefault((r.get("variant") or "", why), []).append(int(r["seed"]))
    out = [f"run ERROR{f' [{v}]' if v else ''} ({_seeds(sorted(seeds))}): {why}"
           for (v, why), seeds in sorted(runs.items())]
    said = {why for _, why in runs}
    for c in cr.criteria:
        if c.verdict is Verdict.ERROR and c.aggregate.reason not in said:
            variant = f" [{c.variant}]" if c.variant else ""
            out.append(f"criterion {c.criterion.id}{variant}: ERROR: {c.aggregate.reason or 'no reason given'}")
    return out


def _num(x: float) -> float | None:
    return None if math.isnan(x) else x


def judge_groups(plan: Iterable[PlannedRun], records: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """Per case and sweep point (``CASE{key=value}``): its verdict over the runs planned for
    it, each criterion's verdict per variant (value in the criterion's display unit), and
    why it could not be judged."""
    groups: dict[tuple[str, tuple[tuple[str, Any], ...]], list[PlannedRun]] = {}
    for run in plan:
        groups.setdefault((run.case_file, run.point), []).append(run)
    out: dict[str, Any] = {}
    for (case_file, point), runs in sorted(groups.items(), key=lambda g: (g[1][0].case_id, point_label(g[0][1]))):
        label = runs[0].case_id + point_label(point)
        try:
            case = case_at(case_file, point)
        except Exception as exc:  # the case file changed or went away since it was planned
            out[label] = {"case_id": runs[0].case_id, "sweep": [list(kv) for kv in point], "verdict": "ERROR",
                          "runs": len(runs), "errors": [f"the case could not be read again: {exc}"], "criteria": []}
            continue
        recs = [records[r.key] for r in runs if r.key in records]
        errors = []
        if len(recs) < len(runs):
            errors.append(f"{len(runs) - len(recs)} of {len(runs)} planned runs have no record: not judged on fewer")
        for r in recs:
            if lacking := missing_criteria(case, r):
                errors.append(f"the record of {r['key'][:16]} (seed {r['seed']}) lacks {', '.join(lacking)}")
        cr = judge_case(case, [run_result(r) for r in sorted(recs, key=lambda r: (r.get("variant") or "", r["seed"]))],
                        errors)
        why = list(cr.errors)
        if cr.verdict is Verdict.ERROR:
            why += [e for e in error_reasons(cr, recs) if e not in why]
        out[label] = {
            "case_id": case.id, "sweep": [list(kv) for kv in point], "verdict": cr.verdict.value, "runs": len(runs),
            "errors": why,
            "criteria": [
                {"id": c.criterion.id, "variant": c.variant, "control": c.control, "verdict": c.verdict.value,
                 "value": _num(c.criterion.display(c.aggregate.value)), "unit": c.criterion.unit,
                 "limit": c.criterion.limit.text(c.criterion.unit),
                 "monte_carlo": c.criterion.monte_carlo.text(len(c.runs)), "reason": c.aggregate.reason}
                | ({"anees": c.aggregate.details} if c.aggregate.details else {})
                for c in cr.criteria
            ],
        }
    return out
