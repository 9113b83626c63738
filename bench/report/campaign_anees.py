"""The campaign report's figure of a criterion judged by ANEES over the runs.

``anees-<criterion>`` (in its case group: case, variant, sweep point): the NEES per degree
of freedom averaged over the N runs (ANEES) at each grid time every run covers, against
time, its chi-square band for N runs shaded and bounded red dashed, 1 (consistent) dotted;
drawn from the criterion's ``anees`` entry in ``campaign.json``'s ``verdicts``
(:mod:`bench.campaign.verdicts`), a dict, so that this module never imports the campaign.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from bench.report.figures import STYLE, Figure, fmt, margins, render, subplots

__all__ = ["anees_figure", "anees_entries"]


def _num(x: Any) -> float:
    if isinstance(x, str) and x in ("inf", "Infinity"):
        return math.inf
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else math.nan


def anees_entries(verdicts: Mapping[str, Any]) -> Iterator[tuple[str, Mapping[str, Any]]]:
    """``(group label, criterion entry)`` of every criterion of ``verdicts`` judged by ANEES,
    the group label as the aggregate spells it (``CASE[variant]{sweep}``)."""
    for label, v in verdicts.items():
        case_id = str(v.get("case_id") or "")
        point = label[len(case_id):] if label.startswith(case_id) else ""
        for c in v.get("criteria") or []:
            if isinstance(c.get("anees"), Mapping):
                variant = c.get("variant")
                yield case_id + (f"[{variant}]" if variant else "") + point, c


def anees_figure(group: str, c: Mapping[str, Any]) -> Figure | None:
    """ANEES against time with its band (None when it holds no grid time)."""
    a = c["anees"]
    t = np.asarray([_num(x) for x in a.get("t_s") or []], dtype=float)
    y = np.asarray([_num(x) for x in a.get("anees") or []], dtype=float)
    if not len(t) or len(t) != len(y):
        return None
    lo, hi = (_num(b) for b in (a.get("band") or [math.nan, math.nan])[:2])
    n, dof, conf = a.get("runs"), a.get("dof"), _num(a.get("confidence"))
    cid = str(c.get("id"))
    control = ", must FAIL" if c.get("control") else ""
    fig, ax = subplots(figsize=(10.0, 3.8))
    ax.axhspan(lo, hi, color="tab:green", alpha=0.12, lw=0, label=f"{fmt(100 * conf)} % band of {n} runs")
    for i, b in enumerate((lo, hi)):
        ax.axhline(b, color=STYLE["limit"], ls="--", lw=1.1, label=f"[{fmt(lo)}, {fmt(hi)}]" if i == 0 else None)
    ax.axhline(1.0, color="0.4", ls=":", lw=1.0, label="1: consistent")
    finite = np.isfinite(y)
    ax.plot(t[finite], y[finite], ".", color=STYLE["dut"], ms=2.5, label=f"ANEES ({dof}-dof NEES per dof)")
    top = max([hi * 1.6, *(y[finite].tolist() or [1.0])])
    if not np.all(finite):
        ax.plot(t[~finite], np.full(int(np.sum(~finite)), top), "^", color=STYLE["limit"], ms=4,
                label="infinite (a zero sigma)")
    ax.set_ylim(0.0, top * 1.05)
    ax.set_xlabel("bench time, s")
    ax.set_ylabel("NEES per dof, mean of the runs")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, ncol=2)
    title = f"{group}: {cid}{control}, ANEES over {n} runs"
    ax.set_title(title, fontsize=11)
    margins(fig)
    within, above, below = (_num(a.get(k)) for k in ("within", "above", "below"))
    step = fmt(_num(a.get("step_s")))
    caption = (f"{cid} ({c.get('limit')} of the grid times, {c.get('verdict')}): at each {step} s "
               f"grid time of the window that all {n} runs cover, the NEES per degree of freedom averaged over them "
               f"(ANEES, dots), against the two-sided {fmt(100 * conf)} % band of {n} runs, chi-square({n}) / {n} "
               f"(shaded, red dashed); in the band {fmt(100 * within)} %, above {fmt(100 * above)} %, below "
               f"{fmt(100 * below)} % of {len(t)} grid times.")
    alt = (f"ANEES of {cid} over {n} runs from {fmt(float(t[0]))} to {fmt(float(t[-1]))} s: {fmt(100 * within)} % "
           f"of grid times in the band [{fmt(lo)}, {fmt(hi)}], mean {fmt(_num(a.get('mean')))}.")
    return Figure(f"anees-{cid}" + ("-control" if control else ""), title, render(fig), alt, caption,
                  {"band_low": lo, "band_high": hi, "within": within, "above": above, "below": below,
                   "runs": float(n or 0), "grid_times": float(len(t))})
