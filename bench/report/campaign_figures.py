"""The figures of the campaign report, drawn from a campaign's aggregate alone (a dict, as
``campaign.json`` holds it: :mod:`bench.campaign.aggregate`), as PNG bytes.

Per case group (case, variant, sweep point):

``dist-<criterion>``  the criterion's values (display unit) over the runs: a histogram and
                      the empirical CDF side by side, the limit red dashed (both bounds of
                      a range; ``±`` of a ``within``), the marginal band shaded inside it,
                      P50, P90 and P95 marked on the CDF;
``pass-rates``        the run pass rate and each criterion's, as bars with their
                      Clopper-Pearson intervals;
``anees-<criterion>`` a criterion judged by ANEES over the runs: the ANEES against time
                      with its band for N runs (:mod:`bench.report.campaign_anees`).

Per swept key of a case (``sweeps``):

``sweep-<k>-<criterion>``  the criterion's median against the swept value, the P10..P90
                           band shaded, min and max as thin lines, every run's value as a
                           dot, the limit red dashed;
``sweep-<k>-pass-rate``    the run pass rate (black, its interval shaded) and the pass rate
                           of each criterion that is not 1 at every point, against the
                           swept value.

A criterion whose every run (two or more) has the same passing value (the integrity checks
at 0, most often) gets no figure: its table row says all there is.

A swept key whose values are quantities is a numeric axis labelled with the unit as written
(``%``, ``ms``); any other is categorical, one tick per value. Colours as the certification
report's (:data:`bench.report.figures.STYLE`: limits red dashed, values blue). Every figure
has alt text, a caption and ``values``: the numbers it marks (``limit_low``/``limit_high``
in the display unit, ``x`` the swept values drawn, ``pass_rate`` the rates drawn...), lists
where a figure marks several.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes

from bench.report.campaign_anees import anees_entries, anees_figure
from bench.report.figures import STYLE, Figure, fmt, margins, render, subplots

__all__ = ["campaign_figures", "group_figures", "criterion_figure", "pass_rate_figure", "sweep_figures"]

_MARK = {"p50": "tab:green", "p90": "tab:purple", "p95": "tab:brown"}


def _unit(c: Mapping[str, Any]) -> str:
    u = c.get("unit") or ""
    return "" if u == "1" else u


def _label(name: str, c: Mapping[str, Any]) -> str:
    u = _unit(c)
    return f"{name}, {u}" if u else name


def _finite(values: Sequence[Any]) -> list[float]:
    return [float(v) for v in values if isinstance(v, int | float) and math.isfinite(v)]


def limit_values(c: Mapping[str, Any]) -> list[float]:
    """The limit lines of a criterion in its display unit (``within``: both signs)."""
    lim = c.get("limit") or {}
    out = [float(v) for v in (lim.get("low"), lim.get("high")) if isinstance(v, int | float)]
    if c.get("comparator") == "within":
        out = sorted({-v for v in out} | set(out))
    return out


def _band_spans(c: Mapping[str, Any]) -> list[tuple[float, float]]:
    """The marginal band(s) inside the limit, display unit."""
    band = c.get("marginal_band")
    lim = c.get("limit") or {}
    lo, hi = lim.get("low"), lim.get("high")
    if not isinstance(band, int | float) or band <= 0:
        return []
    comp = c.get("comparator")
    spans = []
    if comp in ("at_most", "in_range", "within") and hi is not None:
        spans.append((hi - band, hi))
    if comp == "within" and hi is not None:
        spans.append((-hi, -hi + band))
    if comp in ("at_least", "in_range") and lo is not None:
        spans.append((lo, lo + band))
    return spans


def _limit_values_dict(c: Mapping[str, Any]) -> dict[str, Any]:
    lim = c.get("limit") or {}
    return {"limit_low": lim.get("low"), "limit_high": lim.get("high"), "limit_lines": limit_values(c)}


def _draw_limits(ax: Axes, c: Mapping[str, Any], *, vertical: bool) -> None:
    text = f"limit {c.get('limit_text') or ''}".strip()
    for i, v in enumerate(limit_values(c)):
        draw = ax.axvline if vertical else ax.axhline
        draw(v, color=STYLE["limit"], ls="--", lw=1.3, label=text if i == 0 else None)
    for i, (a, b) in enumerate(_band_spans(c)):
        span = ax.axvspan if vertical else ax.axhspan
        span(a, b, color=STYLE["limit"], alpha=0.12, lw=0, label="marginal band" if i == 0 else None)


def criterion_figure(group: str, cid: str, c: Mapping[str, Any]) -> Figure | None:
    """Histogram and empirical CDF of one criterion's values in one case group (None when
    no run measured it)."""
    disp = c.get("display") or {}
    raw = disp.get("values") or []
    values = np.sort(np.asarray(_finite(raw)))
    if not len(values):
        return None
    infinite = len(raw) - len(values)
    fig, (hx, cx) = subplots(1, 2, figsize=(10.0, 3.6))
    lines = limit_values(c)
    lo = min([float(values[0]), *lines])
    hi = max([float(values[-1]), *lines])
    pad = 0.05 * (hi - lo) if hi > lo else max(abs(hi) * 0.05, 1e-9)
    bins = np.linspace(lo - pad, hi + pad, int(min(40, max(8, math.sqrt(len(values)) * 2))) + 1)
    hx.hist(values, bins=bins, color=STYLE["dut"], alpha=0.8, label=f"{len(values)} runs")
    _draw_limits(hx, c, vertical=True)
    hx.set_xlabel(_label(str(c.get("metric") or cid), c))
    hx.set_ylabel("runs")
    hx.grid(True, alpha=0.3)
    hx.legend(loc="best", fontsize=8)
    p = np.arange(1, len(values) + 1) / len(values) * 100.0
    cx.step(np.concatenate([[values[0]], values]), np.concatenate([[0.0], p]), where="post", color=STYLE["dut"],
            lw=1.5, label="runs at or below")
    _draw_limits(cx, c, vertical=True)
    pct = disp.get("percentiles") or {}
    marks: dict[str, float] = {}
    for name, colour in _MARK.items():
        v = (pct.get(name) or {}).get("value")
        if isinstance(v, int | float) and math.isfinite(v):
            marks[name] = float(v)
            cx.axvline(v, color=colour, ls="-.", lw=1.1, label=f"{name.upper()} = {fmt(v)}")
    cx.set_ylim(0, 101)
    cx.set_xlim(lo - pad, hi + pad)
    cx.set_xlabel(_label(cid, c))
    cx.set_ylabel("runs at or below, %")
    cx.grid(True, alpha=0.3)
    cx.legend(loc="lower right", fontsize=8)
    title = f"{group}: {cid} over {len(raw)} runs"
    fig.suptitle(title, fontsize=11)
    margins(fig, top=0.5)
    fig.subplots_adjust(wspace=0.3)
    unit = _unit(c)
    inf_note = f" {infinite} infinite value(s) are not drawn." if infinite else ""
    caption = (f"{cid} ({c.get('metric')}, window {c.get('window')}) in {unit or 'its unit'}: histogram (left) and "
               f"empirical CDF (right) of the values of the {len(values)} runs that measured it; red dashed: the "
               f"limit {c.get('limit_text')}" + ("; shaded red: the marginal band" if _band_spans(c) else "")
               + "; dash-dotted: P50, P90 and P95." + inf_note)
    alt = (f"Distribution of {cid} over {len(values)} runs: from {fmt(float(values[0]))} to {fmt(float(values[-1]))} "
           f"{unit}, limit {c.get('limit_text')}.")
    return Figure(f"dist-{cid}", title, render(fig), alt, caption,
                  {**_limit_values_dict(c), **marks, "runs": float(len(values))})


def pass_rate_figure(group: str, case: Mapping[str, Any]) -> Figure:
    """The run pass rate and each criterion's, with Clopper-Pearson intervals."""
    names = ["(run)", *case.get("criteria", {})]
    rates, lows, highs = [], [], []
    for i, name in enumerate(names):
        src = case if i == 0 else case["criteria"][name]
        r = src.get("pass_rate")
        lo, hi = src.get("pass_rate_interval") or [0.0, 1.0]
        rates.append(math.nan if r is None else float(r))
        lows.append(lo)
        highs.append(hi)
    y = np.arange(len(names))
    r = np.asarray(rates)
    fig, ax = subplots(figsize=(9.0, 1.2 + 0.3 * len(names)))
    colours = ["black" if i == 0 else STYLE["dut"] for i in range(len(names))]
    ax.barh(y, np.nan_to_num(r) * 100.0, color=colours, alpha=0.75)
    err = np.vstack([np.maximum(0, np.nan_to_num(r) - lows), np.maximum(0, np.asarray(highs) - np.nan_to_num(r))])
    ax.errorbar(np.nan_to_num(r) * 100.0, y, xerr=err * 100.0, fmt="none", ecolor="0.2", capsize=3, lw=1)
    ax.set_yticks(y, names, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(0, 105)
    ax.set_xlabel("pass rate (PASS or MARGINAL), %")
    ax.grid(True, axis="x", alpha=0.3)
    title = f"{group}: pass rates over {case.get('runs')} runs"
    ax.set_title(title, fontsize=11)
    margins(fig, left=2.4, top=0.4, bottom=0.55)
    conf = "95 %"
    caption = (f"Pass rate of the runs (black) and of each criterion (blue; N/A runs left out), with their exact "
               f"Clopper-Pearson {conf} intervals as error bars.")
    crit = r[1:][np.isfinite(r[1:])]
    lowest = f", lowest criterion {fmt(float(crit.min()) * 100)} %" if len(crit) else ""
    alt = f"Pass rates of {group}: runs {fmt(rates[0] * 100) if math.isfinite(rates[0]) else '—'} %{lowest}."
    return Figure("pass-rates", title, render(fig), alt, caption,
                  {"names": names, "pass_rate": rates, "interval_low": lows, "interval_high": highs})


def _x(axis: Mapping[str, Any]) -> tuple[np.ndarray, list[str], str]:
    pts = axis["points"]
    name = axis["key"] + (f".{axis['field']}" if axis.get("field") else "")
    if axis.get("numeric"):
        unit = axis.get("unit") or ""
        return np.asarray([float(p["x"]) for p in pts]), [], f"{name}, {unit}" if unit else name
    return np.arange(len(pts), dtype=float), [str(p["label"]) for p in pts], name


def _xaxis(ax: Axes, labels: list[str], x: np.ndarray) -> None:
    if labels:
        ax.set_xticks(x, labels, fontsize=8, rotation=15 if max(map(len, labels)) > 12 else 0)


def sweep_figures(label: str, sweep: Mapping[str, Any]) -> list[Figure]:
    """The figures of one case's sweeps: per swept key, each criterion against the swept
    value, then the pass-rate curve."""
    out: list[Figure] = []
    for k, axis in enumerate(sweep.get("axes", [])):
        x, ticks, xname = _x(axis)
        pooled = " (pooled over the other swept keys)" if axis.get("pooled") else ""
        for cid, meta in axis.get("criteria", {}).items():
            pts = [p["criteria"].get(cid, {}) for p in axis["points"]]
            if all(p.get("pass_rate") == 1.0 for p in pts) and len({p.get("min") for p in pts}
                                                                   | {p.get("max") for p in pts}) == 1:
                continue  # the same passing value at every point and run
            fig = _sweep_metric(label, k, axis, cid, meta, x, ticks, xname, pooled)
            if fig is not None:
                out.append(fig)
        out.append(_sweep_pass_rate(label, k, axis, x, ticks, xname, pooled))
    return out


def _sweep_metric(label: str, k: int, axis: Mapping[str, Any], cid: str, meta: Mapping[str, Any], x: np.ndarray,
                  ticks: list[str], xname: str, pooled: str) -> Figure | None:
    pts = [p["criteria"].get(cid, {}) for p in axis["points"]]
    if not any(_finite(p.get("values") or []) for p in pts):
        return None
    o = np.argsort(x, kind="stable")  # lines in the order of x; values in declaration order
    med = np.asarray([p.get("median", math.nan) for p in pts], dtype=float)
    p10 = np.asarray([p.get("p10", math.nan) for p in pts], dtype=float)
    p90 = np.asarray([p.get("p90", math.nan) for p in pts], dtype=float)
    fig, ax = subplots(figsize=(8.0, 4.2))
    lows = np.asarray([p.get("min", math.nan) for p in pts], dtype=float)
    highs = np.asarray([p.get("max", math.nan) for p in pts], dtype=float)
    ax.fill_between(x[o], p10[o], p90[o], color=STYLE["dut"], alpha=0.2, lw=0, label="P10 .. P90")
    ax.plot(x[o], lows[o], color=STYLE["dut"], lw=0.6, ls=":", label="min, max")
    ax.plot(x[o], highs[o], color=STYLE["dut"], lw=0.6, ls=":")
    ax.plot(x[o], med[o], "o-", color=STYLE["dut"], lw=1.6, ms=5, label="median")
    dx, dy = [], []
    for xi, p in zip(x, pts, strict=True):
        v = _finite(p.get("values") or [])
        dx += [float(xi)] * len(v)
        dy += v
    ax.plot(dx, dy, ".", color=STYLE["truth"], ms=3, alpha=0.6, label="runs")
    _draw_limits(ax, meta, vertical=False)
    _xaxis(ax, ticks, x)
    ax.set_xlabel(xname)
    ax.set_ylabel(_label(cid, meta))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    title = f"{label}: {cid} against {xname}"
    ax.set_title(title, fontsize=11)
    margins(fig)
    caption = (f"{cid} ({meta.get('metric')}) at each value of {axis['key']}{pooled}: median (line), P10 to P90 "
               f"(shaded), min and max (dotted), every run's value (dots); red dashed: the limit "
               f"{meta.get('limit_text')}.")
    alt = (f"{cid} against {xname}: medians " + ", ".join(fmt(m) for m in med if math.isfinite(m))
           + f" {_unit(meta)} at {len(pts)} points; limit {meta.get('limit_text')}.")
    return Figure(f"sweep-{k}-{cid}", title, render(fig), alt, caption,
                  {"x": [float(v) for v in x], "median": med.tolist(), **_limit_values_dict(meta)})


def _sweep_pass_rate(label: str, k: int, axis: Mapping[str, Any], x: np.ndarray, ticks: list[str], xname: str,
                     pooled: str) -> Figure:
    pts = axis["points"]
    o = np.argsort(x, kind="stable")  # lines in the order of x; values in declaration order
    fig, ax = subplots(figsize=(8.0, 4.2))
    run = [math.nan if p["pass_rate"] is None else p["pass_rate"] for p in pts]
    lo = [p["pass_rate_interval"][0] for p in pts]
    hi = [p["pass_rate_interval"][1] for p in pts]
    ax.fill_between(x[o], np.asarray(lo)[o] * 100, np.asarray(hi)[o] * 100, color="0.5", alpha=0.2, lw=0,
                    label="runs: 95 % interval")
    ax.plot(x[o], np.asarray(run)[o] * 100, "o-", color="black", lw=1.8, label="runs")
    values: dict[str, Any] = {"x": [float(v) for v in x], "pass_rate": run, "interval_low": lo, "interval_high": hi}
    always = []
    cmap = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:olive",
            "tab:cyan"]
    drawn = 0
    for cid in axis.get("criteria", {}):
        rates = [p["criteria"].get(cid, {}).get("pass_rate") for p in pts]
        values[f"pass_rate:{cid}"] = rates
        if all(r == 1.0 for r in rates if r is not None):
            always.append(cid)
            continue
        colour = cmap[drawn % len(cmap)]
        drawn += 1
        ivs = [p["criteria"].get(cid, {}).get("pass_rate_interval") or [math.nan, math.nan] for p in pts]
        yerr = np.asarray([[max(0.0, (r or 0) - a), max(0.0, b - (r or 0))] for r, (a, b) in zip(rates, ivs,
                                                                                                 strict=True)]).T
        yr = np.asarray([math.nan if r is None else r for r in rates], dtype=float)
        ax.errorbar(x[o], yr[o] * 100, yerr=yerr[:, o] * 100, fmt="s--", color=colour, ms=4, lw=1, capsize=3, label=cid)
    _xaxis(ax, ticks, x)
    ax.set_ylim(-3, 103)
    ax.set_xlabel(xname)
    ax.set_ylabel("pass rate, %")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    title = f"{label}: pass rate against {xname}"
    ax.set_title(title, fontsize=11)
    margins(fig)
    caption = (f"Pass rate (PASS or MARGINAL) at each value of {axis['key']}{pooled}: of the runs (black, its "
               f"Clopper-Pearson 95 % interval shaded) and of each criterion below 1 somewhere (dashed, with "
               f"its interval)." + (f" Passed at every point: {', '.join(always)}." if always else ""))
    alt = f"Run pass rate against {xname}: " + ", ".join(
        f"{p['label']}: {fmt(r * 100) if math.isfinite(r) else '—'} %" for p, r in zip(pts, run, strict=True)) + "."
    return Figure(f"sweep-{k}-pass-rate", title, render(fig), alt, caption, values)


def group_figures(label: str, case: Mapping[str, Any], anees: Sequence[Mapping[str, Any]] = ()) -> list[Figure]:
    """The figures of one case group: its pass rates, each criterion's distribution, then
    the ANEES over time of each criterion judged by ANEES over the runs (``anees``: their
    entries in ``campaign.json``'s verdicts, :mod:`bench.report.campaign_anees`)."""
    figs = [pass_rate_figure(label, case)]
    for cid, c in case.get("criteria", {}).items():
        disp = c.get("display") or {}
        if set(c.get("verdicts") or {}) == {"PASS"} and c.get("measured", 0) > 1 and disp.get("min") == disp.get("max"):
            continue  # every run the same value and passing: its table row says all (integrity checks at 0)
        f = criterion_figure(label, cid, c)
        if f is not None:
            figs.append(f)
    for entry in anees:
        f = anees_figure(label, entry)
        if f is not None:
            figs.append(f)
    return figs


def figure_jobs(aggregate: Mapping[str, Any], verdicts: Mapping[str, Any] | None = None
                ) -> list[tuple[str, Any, tuple[Any, ...]]]:
    """``(key, function, arguments)`` of every figure group of the report, in its order:
    each case group by its label (with the ANEES criteria ``verdicts`` judged on it), each
    sweep as ``sweep:<label>`` (picklable: for a pool)."""
    anees: dict[str, list[Mapping[str, Any]]] = {}
    for group, entry in anees_entries(verdicts or {}):
        anees.setdefault(group, []).append(entry)
    jobs: list[tuple[str, Any, tuple[Any, ...]]] = [
        (label, group_figures, (label, case, tuple(anees.get(label, ()))))
        for label, case in aggregate.get("cases", {}).items()]
    jobs += [(f"sweep:{label}", sweep_figures, (label, sweep))
             for label, sweep in (aggregate.get("sweeps") or {}).items()]
    return jobs


def campaign_figures(aggregate: Mapping[str, Any], verdicts: Mapping[str, Any] | None = None
                     ) -> dict[str, list[Figure]]:
    """Every figure of the campaign report, per case group label and per sweep
    (``sweep:<label>``), in the aggregate's order."""
    return {key: fn(*args) for key, fn, args in figure_jobs(aggregate, verdicts)}
