"""``bench compare`` shown: a text table for terminals and a self-contained HTML page.

Everything from a record (DUT names, reasons, identification) is DUT- or user-provided
text: the text table passes it through :func:`~bench.textsafe.for_terminal`, the HTML
page through a Jinja2 template with autoescaping on (and the same control-character
filter), so a ``<script>`` in a DUT name is shown, never run.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from bench.atomic import write_atomic
from bench.report.compare import (
    COMMON,
    INCOMPARABLE,
    MISSING,
    NEW,
    NOT_COMPARABLE,
    NOT_COMPARED,
    RUNS,
    SAME,
    SCHEMA,
    VALUE,
    CaseRow,
    Comparison,
    Record,
    Row,
)
from bench.report.html import render_string
from bench.report.results import num
from bench.textsafe import for_terminal

__all__ = ["identification", "fmt", "seed_lines", "case_lines", "verdict_line", "text_report", "to_json",
           "html_report", "write_html"]

#: Keys of a record's ``identification`` shown at the top (others are in compare.json).
_SKIP = ("sha256", "inputs", "files", "seeds", "hash")


def _flat(obj: Any, prefix: str = "") -> list[tuple[str, str]]:
    if isinstance(obj, dict):
        out = []
        for k, v in obj.items():
            if any(s in str(k).lower() for s in _SKIP):
                continue
            out.extend(_flat(v, f"{prefix}{k}."))
        return out
    if isinstance(obj, list):
        return [] if not obj or isinstance(obj[0], dict | list) else [(prefix.rstrip("."), ", ".join(map(str, obj)))]
    return [] if obj is None else [(prefix.rstrip("."), str(obj))]


def identification(r: Record, limit: int = 12) -> list[tuple[str, str]]:
    """What the record says about itself: its file, the ``identification`` block if any
    (scalars, no hashes), the start time, the suite verdict and the DUTs of its cases."""
    out = [("results", r.path)]
    out.extend(_flat(r.data.get("identification") or {})[:limit])
    info = r.data.get("run_info")
    if isinstance(info, dict) and info.get("started_utc"):
        out.append(("started", str(info["started_utc"])))
    out.append(("verdict", str(r.data.get("verdict", "?"))))
    duts = []
    for c in r.cases.values():
        d = c.get("dut")
        if isinstance(d, dict):
            name = " ".join(str(d[k]) for k in ("kind", "name") if d.get(k))
            if name and name not in duts:
                duts.append(name)
    if duts:
        out.append(("DUT", ", ".join(duts)))
    return out


def fmt(x: float | None, signed: bool = False) -> str:
    """A value for a table: 4 significant digits, ``inf``, ``n/a`` for unmeasured."""
    if x is None:
        return "n/a"
    if math.isinf(x):
        return ("+" if signed and x > 0 else "") + ("inf" if x > 0 else "-inf")
    return f"{x:+.4g}" if signed else f"{x:.4g}"


def _rel(x: float | None) -> str:
    return "" if x is None else f"{100 * x:+.1f} %"


def _verdicts(r: Row) -> str:
    if r.verdict_change is None:
        return r.verdict_b or r.verdict_a or ""
    return f"{r.verdict_a} -> {r.verdict_b}"


def _status(r: Row) -> str:
    if r.status == SAME and r.verdict_change == "worse" and r.basis == VALUE:
        return "REGRESSION (verdict)"
    return r.status


def _basis(r: Row) -> str:
    """The table's ``on`` column: what the row was compared on (empty: its value, same seeds)."""
    if r.basis == COMMON:
        return "seeds " + ", ".join(str(s) for s in r.seeds_a if s in r.seeds_b)
    if r.basis == RUNS:
        return f"{len(r.seeds_a)}+{len(r.seeds_b)} runs, p={r.p_value:.2g}" if r.p_value is not None else "runs"
    if r.basis == INCOMPARABLE:
        return "seeds differ"
    if r.status == NOT_COMPARED:
        return r.note
    return ""


HEADER = ("case", "variant", "criterion", "unit", "A", "B", "delta", "rel", "tol", "status", "on", "verdict")


def _cells(r: Row) -> tuple[str, ...]:
    variant = (r.variant or "") + (" (control)" if r.control else "")
    unit = "" if r.unit == "1" else r.unit
    tol = "" if r.tolerance is None else fmt(r.tolerance) + ("" if r.tolerance_source == "default" else " *")
    return (r.case, variant, r.criterion, unit, fmt(r.a) if r.status != NEW else "-",
            fmt(r.b) if r.status != MISSING else "-", fmt(r.delta, True) if r.delta is not None else "",
            _rel(r.relative_delta), tol, _status(r), _basis(r), _verdicts(r))


def _clip(s: str, n: int) -> str:
    return s if len(s) <= n else s[: n - 1] + "…"


def _table(rows: list[tuple[str, ...]], width: int) -> list[str]:
    rows = [tuple(_clip(for_terminal(c), width) for c in r) for r in rows]
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = []
    for k, r in enumerate(rows):
        lines.append("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return lines


def _where(case: str, variant: str | None) -> str:
    return f"{case}/{variant}" if variant else case


def seed_lines(cmp: Comparison) -> list[str]:
    """The seed sets: one line saying they match, or each case and variant whose seeds
    differ and what its criteria were compared on."""
    differ = [(c.case, *s) for c in cmp.cases for s in c.seeds]
    if not differ:
        both = [c for c in cmp.cases if c.status == SAME]
        return ["seeds: the same in every case and variant compared"] if both else []
    what = {COMMON: "compared on the common seeds only", RUNS: "judged over runs",
            INCOMPARABLE: "not comparable (never a regression)"}
    out = [f"seed sets differ in {len(differ)} case variant(s): differences between other seeds are "
           "seed-to-seed variation, not compared value for value:"]
    out += [f"  {_where(cid, v)}: A seeds {_seed(sa)}; B seeds {_seed(sb)} -- {what[basis]}"
            for cid, v, sa, sb, basis in differ]
    return [for_terminal(x) for x in out]


def _seed(seeds: list[int]) -> str:
    return ", ".join(map(str, seeds)) or "none"


def _case_line(c: CaseRow) -> list[str]:
    out = []
    if c.status == NOT_COMPARED:
        out.append(f"case {c.case}: not compared (in {c.side}): {c.verdict_a or '-'} -> {c.verdict_b or '-'}")
    elif c.verdict_change:
        judged = "" if c.like else " (not judged: its variants or seeds differ)"
        out.append(f"case {c.case}: case verdict {c.verdict_change}: {c.verdict_a} -> {c.verdict_b}{judged}")
    out += [f"case {_where(c.case, v) if v else c.case + ' (its criteria without variant)'}: not compared (in {side})"
            for v, side in c.variants]
    return out


def case_lines(cmp: Comparison) -> list[str]:
    """Cases and variants on one side only, and case verdict changes."""
    return [for_terminal(x) for c in cmp.cases for x in _case_line(c)]


def verdict_line(cmp: Comparison) -> str:
    """The last line: ``REGRESSION (n)``, ``no regression`` or, when no criterion could be
    compared like with like, ``nothing compared like with like ...``."""
    s = cmp.summary()
    if cmp.regressed:
        return f"REGRESSION ({s['regressions']})"
    worse = sum(r.status == NOT_COMPARABLE and r.verdict_change == "worse" for r in cmp.rows)
    also = f", {worse} of them with a worse verdict in B" if worse else ""
    if not cmp.compared:
        return ("nothing compared like with like: no criterion was run on the same case, variant and seeds "
                f"(or over enough runs) in A and B ({s['not_comparable']} not comparable{also})")
    if s["not_comparable"]:
        return (f"no regression among the {s['compared']} criteria compared like with like "
                f"({s['not_comparable']} not comparable: seed sets differ{also})")
    return "no regression"


def text_report(cmp: Comparison, changes_only: bool = False, width: int = 40) -> str:
    """The comparison for a terminal: identification, the seed sets, the criteria table
    (every row, or only those that changed or were not compared), verdict changes, cases
    and variants on one side only, a summary line and the verdict line."""
    out = []
    ia, ib = identification(cmp.a), identification(cmp.b)
    for label, ident in (("A", ia), ("B", ib)):
        out.append(f"{label}: " + "; ".join(for_terminal(f"{k} {v}") for k, v in ident))
    out += seed_lines(cmp)
    shown = [r for r in cmp.rows if not changes_only or r.status != SAME or r.verdict_change]
    out += ["", *_table([HEADER, *map(_cells, shown)], width)] if shown else ["", "(no criterion changed)"]
    out.append("(tol: the tolerance applied, display unit; * from the case or the command line; "
               "on: what was compared when the seeds differ)")
    changed = [r for r in cmp.rows if r.verdict_change]
    if changed:
        out += ["", "verdict changes:"]
        out += [for_terminal(f"  {r.verdict_change:<7} {r.label}: {r.verdict_a} -> {r.verdict_b}"
                             + (f" ({r.reason_b})" if r.reason_b else "")
                             + ("" if r.basis == VALUE else f" [{r.basis}: {r.note}]")) for r in changed]
    out += case_lines(cmp)
    s = cmp.summary()
    out += ["", f"{s['criteria']} criteria, {s['compared']} compared like with like: {s['worse']} worse, "
            f"{s['better']} better, {s['same']} same, {s['controls_changed']} controls changed, "
            f"{s['missing_in_b']} missing in B, {s['new_in_b']} new in B; {s['not_comparable']} not comparable "
            f"(seed sets differ), {s['not_compared']} not compared (variant on one side only); "
            f"{s['verdict_changes']} verdict changes ({s['verdicts_worse']} worse, judged); cases: "
            f"{s['cases_missing_in_b']} in A only, {s['cases_new_in_b']} in B only (not compared)",
            verdict_line(cmp)]
    return "\n".join(out)


def to_json(cmp: Comparison) -> dict[str, Any]:
    """The comparison as JSON (``compare.json``): infinities as strings, as in results."""
    def side(r: Record) -> dict[str, Any]:
        return {"path": r.path, "verdict": r.data.get("verdict"), "counts": r.data.get("counts"),
                "identification": dict(identification(r))}

    def clean(d: dict[str, Any]) -> dict[str, Any]:
        return {k: num(v) if isinstance(v, float) else v for k, v in d.items()}

    return {
        "schema": SCHEMA,
        "regression": cmp.regressed,
        "compared": cmp.compared,
        "a": side(cmp.a),
        "b": side(cmp.b),
        "settings": cmp.settings,
        "summary": cmp.summary(),
        "cases": [clean(vars(c)) for c in cmp.cases],
        "criteria": [clean(vars(r)) | {"regression": r.regression} for r in cmp.rows],
    }


def html_report(cmp: Comparison) -> str:
    """The comparison as one self-contained HTML page (no scripts, no external files)."""
    return render_string(
        TEMPLATE,
        {"safe_text": lambda s: for_terminal("" if s is None else s, keep="\n\t")},
        cmp=cmp,
        ident=[("A", identification(cmp.a)), ("B", identification(cmp.b))],
        summary=cmp.summary(),
        rows=[(r, _cells(r)) for r in cmp.rows],
        changed=[r for r in cmp.rows if r.verdict_change],
        cases=[c for c in cmp.cases if c.status != SAME or c.verdict_change or c.variants],
        seeds=seed_lines(cmp),
        verdict=verdict_line(cmp),
        header=HEADER,
    )


def write_html(cmp: Comparison, path: str | Path) -> Path:
    return write_atomic(path, html_report(cmp))  # whole or not at all (bench.atomic)


TEMPLATE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>bench compare: {{ verdict | safe_text }}</title>
<style>
body { font-family: sans-serif; margin: 1.5em; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: left; vertical-align: top; }
th { background: #eee; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.REGRESSION, tr.MISSING, tr.worse { background: #fdd; }
tr.IMPROVEMENT { background: #dfd; }
tr.NEW, tr.CHANGED, tr.changed { background: #ffd; }
tr.NOT-COMPARABLE, tr.NOT-COMPARED { background: #eee; color: #555; }
.verdict { font-size: 1.4em; font-weight: bold; }
.bad { color: #b00; } .good { color: #070; }
</style></head>
<body>
<h1>bench compare</h1>
<p class="verdict {{ 'bad' if cmp.regressed or not cmp.compared else 'good' }}">{{ verdict | safe_text }}</p>
<h2>Identification</h2>
<table><tr><th>A (reference)</th><th>B (compared)</th></tr><tr>
{% for side, items in ident %}
<td><dl>{% for k, v in items %}<dt>{{ k | safe_text }}</dt><dd>{{ v | safe_text }}</dd>{% endfor %}</dl></td>
{% endfor %}
</tr></table>
{% if seeds %}
<h2>Seeds</h2>
<pre>{% for line in seeds %}{{ line | safe_text }}
{% endfor %}</pre>
{% endif %}
<h2>Summary</h2>
<table>{% for k, v in summary.items() %}
<tr><th>{{ k | replace('_', ' ') }}</th><td class="num">{{ v }}</td></tr>{% endfor %}</table>
<p>Tolerances: relative {{ '%.4g' % (100 * cmp.settings.rel_tol) }} % of A by default, at least
{{ '%.4g' % (100 * cmp.settings.floor) }} % of the limit; a tolerance marked * is the case's or the command line's.
Only like is compared with like: a case or variant on one side only is not compared; a criterion whose seeds differ
is compared on the seeds both ran, or judged over runs ({{ cmp.settings.min_runs }} or more each side, significance
{{ cmp.settings.alpha }}), or not comparable -- never a regression.</p>
{% if changed %}
<h2>Verdict changes</h2>
<table><tr><th>criterion</th><th>change</th><th>A</th><th>B</th><th>reason in B</th></tr>
{% for r in changed %}
<tr class="{{ r.verdict_change if r.judged else 'NOT-COMPARABLE' }}"><td>{{ r.label | safe_text }}</td>
<td>{{ r.verdict_change }}{% if not r.judged %} ({{ r.basis }}){% endif %}</td>
<td>{{ r.verdict_a }}</td><td>{{ r.verdict_b }}</td><td>{{ r.reason_b | safe_text }}</td></tr>
{% endfor %}
</table>
{% endif %}
{% if cases %}
<h2>Cases</h2>
<table><tr><th>case</th><th>status</th><th>A</th><th>B</th><th>DUT A</th><th>DUT B</th></tr>
{% for c in cases %}
<tr class="{{ c.status | replace(' ', '-') }} {{ c.verdict_change if c.like else '' }}">
<td>{{ c.case | safe_text }}</td>
<td>{{ c.status }}{% if c.side %} (in {{ c.side }}){% endif %}
{%- if c.verdict_change %} (verdict {{ c.verdict_change }}
{%- if not c.like %}, not judged: variants or seeds differ{% endif %}){% endif %}
{% for v, side in c.variants %}<br>variant {{ v | safe_text }}: not compared (in {{ side }}){% endfor %}</td>
<td>{{ c.verdict_a or '-' }}</td><td>{{ c.verdict_b or '-' }}</td>
<td>{{ c.dut_a | safe_text }}</td><td>{{ c.dut_b | safe_text }}</td></tr>
{% endfor %}
</table>
{% endif %}
<h2>Criteria</h2>
<table><tr>{% for h in header %}<th>{{ h }}</th>{% endfor %}<th>reason (A / B)</th></tr>
{% for r, cells in rows %}
<tr class="{{ r.status | replace(' ', '-') }} {{ r.verdict_change if r.judged else '' }}">{% for c in cells %}
<td{% if loop.index in (5, 6, 7, 8, 9) %} class="num"{% endif %}>{{ c | safe_text }}</td>{% endfor %}
<td>{{ r.reason_a | safe_text }}{% if r.reason_a or r.reason_b %} / {% endif %}{{ r.reason_b | safe_text }}
{%- if r.note %}<br><small>{{ r.note | safe_text }}</small>{% endif %}</td></tr>
{% endfor %}
</table>
</body></html>
"""
