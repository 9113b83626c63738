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
from collections.abc import Mapping, Sequence
from functools import cache
from importlib.resources import files
from typing import Any

import jinja2

from bench.report.model import fmt_num
from bench.textsafe import xml_safe

__all__ = ["render_html", "SETUP_KEYS"]

#: Keys of a run's identity shown as its setup, in this order.
SETUP_KEYS = ("dut", "clock", "links", "sensors", "faults", "inputs")


def _setup(identity: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k in SETUP_KEYS:
        v = identity.get(k)
        if v in (None, {}, []):
            continue
        if isinstance(v, list) and v and isinstance(v[0], Mapping):
            v = {str(i + 1): _flat(x) for i, x in enumerate(v)}
        out[k] = v
    return out


def _flat(x: Mapping[str, Any]) -> str:
    return ", ".join(f"{k} {fmt_num(v) if not isinstance(v, dict | list) else json.dumps(v)}" for k, v in x.items())


def _shown(v: Any) -> Any:
    """Every text a template shows: characters HTML cannot carry (NUL, ESC, lone
    surrogates: a crashed DUT's last lines) made visible; markup is escaped after this."""
    if isinstance(v, str) and not hasattr(v, "__html__"):  # not already markup (the style sheet)
        return xml_safe(v)
    return v


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
    return env


def render_html(
    model: Mapping[str, Any],
    figures: Mapping[str, Sequence[Any]] | None = None,
    *,
    generated_utc: str = "",
    command: str = "",
    rescore_command: str = "",
) -> str:
    """The page for ``model`` (:func:`bench.report.model.report_model`); ``figures`` per
    case id: objects with ``key``, ``title``, ``png``, ``alt`` and ``caption``."""
    cases = []
    for c in model["cases"]:
        figs = [
            {"key": f.key, "title": f.title, "alt": f.alt, "caption": f.caption,
             "b64": base64.b64encode(f.png).decode("ascii")}
            for f in (figures or {}).get(c["id"], [])
        ]
        cases.append({**c, "figures": figs})
    css = files("bench.report").joinpath("templates", "report.css").read_text("utf-8")
    return _env().get_template("report.html.j2").render(
        m={**model, "cases": cases},
        css=css,
        generated_utc=generated_utc,
        command=command,
        rescore_command=rescore_command,
        setup=_setup,
    )
