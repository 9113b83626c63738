"""JUnit XML of an acceptance run, for CI systems and test-management tools.

One ``<testsuite>`` per test case; one ``<testcase>`` per criterion and variant
(``classname`` the case id, ``name`` the criterion id with its variant), carrying its
measurement as ``<property>`` elements named as the results record's criterion keys
(:mod:`bench.report.results`), in this order:

``requirement`` (one per requirement id), ``metric``, ``window``, ``window_text``,
``variant``, ``control``, ``comparator``, ``limit`` (text, display unit),
``limit_si.low``, ``limit_si.high``, ``unit``, ``marginal_band``, ``value`` (display
unit), ``value_si``, ``margin`` (display unit), ``verdict``, ``reason``, ``paper``,
``monte_carlo``, then per run (Monte Carlo seed) ``run.<seed>.value`` (display unit)
and ``run.<seed>.verdict``.

Numbers are written with full precision (``repr``: ``float(value)`` gives back the
record's number), an infinite one as ``inf``/``-inf``, a missing one as the empty
string; booleans as ``true``/``false``. The ``<testsuite>`` carries the case's
``title``, ``verdict``, ``requirement`` ids and, per run, ``recording.<file>.sha256``.
FAIL is a ``<failure>``, ERROR an ``<error>`` (never a failure); MARGINAL passes with
a ``verdict = MARGINAL`` property. A case that could not be loaded or run is a
testcase ``<load>`` with an ``<error>``.

A suite that was interrupted (Ctrl-C, SIGTERM) is marked by one more ``<testsuite
name="bench accept: interrupted">`` holding a testcase ``interrupted`` with an
``<error type="INTERRUPTED">`` naming the signal and the cases that did not finish or
were not run (each of which is also its own ERROR testsuite), so that no CI system can
read the file as a complete run.

Every text and attribute goes through :func:`~bench.textsafe.xml_safe`: ElementTree
escapes markup but writes NUL, ESC and lone surrogates raw, which makes the file
unparsable (a crashed DUT's last output lines are in the reasons).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

from bench.acceptance.interrupted import Interruption
from bench.acceptance.judge import CaseResult
from bench.acceptance.verdict import Verdict
from bench.atomic import atomic_file
from bench.report.identity import run_identity
from bench.report.results import criterion_json
from bench.textsafe import xml_safe

__all__ = ["junit_xml", "write_junit", "PROPERTIES"]


#: The criterion keys written as properties, in order (``requirement`` before, runs after).
PROPERTIES = ("metric", "window", "window_text", "variant", "control", "comparator", "limit", "limit_si.low",
              "limit_si.high", "unit", "marginal_band", "value", "value_si", "margin", "verdict", "reason",
              "paper", "monte_carlo")


def _fmt(v: object) -> str:
    """A message's number: six significant digits."""
    if isinstance(v, float):
        return f"{v:.6g}"
    return "" if v is None else str(v)


def _prop(v: object) -> str:
    """A property's value: full precision, ``true``/``false``, empty for none."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return "" if v is None else str(v)


def _flat(j: dict, key: str) -> object:
    head, _, tail = key.partition(".")
    return j[head][tail] if tail else j[key]


def junit_xml(cases: Sequence[CaseResult], name: str = "bench accept",
              interrupted: Interruption | None = None) -> ET.Element:
    """The ``<testsuites>`` element of an acceptance run (``interrupted``: marked so)."""
    root = ET.Element("testsuites", name=name)
    totals = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    if interrupted is not None:
        suite = ET.SubElement(root, "testsuite", name=f"{name}: interrupted", tests="1", failures="0", errors="1",
                              skipped="0")
        props = ET.SubElement(suite, "properties")
        ET.SubElement(props, "property", name="interrupted_by", value=interrupted.by)
        for key in ("finished", "unfinished", "not_run"):
            ET.SubElement(props, "property", name=key, value=", ".join(getattr(interrupted, key)))
        tc = ET.SubElement(suite, "testcase", classname=name, name="interrupted")
        text = interrupted.headline()
        ET.SubElement(tc, "error", message=text, type="INTERRUPTED").text = text
        totals["tests"] += 1
        totals["errors"] += 1
    for cr in cases:
        suite = ET.SubElement(root, "testsuite", name=cr.case_id, file=cr.file)
        props = ET.SubElement(suite, "properties")
        ET.SubElement(props, "property", name="title", value=cr.title)
        ET.SubElement(props, "property", name="verdict", value=str(cr.verdict))
        for r in cr.requirements:
            ET.SubElement(props, "property", name="requirement", value=r)
        for run in cr.runs:
            sha = (run_identity(run.recording).get("recording") or {}).get("sha256")
            if sha:
                ET.SubElement(props, "property", name=f"recording.{Path(run.recording).name}.sha256", value=sha)
        n = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
        per = cr.elapsed_s / max(1, len(cr.criteria))
        for res in cr.criteria:
            j = criterion_json(res)
            label = res.label
            tc = ET.SubElement(suite, "testcase", classname=cr.case_id, name=label, time=f"{per:.3f}")
            tp = ET.SubElement(tc, "properties")
            for r in res.criterion.requirements:
                ET.SubElement(tp, "property", name="requirement", value=r)
            for key in PROPERTIES:
                ET.SubElement(tp, "property", name=key, value=_prop(_flat(j, key)))
            for run in j["runs"]:
                ET.SubElement(tp, "property", name=f"run.{run['seed']}.value", value=_prop(run["value"]))
                ET.SubElement(tp, "property", name=f"run.{run['seed']}.verdict", value=_prop(run["verdict"]))
            message = (
                f"{res.criterion.metric} = {_fmt(j['value'])} {j['unit']} ({j['window']}), "
                f"limit {j['limit']}: {res.verdict}" + (f" -- {res.aggregate.reason}" if res.aggregate.reason else "")
            )
            n["tests"] += 1
            if res.verdict is Verdict.FAIL:
                ET.SubElement(tc, "failure", message=message, type="FAIL").text = message
                n["failures"] += 1
            elif res.verdict is Verdict.ERROR:
                ET.SubElement(tc, "error", message=message, type="ERROR").text = message
                n["errors"] += 1
            elif res.verdict is Verdict.NA:  # not applicable to this run: neither passed nor failed
                ET.SubElement(tc, "skipped", message=message, type="N/A").text = message
                n["skipped"] += 1
            else:
                ET.SubElement(tc, "system-out").text = message
        for req, why in (cr.case.waived.items() if cr.case is not None else ()):
            tc = ET.SubElement(suite, "testcase", classname=cr.case_id, name=f"requirement {req} (waived)")
            tp = ET.SubElement(tc, "properties")
            ET.SubElement(tp, "property", name="requirement", value=req)
            ET.SubElement(tc, "skipped", message=f"waived: {why}", type="WAIVED").text = f"waived: {why}"
            n["tests"] += 1
            n["skipped"] += 1
        problems = list(cr.errors) + [
            f"run {r.seed}{'/' + r.variant if r.variant else ''}: {'; '.join(r.bench_issues + r.dut_issues)}"
            for r in cr.runs
            if r.bench_issues or r.dut_issues
        ]
        if problems or not cr.criteria:
            tc = ET.SubElement(suite, "testcase", classname=cr.case_id, name="load")
            text = "\n".join(problems) or "no criterion was judged"
            kind = "error" if cr.verdict is Verdict.ERROR or cr.errors else "failure"
            ET.SubElement(tc, kind, message=text.splitlines()[0], type=str(cr.verdict)).text = text
            n["tests"] += 1
            n["errors" if kind == "error" else "failures"] += 1
        for k, v in n.items():
            suite.set(k, str(v))
            totals[k] += v
    for k, v in totals.items():
        root.set(k, str(v))
    for el in root.iter():
        if el.text:
            el.text = xml_safe(el.text)
        for k, v in el.attrib.items():
            el.set(k, xml_safe(v))
    return root


def write_junit(cases: Sequence[CaseResult], path: str | Path, interrupted: Interruption | None = None) -> Path:
    """Write the JUnit XML file, whole or not at all (:mod:`bench.atomic`)."""
    tree = ET.ElementTree(junit_xml(cases, interrupted=interrupted))
    ET.indent(tree)
    with atomic_file(path) as fh:
        tree.write(fh, encoding="utf-8", xml_declaration=True)
    return Path(path)
