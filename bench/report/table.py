"""Summary tables of an acceptance run, for terminals (text) and documents (Markdown).

One row per criterion and variant: case, variant, criterion, requirement, what is
measured over which window, the value, the limit, the paper's figure and the verdict (a
negative control's row says ``(control)`` and ``must fail``: its PASS is the limit failing
it);
then one row per case with its verdict and what went wrong, and the runs' notes (what
was recorded without changing a verdict: a damaged source accepted, processes the DUT
left running). A suite that was interrupted says so on the first line (``INCOMPLETE: the
suite was interrupted by SIGINT; ...``).

The rows and lines are built raw; the text table shows them through
:func:`~bench.textsafe.for_terminal` and the Markdown one through
:func:`~bench.textsafe.for_markdown`, so DUT-provided text (a crashed DUT's last output
lines in a reason) can neither drive a terminal nor inject markup.
"""

from __future__ import annotations

from collections.abc import Sequence

from bench.acceptance.interrupted import Interruption
from bench.acceptance.judge import CaseResult, CriterionResult
from bench.report.results import criterion_json
from bench.textsafe import for_markdown, for_terminal

__all__ = ["summary_rows", "text_table", "markdown_table", "case_lines", "reason_lines", "note_lines"]

HEADER = ("case", "variant", "criterion", "requirement", "metric / window", "value", "limit", "paper", "verdict")


def _value(j: dict) -> str:
    v = j["value"]
    if v is None:
        return "n/a"
    if isinstance(v, str):
        return v
    unit = "" if j["unit"] == "1" else f" {j['unit']}"
    return f"{v:.4g}{unit}"


def summary_rows(cases: Sequence[CaseResult]) -> list[tuple[str, ...]]:
    rows: list[tuple[str, ...]] = []
    for cr in cases:
        if not cr.criteria:
            rows.append((cr.case_id, "", "-", ", ".join(cr.requirements), "(not judged)", "", "", "", str(cr.verdict)))
        for res in cr.criteria:
            j = criterion_json(res)
            what = f"{j['metric']} / {j['window']}"
            if j["relative_to"]:
                what += f" ÷ {j['relative_to']}"
            variant, limit = res.variant or "", j["limit"]
            if res.control:  # a negative control: PASS means the limit failed it, as it must
                what += " (negative control: must FAIL)"
                variant, limit = f"{variant} (control)", f"must fail {limit}"
            rows.append(
                (
                    cr.case_id,
                    variant,
                    res.criterion.id,
                    ", ".join(j["requirements"]),
                    what,
                    _value(j),
                    limit,
                    j["paper"],
                    str(res.verdict),
                )
            )
    return rows


def _clip(s: str, n: int) -> str:
    return s if len(s) <= n else s[: n - 1] + "…"


def fixed_width(rows: Sequence[tuple[str, ...]], width: int = 40) -> list[str]:
    """``rows`` under :data:`HEADER` as fixed-width lines (cells made safe for a terminal
    and clipped to ``width``), a rule under the header."""
    shown = [tuple(_clip(for_terminal(c), width) for c in r) for r in [HEADER, *rows]]
    widths = [max(len(r[i]) for r in shown) for i in range(len(HEADER))]
    lines = []
    for k, r in enumerate(shown):
        lines.append("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return lines


def text_table(cases: Sequence[CaseResult], width: int = 40, interrupted: Interruption | None = None) -> str:
    """A fixed-width table (long cells clipped to ``width``); a suite ``interrupted`` says so
    on the first line."""
    lines = fixed_width(summary_rows(cases), width)
    notes = [for_terminal(line) for line in (*case_lines(cases), *reason_lines(cases), *note_lines(cases))]
    head = [for_terminal(interrupted.headline()), ""] if interrupted is not None else []
    return "\n".join([*head, *lines, "", *notes])


def reason_groups(cr: CaseResult, results: Sequence[CriterionResult]) -> dict[tuple[str, str], list[str]]:
    """(verdict, reason) -> labels of the ``results`` of case ``cr`` that are FAIL, ERROR
    or N/A with a reason: criteria with the same verdict and reason share a line, and the
    run's problem that the case's line shows (a DUT that never started: its last output) is
    not repeated per criterion."""
    shown = [*cr.errors, *(i for r in cr.runs for i in r.bench_issues + r.dut_issues)][:1]
    groups: dict[tuple[str, str], list[str]] = {}
    for res in results:
        if res.aggregate.reason and res.verdict.value in ("FAIL", "ERROR", "N/A"):
            reason = res.aggregate.reason
            for problem in shown:
                reason = reason.replace(problem, "the run's problem above") if problem else reason
            groups.setdefault((str(res.verdict), reason), []).append(res.label)
    return groups


def reason_lines(cases: Sequence[CaseResult]) -> list[str]:
    """Why criteria were not a plain pass, one line each (empty when all passed plainly; raw
    text: escape it for where it is shown)."""
    out = []
    for cr in cases:
        for (verdict, reason), labels in reason_groups(cr, cr.criteria).items():
            many = f" ({len(labels)} criteria)" if len(labels) > 1 else ""
            out.append(f"  {cr.case_id} {', '.join(labels)}{many}: {verdict}: {reason}")
    return out


def _problems(cr: CaseResult) -> list[str]:
    """The case's errors and its runs' issues (``seed N: issue``), as its line counts them."""
    problems = list(cr.errors)
    for r in cr.runs:
        for issue in r.bench_issues + r.dut_issues:
            problems.append(f"seed {r.seed}{'/' + r.variant if r.variant else ''}: {issue}")
    return problems


def note_lines(cases: Sequence[CaseResult]) -> list[str]:
    """The runs' notes, one line each (raw text: escape it for where it is shown)."""
    return [f"  {cr.case_id} seed {r.seed}{'/' + r.variant if r.variant else ''}: note: {note}"
            for cr in cases for r in cr.runs for note in r.notes]


def case_lines(cases: Sequence[CaseResult]) -> list[str]:
    """One line per case: verdict, title, and the first problem if any (raw text)."""
    out = []
    for cr in cases:
        problems = _problems(cr)
        dut = ""
        if cr.case is not None:
            dut = f" [DUT: {cr.case.dut.kind}{' ' + cr.case.dut.names if cr.case.dut.names else ''}]"
        line = f"{cr.verdict!s:<8} {cr.case_id}: {cr.title}{dut}"
        if problems:
            line += f" -- {problems[0]}" + (f" (+{len(problems) - 1} more)" if len(problems) > 1 else "")
        out.append(line)
        if cr.case is not None:
            out.extend(f"         {cr.case_id}: requirement {req} waived: {why}" for req, why in cr.case.waived.items())
    return out


def markdown_table(cases: Sequence[CaseResult], interrupted: Interruption | None = None) -> str:
    """The same table in Markdown (an ``interrupted`` suite says so first, in bold)."""
    rows = summary_rows(cases)
    out = [f"**{for_markdown(interrupted.headline())}**", ""] if interrupted is not None else []
    out += ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    for r in rows:
        out.append("| " + " | ".join(for_markdown(c) for c in r) + " |")
    out.append("")
    out.extend(f"- {for_markdown(line)}" for line in case_lines(cases))
    out.extend(f"- {for_markdown(line.strip())}" for line in note_lines(cases))
    return "\n".join(out) + "\n"
