"""Accuracy metrics: statistics of the DUT's navigation errors over a window.

Metric names are ``accuracy.<quantity>.<statistic>``.

Quantities (error = DUT minus truth, see :mod:`bench.scoring.align`):

========================  =====  ==========================================================
``horizontal``            m      norm of the east/north position error
``vertical``              m      up position error (signed)
``position``              m      3-D position error norm
``east``, ``north``       m      signed components
``along_track``           m      signed, along the truth's heading (forward positive: a
                                 solution lagging behind the vehicle is negative)
``cross_track``           m      signed, across the truth's heading (right positive)
``velocity``              m/s    3-D velocity error norm
``velocity_horizontal``   m/s    norm of the east/north velocity error
``velocity_east`` ...     m/s    signed components (``_east``, ``_north``, ``_up``)
``heading``               rad    heading error wrapped to [-180, 180) deg (signed)
``pitch``, ``roll``       rad    signed
``level``                 rad    max(abs(pitch error), abs(roll error)) per epoch
``attitude``              rad    total attitude error angle on SO(3)
========================  =====  ==========================================================

Statistics over the window's usable epochs (the DUT's valid epochs inside the truth):
``rms``, ``mean`` (signed), ``std`` (population), ``max`` (of the absolute value),
``p50``/``p68``/``p95``/``p99`` (percentiles of the absolute value, linear
interpolation between order statistics), ``final`` (absolute value at the window's last
epoch), ``growth`` (largest rise of the absolute value within one interval of the window
over its value at the interval's first epoch: the drift through an outage), and for
horizontal and 3-D position: ``cep50`` and ``cep95`` (horizontal 50 % and 95 % radius),
``r95`` and ``sep50`` (3-D 95 % and 50 % radius), ``of_distance`` (max error over the
window divided by the distance the truth drove within the window; shown in %), and the
per-interval figures of the i2Nav OutageStatistic style, for a window of several intervals
(one per outage): ``interval_max`` (the largest of the intervals' max errors) and
``interval_of_distance`` (the largest over the intervals of the interval's max error
divided by the distance the truth drove in that interval; shown in %; an interval in which
the vehicle did not move is listed but left out of it). Their details list every interval
of the window with usable epochs: start and end (s), max error, distance driven (m), and
the ratio (%).
Epochs are weighted equally (statistics are per epoch, as the DUT reported them).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from bench.scoring.align import NavErrors
from bench.scoring.data import DutDataError, NoDataError
from bench.scoring.windows import Window

__all__ = [
    "QUANTITIES", "STATS", "QUANTITY_STATS", "accuracy_value", "select", "stat_of", "interval_table", "SIGNED",
]

_Q = Callable[[NavErrors], np.ndarray]

#: quantity -> (dimension, display unit, function of the errors, description)
QUANTITIES: dict[str, tuple[str, str, _Q, str]] = {
    "horizontal": ("length", "m", lambda e: np.hypot(e.pos[:, 0], e.pos[:, 1]), "horizontal position error"),
    "vertical": ("length", "m", lambda e: e.pos[:, 2], "vertical position error"),
    "position": ("length", "m", lambda e: np.linalg.norm(e.pos, axis=1), "3-D position error"),
    "east": ("length", "m", lambda e: e.pos[:, 0], "east position error"),
    "north": ("length", "m", lambda e: e.pos[:, 1], "north position error"),
    "along_track": ("length", "m", lambda e: e.along_cross[:, 0], "along-track position error (forward positive)"),
    "cross_track": ("length", "m", lambda e: e.along_cross[:, 1], "cross-track position error (right positive)"),
    "velocity": ("velocity", "m/s", lambda e: np.linalg.norm(e.vel, axis=1), "3-D velocity error"),
    "velocity_horizontal": (
        "velocity",
        "m/s",
        lambda e: np.hypot(e.vel[:, 0], e.vel[:, 1]),
        "horizontal velocity error",
    ),
    "velocity_east": ("velocity", "m/s", lambda e: e.vel[:, 0], "east velocity error"),
    "velocity_north": ("velocity", "m/s", lambda e: e.vel[:, 1], "north velocity error"),
    "velocity_up": ("velocity", "m/s", lambda e: e.vel[:, 2], "up velocity error"),
    "heading": ("angle", "arcmin", lambda e: e.att[:, 0], "heading error"),
    "pitch": ("angle", "arcmin", lambda e: e.att[:, 1], "pitch error"),
    "roll": ("angle", "arcmin", lambda e: e.att[:, 2], "roll error"),
    "level": ("angle", "arcmin", lambda e: np.maximum(np.abs(e.att[:, 1]), np.abs(e.att[:, 2])), "level error"),
    "attitude": ("angle", "arcmin", lambda e: e.att_angle, "attitude error angle (SO(3))"),
}
#: Quantities with a sign (``mean`` keeps it; the other statistics use absolute values).
SIGNED = {
    "vertical", "east", "north", "along_track", "cross_track", "velocity_east", "velocity_north", "velocity_up",
    "heading", "pitch", "roll",
}

STATS = ("rms", "mean", "std", "max", "p50", "p68", "p95", "p99", "final", "growth")
_EXTRA = {
    "horizontal": ("cep50", "cep95", "of_distance", "interval_max", "interval_of_distance"),
    "position": ("r95", "sep50", "of_distance", "interval_max", "interval_of_distance"),
}
#: quantity -> its statistics
QUANTITY_STATS: dict[str, tuple[str, ...]] = {q: STATS + _EXTRA.get(q, ()) for q in QUANTITIES}


def select(errors: NavErrors, window: Window) -> np.ndarray:
    """Indices of the usable epochs in ``window``.

    Raises :class:`NoDataError` when no DUT epoch falls in the window at all and
    :class:`DutDataError` when there are epochs but the DUT flagged all of them invalid.
    """
    if window.empty:
        what = window.spec.describe()
        named = f"{window.spec.name!r} ({what})" if window.spec.name != what else repr(what)
        raise NoDataError(f"window {named} selects no time in this run")
    in_w = window.mask(errors.t_ns) & errors.covered
    if not np.any(in_w):
        raise NoDataError(f"no DUT epoch in window {window.text()}")
    idx = np.flatnonzero(in_w & errors.usable)
    if len(idx) == 0:
        raise DutDataError(f"the DUT flagged all {int(np.sum(in_w))} epochs of window {window.text()} invalid")
    return idx


def stat_of(
    stat: str,
    values: np.ndarray,
    t_ns: np.ndarray,
    window: Window,
    distance: Callable[[Window], float] | None = None,
) -> float:
    """One statistic of the error values at the selected epochs (times ``t_ns``)."""
    a = np.abs(values)
    if stat == "rms":
        return float(np.sqrt(np.mean(values * values)))
    if stat == "mean":
        return float(np.mean(values))
    if stat == "std":
        return float(np.std(values))
    if stat == "max":
        return float(np.max(a))
    if stat in ("p50", "p68", "p95", "p99", "cep50", "cep95", "r95", "sep50"):
        q = {"p50": 50, "p68": 68, "p95": 95, "p99": 99, "cep50": 50, "cep95": 95, "r95": 95, "sep50": 50}[stat]
        return float(np.percentile(a, q))
    if stat == "final":
        return float(a[-1])
    if stat == "growth":
        ids = window.interval_ids(t_ns)
        best = -np.inf
        for k in np.unique(ids[ids >= 0]):
            seg = a[ids == k]
            best = max(best, float(np.max(seg) - seg[0]))
        return best
    if stat == "of_distance":
        if distance is None:
            raise NoDataError("distance travelled is not available")
        d = distance(window)
        if d <= 0.0:
            raise NoDataError(f"the vehicle drove no distance in window {window.text()}")
        return float(np.max(a)) / d
    raise KeyError(stat)


def interval_table(
    values: np.ndarray, t_ns: np.ndarray, window: Window, distance: Callable[[Window], float] | None
) -> list[dict[str, Any]]:
    """Per interval of ``window`` holding selected epochs: start and end (s), the max of the
    absolute values, the distance driven in the interval (m) and their ratio (%; None when
    the vehicle did not move)."""
    if distance is None:
        raise NoDataError("distance travelled is not available")
    ids = window.interval_ids(t_ns)
    rows = []
    for k in np.unique(ids[ids >= 0]):
        a, b = window.intervals[k]
        peak = float(np.max(np.abs(values[ids == k])))
        d = distance(Window(window.spec, window.intervals[k : k + 1], window.run_end_ns))
        rows.append({
            "start_s": float(a) * 1e-9,
            "end_s": float(b) * 1e-9,
            "max_error": peak,
            "distance_m": d,
            "of_distance_pct": 100.0 * peak / d if d > 0.0 else None,
        })
    return rows


def _interval_stat(stat: str, rows: list[dict[str, Any]], window: Window) -> float:
    if stat == "interval_max":
        return max(r["max_error"] for r in rows)
    ratios = [r["of_distance_pct"] for r in rows if r["of_distance_pct"] is not None]
    if not ratios:
        raise NoDataError(f"the vehicle drove no distance in any interval of window {window.text()}")
    return max(ratios) / 100.0


def accuracy_value(
    quantity: str,
    stat: str,
    errors: NavErrors,
    window: Window,
    distance: Callable[[Window], float] | None = None,
) -> tuple[float, dict[str, Any]]:
    """Value (SI) of ``accuracy.<quantity>.<stat>`` over ``window``, with details."""
    idx = select(errors, window)
    values = QUANTITIES[quantity][2](errors)[idx]
    if stat.startswith("interval_"):
        rows = interval_table(values, errors.t_ns[idx], window, distance)
        return _interval_stat(stat, rows, window), {"epochs": len(idx), "window": window.text(), "intervals": rows}
    value = stat_of(stat, values, errors.t_ns[idx], window, distance)
    return value, {"epochs": len(idx), "window": window.text()}
