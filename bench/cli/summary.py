"""The summary ``bench accept`` and ``bench run`` print at the end (stdout), for a person.

A suite of nine reference cases judges some 370 criteria, most of them the default
``INTEGRITY-*`` checks at zero; a table of every one buries the few that matter. The
terminal therefore shows:

* the suite's interruption first, when it was interrupted;
* one line per case (verdict, title, DUT, its first problem);
* a table of the criteria that are not PASS (MARGINAL, FAIL, ERROR, N/A), the criteria of
  a case that all failed for one reason (a case whose run never started) as one row;
* why each was not a pass (one line per reason, criteria sharing it named together);
* the runs' notes;
* one line counting the rest: how many criteria PASSed, how many of them integrity
  checks, and where every row is (``summary.txt``, ``results.json``, when written).

``summary.txt``/``summary.md`` keep the full table (:mod:`bench.report.table`). Every
DUT-provided text goes through :func:`~bench.textsafe.for_terminal`.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path

from bench.acceptance.integrity_criteria import PREFIX as INTEGRITY_PREFIX
from bench.acceptance.interrupted import Interruption
from bench.acceptance.judge import CaseResult, CriterionResult
from bench.acceptance.verdict import Verdict
from bench.report.table import case_lines, fixed_width, note_lines, reason_groups, summary_rows
from bench.textsafe import for_terminal

__all__ = ["terminal_summary", "ORDER"]

#: The order verdicts are counted in.
ORDER = (Verdict.PASS, Verdict.MARGINAL, Verdict.FAIL, Verdict.ERROR, Verdict.NA)

#: Criteria of one case failing for one reason shown as one row from this many.
COLLAPSE = 3


def _clip(s: str, n: int = 40) -> str:
    return s if len(s) <= n else s[: n - 1] + "…"


def _names(ids: Sequence[str], shown: int = 4) -> str:
    if len(ids) <= shown:
        return ", ".join(ids)
    return f"{', '.join(ids[:shown])} and {len(ids) - shown} more"


def _listed(cases: Sequence[CaseResult]) -> tuple[list[tuple[str, ...]], list[str], Counter, int, int]:
    """The rows and reason lines of the criteria not PASS, the count of every verdict,
    and how many criteria PASSed (how many of them integrity checks)."""
    rows: list[tuple[str, ...]] = []
    reasons: list[str] = []
    counts: Counter = Counter()
    passed = integrity = 0
    for cr in cases:
        table = summary_rows([cr])
        if not cr.criteria:  # nothing judged: the case's own row
            if cr.verdict is not Verdict.PASS:
                rows.append(table[0])
            continue
        bad: list[tuple[CriterionResult, tuple[str, ...]]] = []
        for res, row in zip(cr.criteria, table, strict=True):
            counts[res.verdict] += 1
            if res.verdict is Verdict.PASS:
                passed += 1
                integrity += res.criterion.id.startswith(INTEGRITY_PREFIX)
            else:
                bad.append((res, row))
        same = {(str(res.verdict), res.aggregate.reason or "") for res, _ in bad}
        if len(bad) >= COLLAPSE and len(bad) == len(cr.criteria) and len(same) == 1:
            verdict = str(bad[0][0].verdict)
            reqs = ", ".join(dict.fromkeys(r for _, row in bad for r in row[3].split(", ") if r))
            rows.append((cr.case_id, "", f"all {len(bad)} criteria", reqs, "", "", "", "", verdict))
        else:
            rows += [row for _, row in bad]
        groups = reason_groups(cr, [res for res, _ in bad])
        for (verdict, reason), labels in groups.items():
            which = labels[0] if len(labels) == 1 else f"{_names(labels)} ({len(labels)} criteria)"
            reasons.append(f"  {cr.case_id} {which}: {verdict}: {reason}")
    return rows, reasons, counts, passed, integrity


def _count(counts: Counter) -> str:
    total = sum(counts.values())
    parts = [f"{counts[v]} {v}" for v in ORDER if counts[v] or v is Verdict.PASS]
    return f"{total} criteria: {', '.join(parts)}"


def terminal_summary(
    cases: Sequence[CaseResult],
    interrupted: Interruption | None = None,
    written: Mapping[str, Path] | None = None,
) -> str:
    """The end-of-run summary of ``cases`` (module docstring); ``written`` the reports
    written by kind (``summary``, ``json``...), named as where every criterion is."""
    rows, reasons, counts, passed, integrity = _listed(cases)
    out: list[str] = []
    if interrupted is not None:
        out += [for_terminal(interrupted.headline()), ""]
    out += [for_terminal(line) for line in case_lines(cases)]
    if rows:
        out += ["", _count(counts)]
        not_pass = sum(counts[v] for v in ORDER if v is not Verdict.PASS)
        out += ["", f"Criteria not PASS ({not_pass}):", *fixed_width(rows)]
        out += [for_terminal(line) for line in reasons]
    notes = [for_terminal(line) for line in note_lines(cases)]
    if notes:
        out += ["", *notes]
    where = [str(p) for k, p in (written or {}).items() if k in ("summary", "json")]
    rest = f"{passed} criteria PASS, not listed" if rows else f"All {passed} criteria PASS"
    rest += f" ({integrity} of them default integrity checks)" if integrity else ""
    rest += f"; every criterion is in {' and '.join(where)}" if where else ""
    if passed:
        out += ["", rest + "."]
    return "\n".join(out)
