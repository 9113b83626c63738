"""The figures of a case's page in the certification report, as PNG bytes.

:func:`case_figures` draws, from one recording and the case's criteria (the criterion
dicts of the results record), each figure the recording has the data for:

``trajectory``   truth (black) against the DUT (blue) on the tangent plane at the start;
``errors``       horizontal, vertical, heading and velocity errors against time, with the
                 limits of the criteria that bound them (red dashed, over their windows);
``cdf``          cumulative distribution of the horizontal error with CEP50 and CEP95;
``nees``         NEES of position, velocity and heading with the chi-square bounds
                 (a DUT reporting sigmas on NAV_QUALITY only);
``switch-<k>``   +-60 s around the k-th navigation-frame switch;
``faults``       per fault window: the DUT's detection and exclusion flags, the latency.

Colours are the same in every figure: truth black, DUT blue, limits red dashed, fault
windows shaded orange, GNSS-blocked stretches grey, frame switches purple dotted.
Every number drawn is computed by the scoring's own functions (:mod:`bench.report.figdata`).
Drawn with matplotlib's Agg backend; long series are thinned to display resolution
keeping each bin's extremes.
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure as MplFigure

from bench.report.figdata import FigureData, Span, decimate, figure_data, gaps_broken, local_plane, run_criteria
from bench.scoring.accuracy import accuracy_value, select
from bench.scoring.data import ScoringError

__all__ = ["Figure", "case_figures", "STYLE"]

#: The colours of every figure.
STYLE = {
    "truth": "black",
    "dut": "tab:blue",
    "limit": "red",
    "fault": "tab:orange",
    "blocked": "0.55",
    "switch": "tab:purple",
}
DPI = 100
ARCMIN = 60.0 * 180.0 / math.pi  # rad -> arcmin


@dataclass
class Figure:
    """One figure: ``key`` (stable id: ``trajectory``, ``errors``, ``cdf``, ``nees``,
    ``switch-1``..., ``faults``), ``title``, ``png`` (the image), ``alt`` (text
    alternative), ``caption`` (what is drawn, for the reader); ``values`` the numbers
    marked on it (in the figure's units, named with them: ``cep95`` m, ``heading_max``
    arcmin...), for the report and the tests."""

    key: str
    title: str
    png: bytes
    alt: str
    caption: str
    values: dict[str, float] = field(default_factory=dict)


def case_figures(recording: Path, criteria: list[dict], *, title: str = "") -> list[Figure]:
    """The figures of one recording (see the module docstring), in the order listed there;
    a figure whose data the recording lacks is left out (no DUT output: the truth's
    trajectory only; nothing readable: an empty list)."""
    from bench.report.figures_events import fault_figure, nees_figure, switch_figures

    data = figure_data(recording)
    mine = run_criteria(criteria, data.variant)
    head = title or Path(recording).stem
    out: list[Figure] = []
    for make in (trajectory_figure, errors_figure, cdf_figure, nees_figure):
        fig = make(data, mine, head)
        if fig is not None:
            out.append(fig)
    out += switch_figures(data, mine, head)
    fig = fault_figure(data, mine, head)
    if fig is not None:
        out.append(fig)
    return out


# -- shared drawing helpers -------------------------------------------------------------------
def subplots(*args: Any, figsize: tuple[float, float], **kw: Any) -> tuple[MplFigure, Any]:
    """A figure on its own Agg canvas, outside pyplot (nothing global to close or leak)."""
    fig = MplFigure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(*args, **kw)


def render(fig: MplFigure) -> bytes:
    """PNG bytes of a figure."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    return buf.getvalue()


def margins(fig: Any, *, left: float = 0.85, right: float = 0.2, top: float = 0.45, bottom: float = 0.6,
            hspace: float = 0.35) -> None:
    """Fixed margins in inches (tight_layout measures every tick label: slow)."""
    w, h = fig.get_size_inches()
    fig.subplots_adjust(left=left / w, right=1 - right / w, top=1 - top / h, bottom=bottom / h, hspace=hspace)


def shade(ax: Axes, spans: Sequence[Span], labelled: set[str] | None = None) -> None:
    """Shade fault windows (orange) and GNSS-blocked stretches (grey) on a time axis."""
    for s in spans:
        kind = "fault" if s.kind == "fault" else "blocked"
        label = {"fault": "fault window", "blocked": "GNSS blocked"}[kind]
        show = labelled is not None and label not in labelled
        if show:
            labelled.add(label)  # type: ignore[union-attr]
        ax.axvspan(s.start_s, s.end_s, color=STYLE[kind], alpha=0.25 if kind == "fault" else 0.3, lw=0,
                   label=label if show else None)


def mark_switches(ax: Axes, times: np.ndarray, labelled: set[str] | None = None) -> None:
    for t in times:
        show = labelled is not None and "frame switch" not in labelled
        if show:
            labelled.add("frame switch")  # type: ignore[union-attr]
        ax.axvline(float(t), color=STYLE["switch"], ls=":", lw=1.2, label="frame switch" if show else None)


def line(ax: Axes, t: np.ndarray, y: np.ndarray, gap_s: float, **kw: Any) -> None:
    """A decimated line, broken across gaps in the output."""
    td, yd = decimate(t, y)
    td, yd = gaps_broken(td, yd, gap_s)
    ax.plot(td, yd, **kw)


def fmt(x: float) -> str:
    return f"{x:.3g}" if abs(x) < 1e4 else f"{x:.0f}"


# -- trajectory ------------------------------------------------------------------------------
def trajectory_figure(data: FigureData, criteria: Sequence[Mapping[str, Any]], head: str) -> Figure | None:
    run = data.run
    dut = None
    if data.has_nav:
        nav = run.nav[np.argsort(run.nav["t_ns"], kind="stable")]  # type: ignore[index]
        nav = nav[(nav["valid"] != 0) & np.isfinite(nav["lat"]) & np.isfinite(nav["lon"])]
        dut = nav if len(nav) else None
    if not data.has_truth and dut is None:
        return None
    src = run.truth if data.has_truth else dut
    assert src is not None
    origin = (float(src["lat"][0]), float(src["lon"][0]), float(src["h"][0]))

    def plane(rec: np.ndarray, n: int = 4000) -> tuple[np.ndarray, np.ndarray]:
        step = max(1, -(-len(rec) // n))
        r = rec[::step] if (len(rec) - 1) % step == 0 else np.concatenate([rec[::step], rec[-1:]])
        return r["t_ns"] * 1e-9, local_plane(r["lat"], r["lon"], r["h"], origin)

    fig, ax = subplots(figsize=(8.0, 7.0))
    parts = []
    tt = xy = None
    if data.has_truth:
        tt, xy = plane(run.truth)  # type: ignore[arg-type]
        parts.append(xy)
    if dut is not None:
        parts.append(plane(dut)[1])
    extent = float(np.ptp(np.vstack(parts), axis=0).max())
    km = extent > 5000.0
    k = 1e-3 if km else 1.0
    unit = "km" if km else "m"
    done: set[str] = set()
    if xy is not None and tt is not None:
        for s in data.spans():
            sel = (tt >= s.start_s) & (tt <= s.end_s)
            if np.any(sel):
                kind = "fault" if s.kind == "fault" else "blocked"
                label = {"fault": "fault window", "blocked": "GNSS blocked"}[kind]
                ax.plot(xy[sel, 0] * k, xy[sel, 1] * k, color=STYLE[kind], lw=7, alpha=0.6, solid_capstyle="round",
                        label=None if label in done else label, zorder=1)
                done.add(label)
        ax.plot(xy[:, 0] * k, xy[:, 1] * k, color=STYLE["truth"], lw=1.6, label="truth", zorder=2)
    if dut is not None:
        d = plane(dut)[1]
        ax.plot(d[:, 0] * k, d[:, 1] * k, color=STYLE["dut"], lw=1.0, label="DUT", zorder=3)
    first = parts[0]
    ax.plot(first[0, 0] * k, first[0, 1] * k, "o", ms=9, mfc="white", mec="black", mew=1.5, label="start", zorder=4)
    ax.plot(first[-1, 0] * k, first[-1, 1] * k, "s", ms=8, mfc="black", mec="black", label="end", zorder=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"east of the start, {unit}")
    ax.set_ylabel(f"north of the start, {unit}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    title = f"{head}: trajectory"
    ax.set_title(title)
    margins(fig)
    if xy is None:
        who = "the DUT's solutions (no truth recorded)"
    elif dut is None:
        who = "truth only (the recording holds no DUT output)"
    else:
        who = "truth (black) and the DUT's valid solutions (blue)"
    caption = (
        f"Trajectory on the tangent plane at the start ({unit}, equal scales): {who}; start circle, end square."
        + (" Orange: the track during fault windows." if "fault window" in done else "")
        + (" Grey: the track with GNSS blocked." if "GNSS blocked" in done else "")
    )
    return Figure("trajectory", title, render(fig), f"Map of the drive, {extent * k:.3g} {unit} across: {who}.",
                  caption, {"extent_m": extent})


# -- errors against time ---------------------------------------------------------------------
#: panel -> (accuracy quantity bounded on it, SI -> display scale, unit, signed)
_PANELS = {
    "horizontal": ("horizontal", 1.0, "m", False),
    "vertical": ("vertical", 1.0, "m", True),
    "heading": ("heading", ARCMIN, "arcmin", True),
    "velocity": ("velocity_horizontal", 1.0, "m/s", False),
}
#: statistics whose limit bounds the per-epoch error (a line on the time series)
_LINE_STATS = {"max", "rms", "mean", "p50", "p68", "p95", "p99", "cep50", "cep95", "final", "interval_max"}


def limit_lines(data: FigureData, criteria: Sequence[Mapping[str, Any]], quantity: str, signed: bool
                ) -> list[tuple[Mapping[str, Any], list[float], Any]]:
    """``(criterion, limit values SI, window)`` of the criteria bounding ``quantity``."""
    out = []
    for c in criteria:
        parts = str(c.get("metric", "")).split(".")
        if len(parts) != 3 or parts[0] != "accuracy" or parts[1] != quantity or parts[2] not in _LINE_STATS:
            continue
        lim = c.get("limit_si") or {}
        vals = [float(v) for v in (lim.get("low"), lim.get("high")) if isinstance(v, (int, float))]
        if signed and (parts[2] != "mean" or c.get("comparator") == "within"):
            vals += [-v for v in vals if v > 0]
        w = data.window(c.get("window"))
        if vals and w is not None:
            out.append((c, vals, w))
    return out


def _bound(c: Mapping[str, Any], scale: float) -> str:
    """``≤ 10``, ``≥ 0.9``, ``in 99 – 101`` of a criterion's SI limits, in display units."""
    lim = c.get("limit_si") or {}
    lo, hi = lim.get("low"), lim.get("high")
    if c.get("comparator") == "within" and hi is not None:
        return f"within ±{fmt(hi * scale)}"
    if lo is not None and hi is not None:
        return f"in {fmt(lo * scale)} – {fmt(hi * scale)}"
    return f"≥ {fmt(lo * scale)}" if lo is not None else f"≤ {fmt(hi * scale)}"


def errors_figure(data: FigureData, criteria: Sequence[Mapping[str, Any]], head: str) -> Figure | None:
    e = data.errors
    if e is None:
        return None
    u = e.usable
    t = e.t_ns[u] * 1e-9
    series = {
        "horizontal": np.hypot(e.pos[u, 0], e.pos[u, 1]),
        "vertical": e.pos[u, 2],
        "heading": e.att[u, 0] * ARCMIN,
        "velocity": np.hypot(e.vel[u, 0], e.vel[u, 1]),
    }
    names = {"horizontal": "horizontal position error", "vertical": "vertical position error (up)",
             "heading": "heading error", "velocity": "horizontal velocity error"}
    gap = max(1.0, 5.0 * float(np.median(np.diff(t)))) if len(t) > 1 else 1.0
    fig, axes = subplots(4, 1, figsize=(10.0, 9.0), sharex=True)
    spans, switches = data.spans(), data.switch_times_s()
    drawn: list[str] = []
    labelled: set[str] = set()
    values: dict[str, float] = {}
    for ax, (key, (quantity, scale, unit, signed)) in zip(axes, _PANELS.items(), strict=True):
        shade(ax, spans, labelled)
        mark_switches(ax, switches, labelled)
        line(ax, t, series[key], gap, color=STYLE["dut"], lw=0.8, label=names[key])
        values[f"{key}_max"] = float(np.max(np.abs(series[key])))
        peak = values[f"{key}_max"]  # display unit, as the series
        for c, vals, w in limit_lines(data, criteria, quantity, signed):
            far = peak > 0 and min(abs(v) * scale for v in vals) > 3.0 * peak  # would flatten the curve
            for v in [] if far else vals:
                for a, b in w.intervals:
                    ax.hlines(v * scale, a * 1e-9, b * 1e-9, colors=STYLE["limit"], linestyles="--", lw=1.2)
            stat = str(c["metric"]).split(".")[2]
            what = "|mean|" if signed and stat == "mean" else stat
            text = f"{c['id']}: {what} {_bound(c, scale)} {unit} ({c.get('window')})"
            ax.plot([], [], color=STYLE["limit"], ls="--" if not far else ":", lw=1.2,
                    label=text + (", off scale" if far else ""))
            drawn.append(f"{c['id']} ({c['metric']} {_bound(c, scale)} {unit} over '{c.get('window')}'"
                         + (", beyond 3 times the largest error: not drawn" if far else "") + ")")
        if signed:
            ax.axhline(0.0, color="0.3", lw=0.5)
        ax.set_ylabel(f"{key}, {unit}")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=8, ncol=2)
    axes[-1].set_xlabel("bench time, s")
    title = f"{head}: errors against time"
    axes[0].set_title(title)
    margins(fig)
    caption = (
        "DUT minus truth at the DUT's valid epochs: horizontal and vertical position (m), heading (arcmin), "
        "horizontal velocity (m/s). Orange: fault windows; grey: GNSS blocked; purple dotted: frame switches."
        + (" Red dashed: criterion limits, drawn over the window each judges: " + "; ".join(drawn) + "."
           if drawn else " No criterion bounds these errors epoch by epoch, so no limit is drawn.")
        + " Statistics (RMS, percentiles) are limits on the whole window, shown for scale."
    )
    alt = (f"Errors against time over {t[-1] - t[0]:.0f} s: horizontal max {values['horizontal_max']:.3g} m, "
           f"heading max {values['heading_max']:.3g} arcmin.")
    return Figure("errors", title, render(fig), alt, caption, values)


# -- horizontal error CDF --------------------------------------------------------------------
def cdf_window(data: FigureData, criteria: Sequence[Mapping[str, Any]]) -> tuple[str, Mapping[str, Any] | None]:
    """The window of the CDF: that of a CEP criterion, else ``converged`` when the case sets
    a convergence time, else ``all``."""
    for c in criteria:
        if str(c.get("metric", "")).startswith("accuracy.horizontal.cep") and data.window(c.get("window")) is not None:
            return str(c.get("window")), c
    return ("converged" if data.settings.convergence_ns > 0 else "all"), None


def cdf_figure(data: FigureData, criteria: Sequence[Mapping[str, Any]], head: str) -> Figure | None:
    e = data.errors
    if e is None:
        return None
    name, crit = cdf_window(data, criteria)
    w = data.window(name)
    if w is None:
        return None
    try:
        idx = select(e, w)
        cep50 = accuracy_value("horizontal", "cep50", e, w)[0]
        cep95 = accuracy_value("horizontal", "cep95", e, w)[0]
    except ScoringError:
        return None
    h = np.sort(np.hypot(e.pos[idx, 0], e.pos[idx, 1]))
    p = np.arange(1, len(h) + 1) / len(h)
    if len(h) > 4000:
        keep = np.unique(np.linspace(0, len(h) - 1, 4000).astype(np.int64))
        h, p = h[keep], p[keep]
    fig, ax = subplots(figsize=(8.0, 5.0))
    ax.plot(h, p * 100.0, color=STYLE["dut"], lw=1.5, drawstyle="steps-post", label=f"DUT ({len(idx)} epochs)")
    ax.axvline(cep50, color="tab:green", ls="-.", lw=1.3, label=f"CEP50 = {fmt(cep50)} m")
    ax.axvline(cep95, color="tab:purple", ls="-.", lw=1.3, label=f"CEP95 = {fmt(cep95)} m")
    ax.axhline(50.0, color="0.6", lw=0.6)
    ax.axhline(95.0, color="0.6", lw=0.6)
    limit_note = ""
    if crit is not None:
        hi = (crit.get("limit_si") or {}).get("high")
        if isinstance(hi, (int, float)):
            stat = str(crit["metric"]).rsplit(".", 1)[1].upper()
            far = float(hi) > 3.0 * float(h[-1])  # would flatten the curve
            label = f"{crit['id']}: {stat} ≤ {fmt(hi)} m" + (", off scale" if far else "")
            if far:
                ax.plot([], [], color=STYLE["limit"], ls=":", lw=1.2, label=label)
            else:
                ax.axvline(float(hi), color=STYLE["limit"], ls="--", lw=1.2, label=label)
            limit_note = f" Red dashed: the limit of {crit['id']} ({crit['metric']})" + (
                ", beyond 3 times the largest error: not drawn." if far else ".")
    ax.set_xlabel("horizontal position error, m")
    ax.set_ylabel("epochs at or below, %")
    ax.set_ylim(0, 101)
    ax.set_xlim(left=0)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=9)
    title = f"{head}: horizontal error distribution ({name})"
    ax.set_title(title)
    margins(fig)
    caption = (
        f"Cumulative distribution of the horizontal position error over window '{name}' ({w.text()}); "
        f"CEP50 and CEP95 as the scoring computes them (accuracy.horizontal.cep50/cep95)." + limit_note
    )
    alt = f"CDF of the horizontal error: CEP50 {cep50:.3g} m, CEP95 {cep95:.3g} m over {len(idx)} epochs."
    return Figure("cdf", title, render(fig), alt, caption, {"cep50": cep50, "cep95": cep95, "epochs": float(len(idx))})
