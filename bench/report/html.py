"""The report as one self-contained HTML page (the one module using Jinja2).

Templates and style sheet live in ``bench/report/templates``; the style is inlined, the
figures are PNG data URIs, no font or script is loaded from anywhere: the file opens
from a disk with no network, and WeasyPrint renders the same page to PDF
(:mod:`bench.report.pdf`). Autoescaping is on: a DUT's name, log line or reason is text,
never markup, and its control characters are shown as escapes
(:func:`bench.textsafe.xml_safe`).
"""

from __future__ import annotations

import base64
import json
import re
from collections.abc import Mapping, Sequence
from functools import cache
from importlib.resources import files
from typing import Any

import jinja2
from markupsafe import Markup, escape

from bench.report.model import fmt_num
from bench.textsafe import xml_safe

__all__ = ["render_html", "render_string", "render_template", "setup_rows", "quality_cells"]

def _line(d: Mapping[str, Any] | None, skip: tuple[str, ...] = ()) -> str:
    """A mapping as one line: ``key value, ...`` (empty and null values left out)."""
    if not d:
        return "—"
    parts = []
    for k, v in d.items():
        if k in skip or v in (None, "", [], {}):
            continue
        if isinstance(v, Mapping):
            v = "{" + _line(v) + "}"
        elif isinstance(v, list | tuple):
            v = "[" + ", ".join(fmt_num(x) if not isinstance(x, Mapping | list) else json.dumps(x) for x in v) + "]"
        else:
            v = fmt_num(v)
        parts.append(f"{k} {v}")
    return ", ".join(parts) or "—"


def setup_rows(identity: Mapping[str, Any]) -> list[tuple[str, str]]:
    """A run's setup as (label, text) rows: DUT, clock, links, IMU, sensors, plant, faults,
    inputs with their sha256 (from the run's ``identity`` in the record)."""
    rows: list[tuple[str, str]] = []
    dut = identity.get("dut") or {}
    if dut:
        rows.append(("DUT", _line(dut)))
    setup = identity.get("setup") or {}
    if setup.get("clock"):
        rows.append(("clock", _line(setup["clock"])))
    for link in setup.get("links") or []:
        rows.append((f"link {link.get('name', '')}", _line(link, skip=("name",))))
    if setup.get("imu"):
        rows.append(("IMU", _line(setup["imu"], skip=("realised",))))
        if setup["imu"].get("realised"):
            rows.append(("IMU errors drawn (SI)", json.dumps(setup["imu"]["realised"], separators=(",", ":"))))
    for name, params in (setup.get("sensors") or {}).items():
        rows.append((f"sensor {name}", _line(params)))
    if setup.get("plant"):
        rows.append(("plant", _line(setup["plant"])))
    for f in setup.get("faults") or []:
        window = f"{fmt_num(f.get('start_s'))}–{fmt_num(f.get('end_s'))} s"
        what = f"{f.get('kind', '')} on {f.get('target', '')} ({f.get('layer', '')}), {window}"
        rows.append((f"fault {f.get('id', '')}", what + (f", {_line(f.get('params'))}" if f.get("params") else "")))
    for i in identity.get("inputs") or []:
        rows.append((f"input ({i.get('role', '')})", f"{i.get('name', '')}  sha256 {i.get('sha256') or '—'}"))
    rec = identity.get("recording") or {}
    if rec:
        size = fmt_num(rec.get("size"))
        rows.append(("recording", f"{rec.get('name', '')}  {size} B  sha256 {rec.get('sha256', '')}"))
    return rows


def quality_cells(run: Mapping[str, Any]) -> dict[str, str]:
    """One run's bench quality as three texts: real-time lateness, bad frames, integrity."""
    q = (run.get("identity") or {}).get("quality") or {}
    t = q.get("timing") or run.get("timing") or {}
    if t and t.get("count"):
        late = ", ".join(f"{k[:-3]} {fmt_num(t[k] / 1e3)}" for k in ("p50_ns", "p99_ns", "p999_ns", "max_ns")
                         if isinstance(t.get(k), int | float)) + f" µs over {fmt_num(t.get('count'))} emissions"
    else:
        late = "lockstep: not timed"
    by_kind = (q.get("bad_frames") or {}).get("by_kind") or {}
    bad = ", ".join(f"{k} {fmt_num(v)}" for k, v in by_kind.items()) or "none"
    integ = q.get("integrity") or {}
    if not integ:
        state = "—"
    elif integ.get("intact"):
        state = f"finished, intact ({integ.get('status', '')})"
    else:
        ended = "finished" if integ.get("finished") else "UNFINISHED"
        state = (f"{ended}, {fmt_num(integ.get('damaged_chunks'))} damaged chunk(s); "
                 f"{integ.get('status', '')} {integ.get('reason', '')}").strip()
    return {"lateness": late, "bad_frames": bad, "integrity": state}


def _shown(v: Any) -> Any:
    """Every text a template shows: characters HTML cannot carry (NUL, ESC, lone
    surrogates: a crashed DUT's last lines) made visible; markup is escaped after this."""
    if isinstance(v, str) and not hasattr(v, "__html__"):  # not already markup (the style sheet)
        return xml_safe(v)
    return v


def breakable(v: Any) -> Markup:
    """An identifier that a narrow column may break only after its separators (``-``,
    ``_``, ``.``, ``/``, ``,``), never inside a word: ``with_<wbr>detection``."""
    text = escape(xml_safe(str(v)))
    return Markup(re.sub(r"([-_./,])", r"\1<wbr>", str(text)))


@cache
def _env() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FunctionLoader(lambda name: files("bench.report").joinpath("templates", name).read_text("utf-8")),
        autoescape=True,
        undefined=jinja2.ChainableUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        finalize=_shown,
    )
    env.filters["num"] = fmt_num
    env.filters["breakable"] = breakable
    return env


def render_html(
    model: Mapping[str, Any],
    figures: Mapping[str, Sequence[Any]] | None = None,
    *,
    generated_utc: str = "",
    command: str = "",
    rescore_command: str = "",
    part: str = "all",
) -> str:
    """The page for ``model`` (:func:`bench.report.model.report_model`); ``figures`` per
    case id: objects with ``key``, ``title``, ``png``, ``alt`` and ``caption``. ``part``:
    the whole page (``"all"``), its front matter (``"front"``: identification, summary,
    coverage, reproduction, approval) or one case's section (its id), for the PDF's parts."""
    cases = []
    for c in model["cases"]:
        if part not in ("all", "front", c["id"]):
            continue
        figs = [
            {"key": f.key, "title": f.title, "alt": f.alt, "caption": f.caption,
             "b64": base64.b64encode(f.png).decode("ascii")}
            for f in ((figures or {}).get(c["id"], []) if part != "front" else [])
        ]
        cases.append({**c, "figures": figs})
    css = files("bench.report").joinpath("templates", "report.css").read_text("utf-8")
    return _env().get_template("report.html.j2").render(
        m={**model, "cases": cases},
        css=css,
        generated_utc=generated_utc,
        command=command,
        rescore_command=rescore_command,
        setup_rows=setup_rows,
        quality=quality_cells,
        line=_line,
        part=part,
    )


def render_template(name: str, **context: Any) -> str:
    """Render the package template ``name`` (``templates/<name>``) with the report's
    conventions (autoescape, control characters made visible, the ``num`` filter), the
    style sheet given as ``css``."""
    css = files("bench.report").joinpath("templates", "report.css").read_text("utf-8")
    return _env().get_template(name).render(css=css, **context)


def render_string(source: str, filters: Mapping[str, Any] | None = None, **context: Any) -> str:
    """Render a template given as text (``bench compare``'s page), autoescaped, every name
    it uses required (a missing one is an error, not an empty string)."""
    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters.update(filters or {})
    return env.from_string(source).render(**context)
