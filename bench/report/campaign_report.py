"""The campaign report: ``campaign_report.html`` and ``campaign_report.pdf`` of a campaign
folder, from its ``campaign.json`` alone (the aggregate and what the campaign planned).

Sections: identification (paths, planned, complete and missing runs, executor, bench
version, generated time; a campaign that is incomplete says so at the top), a summary
table per case group (runs, verdict counts, pass rate with its interval), per group a
table per criterion (limit, unit, runs, pass rate with interval, min, P50, P90 with its
bounds, P95, P99, max, the worst runs with seed and recording) with the figures of
:mod:`bench.report.campaign_figures`, and the sweeps (each criterion and the pass rate
against each swept parameter). The PDF is laid out in parts (front matter, one part per
group, the sweeps) by :mod:`bench.report.pdf`, every page footed as the certification
report's. Never imports :mod:`bench.campaign`: the aggregate is a dict.
"""

from __future__ import annotations

import base64
import concurrent.futures as cf
import datetime as _dt
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.atomic import write_atomic
from bench.report.build import pool_of
from bench.report.campaign_figures import figure_jobs
from bench.report.figures import Figure
from bench.report.html import render_template

__all__ = ["build_campaign_report", "campaign_model", "CampaignReportFiles", "HTML_NAME", "PDF_NAME"]

HTML_NAME = "campaign_report.html"
PDF_NAME = "campaign_report.pdf"
_VERDICTS = ("PASS", "MARGINAL", "FAIL", "ERROR", "N/A")


@dataclass
class CampaignReportFiles:
    """What :func:`build_campaign_report` wrote."""

    html: Path
    pdf: Path | None
    figures: dict[str, list[Figure]]


def _pct(c: Mapping[str, Any], name: str) -> dict[str, Any]:
    p = ((c.get("display") or {}).get("percentiles") or {}).get(name) or {}
    lo, hi = (p.get("interval") or [None, None])[:2]
    return {"value": p.get("value"), "low": lo, "high": hi}


def _criterion_row(cid: str, c: Mapping[str, Any]) -> dict[str, Any]:
    d = c.get("display") or {}
    return {
        "id": cid, "metric": c.get("metric"), "window": c.get("window"), "limit": c.get("limit_text"),
        "unit": "" if c.get("unit") in (None, "1") else c.get("unit"), "runs": c.get("runs"),
        "measured": c.get("measured"), "verdicts": c.get("verdicts") or {}, "pass_rate": c.get("pass_rate"),
        "interval": c.get("pass_rate_interval") or [None, None], "min": d.get("min"), "max": d.get("max"),
        "p50": _pct(c, "p50"), "p90": _pct(c, "p90"), "p95": _pct(c, "p95"), "p99": _pct(c, "p99"),
        "worst": c.get("worst") or [], "notes": c.get("notes") or [],
        "requirements": ", ".join(c.get("requirements") or []),
    }


def campaign_model(campaign: Mapping[str, Any], out_dir: str | Path = "", *, generated_utc: str = "") -> dict[str, Any]:
    """What the page shows, from ``campaign.json``'s content."""
    from bench import __version__

    camp = campaign.get("campaign") or {}
    agg = campaign.get("aggregate") or {}
    inv = campaign.get("invocation") or {}
    groups = []
    for label, case in (agg.get("cases") or {}).items():
        groups.append({
            "label": label, "anchor": f"g{len(groups)}", "case_id": case.get("case_id"),
            "variant": case.get("variant"), "sweep": case.get("sweep") or [], "runs": case.get("runs"),
            "seeds": case.get("seeds") or [], "verdicts": case.get("verdicts") or {},
            "pass_rate": case.get("pass_rate"), "interval": case.get("pass_rate_interval") or [None, None],
            "criteria": [_criterion_row(cid, c) for cid, c in (case.get("criteria") or {}).items()],
        })
    sweeps = []
    for label, sw in (agg.get("sweeps") or {}).items():
        axes = [{"key": a["key"], "field": a.get("field"), "unit": a.get("unit"), "numeric": a.get("numeric"),
                 "pooled": a.get("pooled"), "points": a.get("points") or []} for a in sw.get("axes") or []]
        sweeps.append({"label": label, "anchor": f"s{len(sweeps)}", "runs": sw.get("runs"), "axes": axes})
    judged = [{"label": label, "verdict": v.get("verdict"), "runs": v.get("runs"), "errors": v.get("errors") or [],
               "criteria": v.get("criteria") or []}
              for label, v in (campaign.get("verdicts") or {}).items()]
    planned = camp.get("planned")
    missing = list(camp.get("missing") or [])
    return {
        "title": "Campaign report",
        "folder": str(out_dir), "paths": camp.get("paths") or [], "planned": planned,
        "recorded": agg.get("runs", 0), "missing": missing, "complete": bool(camp.get("complete")),
        "failing": agg.get("failing", 0), "confidence": agg.get("confidence", 0.95),
        "executor": f"{inv.get('scheduler', '—')}, {inv.get('workers', '—')} worker(s)",
        "invocation": inv, "bench_version": __version__, "campaign_version": camp.get("bench_version"),
        "finished_utc": camp.get("finished_utc"),
        "generated_utc": generated_utc or _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "judged": judged, "groups": groups, "sweeps": sweeps, "verdict_names": _VERDICTS,
        "running": campaign.get("running"),  # the holder of the folder's lock, while a campaign runs there
    }


def _figs(figs: Sequence[Figure]) -> list[dict[str, Any]]:
    return [{"key": f.key, "title": f.title, "alt": f.alt, "caption": f.caption,
             "b64": base64.b64encode(f.png).decode("ascii")} for f in figs]


def render_campaign_html(model: Mapping[str, Any], figures: Mapping[str, Sequence[Figure]], part: str = "all") -> str:
    """The page, or one part of it for the PDF: ``front``, a group's label, ``sweeps``."""
    figs = {k: _figs(v) for k, v in figures.items()} if part != "front" else {}
    return render_template("campaign_report.html.j2", m=model, figs=figs, part=part)


def _render_part(html: str) -> bytes:
    from bench.report.pdf import render_part

    return render_part(html)


def _call(fn: Callable[..., Any], *args: Any) -> Any:
    return fn(*args)


def build_campaign_report(
    campaign: Mapping[str, Any], out_dir: str | Path, *, pdf: bool = True, generated_utc: str = "",
    workers: int | None = None, stage: Callable[[str], None] | None = None,
) -> CampaignReportFiles:
    """Write ``campaign_report.html`` (and ``campaign_report.pdf``) for ``campaign`` (the
    content of ``campaign.json``) into ``out_dir``. ``workers`` processes (the CPU count by
    default; 1: none) draw the figures, one case group or sweep per job, and lay out the
    PDF's parts as soon as their figures are in."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = campaign_model(campaign, out, generated_utc=generated_utc)
    jobs = figure_jobs(campaign.get("aggregate") or {}, campaign.get("verdicts") or {})
    n = max(1, min(workers or os.cpu_count() or 1, len(jobs) + 1))
    part_of = {g["label"]: g["label"] for g in model["groups"]} | {f"sweep:{s['label']}": "sweeps"
                                                                     for s in model["sweeps"]}
    parts = ["front", *(g["label"] for g in model["groups"])] + (["sweeps"] if model["sweeps"] else [])
    figures: dict[str, list[Figure]] = {}
    laid: dict[str, cf.Future] = {}
    with pool_of(n) as pool:
        if pdf:
            laid["front"] = pool.submit(_render_part, render_campaign_html(model, {}, part="front"))
        futs = {pool.submit(_call, fn, *args): key for key, fn, args in jobs}
        waiting = {p: sum(1 for k in futs.values() if part_of.get(k) == p) for p in parts}
        for fut in cf.as_completed(futs):
            key = futs[fut]
            figures[key] = fut.result()
            part = part_of.get(key, "")
            waiting[part] = waiting.get(part, 1) - 1
            if pdf and waiting[part] == 0:
                laid[part] = pool.submit(_render_part, render_campaign_html(model, figures, part=part))
        for p in parts:  # a part without figures
            if pdf and p not in laid:
                laid[p] = pool.submit(_render_part, render_campaign_html(model, figures, part=p))
        figures = {key: figures[key] for key, _fn, _args in jobs}  # in the report's order
        if stage is not None:
            stage(f"drew {sum(len(f) for f in figures.values())} figures")
        html_path = out / HTML_NAME
        write_atomic(html_path, render_campaign_html(model, figures))
        pieces = [laid[p].result() for p in parts] if pdf else []
    pdf_path = None
    if pdf:
        from bench.report.pdf import assemble

        pdf_path = assemble(pieces, out / PDF_NAME, footer=f"campaign {out.resolve().name}")
    return CampaignReportFiles(html_path, pdf_path, figures)

