"""The event figures of a case's page: NEES, frame-switch close-ups, fault detection.

Part of :mod:`bench.report.figures` (same colours, same :class:`~bench.report.figures.Figure`),
split off to keep each module short. Every number drawn comes from the scoring:
:func:`~bench.scoring.consistency.nees_series` and
:func:`~bench.scoring.consistency.chi2_bounds`, the scorer's
:meth:`~bench.scoring.metrics.Scorer.switch_analysis` and
:meth:`~bench.scoring.metrics.Scorer.fault_analysis` with the case's settings.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.ticker import LogLocator, NullLocator
from numpy.lib.recfunctions import repack_fields

from bench.report.figdata import FigureData
from bench.report.figures import ARCMIN, STYLE, Figure, fmt, line, margins, mark_switches, render, shade, subplots
from bench.scoring.accuracy import select
from bench.scoring.consistency import CONSISTENCY_QUANTITIES, chi2_bounds, nees_series
from bench.scoring.data import ScoringError
from bench.scoring.faults import target_bit
from bench.scoring.windows import WindowSpec

__all__ = ["nees_figure", "switch_figures", "fault_figure", "MAX_SWITCHES", "MAX_FAULT_ROWS"]

MAX_SWITCHES = 4
MAX_FAULT_ROWS = 8
_SIGMA = {"position": "sigma_pos", "velocity": "sigma_vel", "heading": "sigma_att"}
_NEES_CLIP = (1e-4, 1e6)


def _limits(criteria: Sequence[Mapping[str, Any]], prefix: str) -> list[Mapping[str, Any]]:
    return [c for c in criteria if str(c.get("metric", "")).startswith(prefix)]


# -- NEES ------------------------------------------------------------------------------------
def _reported(quality: np.ndarray, quantity: str) -> bool:
    s = quality[_SIGMA[quantity]]
    s = s[:, 0] if quantity == "heading" else s
    return bool(np.any(np.isfinite(s) & (s > 0)))


def _window_stats(e: Any, w: Any, match: np.ndarray, nees: np.ndarray, lo: float, hi: float, dof: int
                  ) -> tuple[float, float]:
    """``consistency.<q>.within`` and ``.nees`` over window ``w`` from the series already
    computed: the epochs :func:`~bench.scoring.consistency.consistency_value` takes, the same
    statistics (the tests check the two agree)."""
    try:
        idx = select(e, w)
    except ScoringError:
        return math.nan, math.nan
    v = nees[idx[match[idx]]]
    if len(v) == 0:
        return math.nan, math.nan
    return float(np.mean((v >= lo) & (v <= hi))), float(np.mean(v)) / dof


def nees_figure(data: FigureData, criteria: Sequence[Mapping[str, Any]], head: str) -> Figure | None:
    e, q = data.errors, data.run.quality
    if e is None or q is None or len(q) == 0:
        return None
    names = [n for n in CONSISTENCY_QUANTITIES if _reported(q, n)]
    if not names:
        return None
    conf = data.settings.confidence
    # the columns the NEES reads, packed (nees_series copies the records it matches: 4x faster)
    q = repack_fields(q[["t_ns", "sigma_pos", "sigma_vel", "sigma_att"]])
    fig, axes = subplots(len(names), 1, figsize=(10.0, 2.6 * len(names) + 0.8), sharex=True, squeeze=False)
    values: dict[str, float] = {}
    notes = []
    labelled: set[str] = set()
    for ax, name in zip(axes[:, 0], names, strict=True):
        dof = CONSISTENCY_QUANTITIES[name]
        match, nees = nees_series(e, q, name)
        sel = e.usable & match
        t = e.t_ns[sel] * 1e-9
        v = np.clip(np.nan_to_num(nees[sel], nan=_NEES_CLIP[0], posinf=_NEES_CLIP[1]), *_NEES_CLIP)
        lo, hi = chi2_bounds(dof, conf)
        shade(ax, data.spans(), labelled)
        mark_switches(ax, data.switch_times_s(), labelled)
        line(ax, t, v, 1.0, color=STYLE["dut"], lw=0.6, label=f"{name} NEES ({dof} dof)")
        ax.axhline(lo, color=STYLE["limit"], ls="--", lw=1.1, label=f"{conf:.0%} χ² bounds: {fmt(lo)} – {fmt(hi)}")
        ax.axhline(hi, color=STYLE["limit"], ls="--", lw=1.1)
        crit = _limits(criteria, f"consistency.{name}.")
        wname = str(crit[0].get("window")) if crit else ("converged" if data.settings.convergence_ns > 0 else "all")
        w = data.window(wname)
        if w is not None:
            within, mean = _window_stats(e, w, match, nees, lo, hi, dof)
            values[f"{name}_within"], values[f"{name}_nees"] = within, mean
            ax.plot([], [], " ", label=f"over '{wname}': {within:.1%} within, mean NEES/dof {fmt(mean)}")
        for c in crit:
            hi_c = (c.get("limit_si") or {}).get("high")
            lo_c = (c.get("limit_si") or {}).get("low")
            notes.append(f"{c['id']} {c['metric']} ({c.get('window')}) limit "
                         + " / ".join(f"{k} {fmt(float(x))}" for k, x in (("≥", lo_c), ("≤", hi_c)) if x is not None))
        values[f"{name}_lower"], values[f"{name}_upper"] = lo, hi
        ax.set_yscale("log")
        ax.yaxis.set_major_locator(LogLocator(numticks=6))
        ax.yaxis.set_minor_locator(NullLocator())
        ax.set_ylabel(f"{name} NEES")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(loc="upper left", fontsize=8, ncol=2)
    axes[-1, 0].set_xlabel("bench time, s")
    title = f"{head}: NEES (consistency of the DUT's sigmas)"
    axes[0, 0].set_title(title)
    margins(fig)
    caption = (
        "Normalised estimation error squared at each DUT epoch with a NAV_QUALITY record, from the DUT's "
        f"own sigmas (taken uncorrelated, as the scoring does). Red dashed: the two-sided {conf:.0%} chi-square "
        "interval for the degrees of freedom; a consistent DUT stays inside it that often."
        + (" Criteria: " + "; ".join(notes) + "." if notes else "")
    )
    alt = "NEES against time: " + ", ".join(
        f"{n} {values.get(f'{n}_within', math.nan):.0%} within bounds" for n in names
    )
    return Figure("nees", title, render(fig), alt, caption, values)


# -- frame switches --------------------------------------------------------------------------
def switch_figures(data: FigureData, criteria: Sequence[Mapping[str, Any]], head: str,
                   half_s: float = 60.0) -> list[Figure]:
    e = data.errors
    if e is None or data.switch_times_s().size == 0:
        return []
    try:
        sa = data.scorer.switch_analysis(WindowSpec("all"))
    except ScoringError:
        return []
    crit = _limits(criteria, "frameswitch.")
    out = []
    u = e.usable
    t_all = e.t_ns[u] * 1e-9
    pre_s = data.settings.switches.pre_ns * 1e-9
    for k, sw in enumerate(sa.switches[:MAX_SWITCHES], start=1):
        near = (t_all >= sw.t_s - half_s) & (t_all <= sw.t_s + half_s)
        t = t_all[near]
        panels = [
            ("heading", "heading error, arcmin", e.att[u][near, :1] * ARCMIN, ("heading",)),
            ("velocity", "velocity error, m/s", e.vel[u][near], ("east", "north", "up")),
            ("position", "position error, m", e.pos[u][near], ("east", "north", "up")),
        ]
        fig, axes = subplots(3, 1, figsize=(10.0, 8.0), sharex=True)
        values: dict[str, float] = {"t_s": sw.t_s}
        for ax, (q, ylabel, y, comps) in zip(axes, panels, strict=True):
            ax.axvspan(max(sw.t_s - pre_s, sw.t_s - half_s), sw.t_s, color="0.85", lw=0, label="pre-switch window")
            shade(ax, data.spans(), set())
            ax.axvline(sw.t_s, color=STYLE["switch"], ls=":", lw=1.5, label=f"switch to {sw.to}")
            colours = ("tab:blue", "tab:cyan", "navy")
            for j, comp in enumerate(comps):
                line(ax, t, y[:, j], 1.0, color=colours[j] if len(comps) > 1 else STYLE["dut"], lw=0.9,
                     label=comp if len(comps) > 1 else "DUT")
            m = sw.measures[q]
            scale = ARCMIN if q == "heading" else 1.0
            unit = ylabel.rsplit(", ", 1)[1]
            for key in ("jump", "jump_excess", "excess", "band", "settling", "step_ratio"):
                values[f"{q}_{key}"] = float(m[key])
            text = (f"jump {fmt(m['jump'] * scale)} {unit}, beyond step {fmt(m['jump_excess'] * scale)}; "
                    f"excess {fmt(m['excess'] * scale)} over band {fmt(m['band'] * scale)} {unit}; "
                    f"settling {fmt(m['settling'])} s; step ratio {fmt(m['step_ratio'])}")
            for c in crit:
                metric = str(c["metric"]).split(".", 1)[1]
                hi = (c.get("limit_si") or {}).get("high")
                if metric.endswith(f"_{q}") and isinstance(hi, (int, float)):
                    sc = 1.0 if metric.startswith("step_ratio") else scale
                    text += f"\n{c['id']}: {metric} ≤ {fmt(hi * sc)}"
            ax.text(0.99, 0.97, text, transform=ax.transAxes, ha="right", va="top", fontsize=8,
                    bbox={"boxstyle": "round", "fc": "white", "ec": "0.7", "alpha": 0.9})
            ax.set_ylabel(ylabel)
            ax.grid(True, alpha=0.3)
            ax.legend(loc="lower left", fontsize=8, ncol=5)
        axes[-1].set_xlabel("bench time, s")
        axes[-1].set_xlim(sw.t_s - half_s, sw.t_s + half_s)
        title = f"{head}: frame switch {k} at {sw.t_s:.2f} s to {sw.to} (latitude {sw.latitude_deg:.3f}°)"
        axes[0].set_title(title, fontsize=10)
        margins(fig)
        more = ""
        if len(sa.switches) > MAX_SWITCHES:
            more = f" ({len(sa.switches)} switches; the first {MAX_SWITCHES} drawn.)"
        caption = (
            f"±{half_s:.0f} s around the switch (purple dotted): heading, velocity (ENU) and position (ENU) errors. "
            "Grey: the pre-switch window the band is taken over. Boxes: the scoring's measures of this switch "
            "(jump, jump beyond the ordinary step, excess over the pre-switch band, settling, step ratio) and "
            "the limits of the case's frame-switch criteria." + more
        )
        alt = (f"Frame switch at {sw.t_s:.1f} s: heading jump {m_fmt(sw.measures['heading']['jump'] * ARCMIN)} arcmin, "
               f"position jump {m_fmt(sw.measures['position']['jump'])} m.")
        out.append(Figure(f"switch-{k}", title, render(fig), alt, caption, values))
    return out


def m_fmt(x: float) -> str:
    return fmt(x) if math.isfinite(x) else str(x)


# -- fault detection -------------------------------------------------------------------------
def fault_figure(data: FigureData, criteria: Sequence[Mapping[str, Any]], head: str,
                 before_s: float = 10.0, after_s: float = 15.0) -> Figure | None:
    q = data.run.quality
    if q is None or len(q) == 0 or not data.has_truth or not data.run.faults:
        return None
    try:
        fa = data.scorer.fault_analysis(WindowSpec("all"), {})
    except ScoringError:
        return None
    if not fa.outcomes:
        return None
    fs = data.settings.faults
    grace_s = fs.grace_ns * 1e-9
    q = q[np.argsort(q["t_ns"], kind="stable")]
    tq = q["t_ns"] * 1e-9
    rows = fa.outcomes[:MAX_FAULT_ROWS]
    fig, axes = subplots(len(rows), 1, figsize=(10.0, 1.0 + 1.45 * len(rows)), squeeze=False)
    values: dict[str, float] = {}
    for ax, o in zip(axes[:, 0], rows, strict=True):
        bit = target_bit(o.target)
        a, b = o.start_s - before_s, o.end_s + grace_s + after_s
        sel = (tq >= a) & (tq <= b)
        t = tq[sel]
        m = np.uint8(1 << (bit or 0))
        det = (q["fault_detected"][sel] & m) != 0
        exc = (q["excluded"][sel] & m) != 0
        ax.axvspan(o.start_s, o.end_s, color=STYLE["fault"], alpha=0.25, lw=0, label="fault window")
        if grace_s > 0:
            ax.axvspan(o.end_s, o.end_s + grace_s, color=STYLE["fault"], alpha=0.1, lw=0, hatch="//",
                       label=f"grace {grace_s:g} s")
        ax.fill_between(t, 1.1, 1.1 + 0.8 * det, step="post", color=STYLE["dut"], alpha=0.8, lw=0,
                        label=f"{fs.flag if fs.flag != 'either' else 'detected or excluded'} flag")
        ax.fill_between(t, 0.0, 0.8 * exc, step="post", color="navy", alpha=0.5, lw=0, label="excluded flag")
        if o.detected and math.isfinite(o.latency_s):
            t_det = o.start_s + o.latency_s
            ax.annotate("", xy=(t_det, 2.05), xytext=(o.start_s, 2.05),
                        arrowprops={"arrowstyle": "<->", "color": "black", "lw": 1.0})
            ax.text((o.start_s + t_det) / 2, 2.12, f"latency {o.latency_s:.2f} s", ha="center", va="bottom", fontsize=8)
        verdict = f"detected after {o.latency_s:.2f} s" if o.detected else "MISSED"
        cls = "" if o.class_ok is None else f", class {o.reported_class} ({'right' if o.class_ok else 'wrong'})"
        ax.set_title(f"#{o.id} {o.kind} on {o.target}, {o.start_s:g}–{o.end_s:g} s: {verdict}, "
                     f"excluded {o.exclusion:.0%} of the window, error growth {m_fmt(o.growth_m)} m{cls}",
                     fontsize=9, loc="left")
        ax.set_xlim(a, b)
        ax.set_ylim(-0.1, 2.6)
        ax.set_yticks([0.4, 1.5], ["excluded", "detected"], fontsize=8)
        ax.grid(True, axis="x", alpha=0.3)
        values[f"latency_{o.id}"] = o.latency_s
        values[f"exclusion_{o.id}"] = o.exclusion
    axes[0, 0].legend(loc="upper right", fontsize=7, ncol=4)
    axes[-1, 0].set_xlabel("bench time, s")
    title = f"{head}: fault detection per fault window"
    fig.suptitle(title, fontsize=11)
    margins(fig, top=0.75, hspace=0.75)
    limits = "; ".join(
        f"{c['id']} {c['metric']} " + " ".join(
            f"{k} {fmt(float(x))}" for k, x in (("≥", (c.get('limit_si') or {}).get('low')),
                                                ("≤", (c.get('limit_si') or {}).get('high'))) if x is not None)
        for c in _limits(criteria, "faults.")
    )
    more = ""
    if len(fa.outcomes) > MAX_FAULT_ROWS:
        more = f" {len(fa.outcomes)} windows; the first {MAX_FAULT_ROWS} drawn."
    caption = (
        "Per sensor fault window (orange; hatched: the grace period a detection may still come in): the DUT's "
        f"NAV_QUALITY flags of the faulted sensor over time; latency from the window's start to the first flag "
        f"(the scoring's faults analysis, flag '{fs.flag}'). False alarms over the run: {len(fa.false_alarms)}."
        + (f" Criteria (SI): {limits}." if limits else "") + more
    )
    n_det = sum(1 for o in fa.outcomes if o.detected)
    alt = f"Fault detection timeline: {n_det} of {len(fa.outcomes)} fault windows detected."
    return Figure("faults", title, render(fig), alt, caption, values)
