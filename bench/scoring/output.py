"""Output quality of the DUT: rate, latency, missing epochs, bad frames, integrity.

Computed over the DUT's NAV_SOLUTION epochs whose time of validity falls in the window:

* ``rate`` -- distinct times of validity delivered in the window (each interval taken
  half-open, ``[start, end)``) divided by the window's duration, Hz: the epochs really
  delivered, valid-flagged or not; ``median_rate`` -- 1 / median interval between them;
  ``mean_rate`` -- epochs per second over the span they cover;
* ``latency_mean``, ``latency_p95``, ``latency_max`` -- arrival bench time minus time of
  validity (``rx_ns - t_ns``), s;
* ``missing_epochs`` -- against the nominal output period P: every gap g between
  consecutive epochs, and from each window interval's edges to its first/last epoch,
  counts ``max(0, round(g / P) - 1)``; ``missing_fraction`` = missing / (missing + present);
  ``max_gap`` -- the longest such gap, s;
* ``counter_gaps`` -- epochs missing by the epoch counter (modulo 256);
* ``invalid_fraction`` -- fraction of epochs with the valid bit clear;
* ``quality_unmatched`` -- solutions without a NAV_QUALITY of the same time of validity,
  plus quality records without a solution;
* ``bad_frames`` -- frames from the DUT the bench rejected (CRC, counter, length...),
  ``bad_frame_rate`` per second (shown per hour).

Over the epochs that arrived in the window or whose time of validity falls in it (a time
of validity thrown far outside the run still counts), in arrival order, see
:mod:`bench.scoring.epochs`: ``repeated``, ``out_of_order``, ``time_jumps``,
``counter_faults``, ``out_of_range``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.scoring import epochs
from bench.scoring.data import NoDataError
from bench.scoring.epochs import EpochBounds
from bench.scoring.windows import Window

__all__ = ["OUTPUT_METRICS", "output_value"]

#: name -> (dimension, display unit, description)
OUTPUT_METRICS: dict[str, tuple[str, str, str]] = {
    "rate": ("frequency", "Hz", "output rate (epochs delivered / window duration)"),
    "median_rate": ("frequency", "Hz", "output rate (1 / median interval)"),
    "mean_rate": ("frequency", "Hz", "mean output rate over the span of the epochs"),
    "latency_mean": ("time", "ms", "mean latency, arrival minus time of validity"),
    "latency_p95": ("time", "ms", "95th percentile latency"),
    "latency_max": ("time", "ms", "largest latency"),
    "missing_epochs": ("count", "1", "epochs missing against the nominal rate"),
    "missing_fraction": ("dimensionless", "%", "fraction of epochs missing"),
    "max_gap": ("time", "s", "longest gap between epochs"),
    "counter_gaps": ("count", "1", "epochs missing by the epoch counter"),
    "counter_faults": ("count", "1", "epoch counter stuck, skipped or reset against the time of validity"),
    "repeated": ("count", "1", "epochs whose time of validity was already delivered"),
    "out_of_order": ("count", "1", "epochs whose time of validity is before the previous one's"),
    "time_jumps": ("count", "1", "jumps of the time of validity, back or forward"),
    "out_of_range": ("count", "1", "valid epochs with a value not finite or outside its physical range"),
    "invalid_fraction": ("dimensionless", "%", "fraction of epochs flagged invalid"),
    "quality_unmatched": ("count", "1", "NAV_SOLUTION/NAV_QUALITY records without partner"),
    "bad_frames": ("count", "1", "bad frames received from the DUT"),
    "bad_frame_rate": ("frequency", "1/h", "bad frames from the DUT per hour"),
}

_SEQUENCE = ("repeated", "out_of_order", "time_jumps", "counter_faults", "out_of_range")


def _gaps(t: np.ndarray, window: Window) -> np.ndarray:
    """Gaps (ns) between consecutive epochs and from interval edges, per interval."""
    out: list[np.ndarray] = []
    ids = window.interval_ids(t)
    for k, (a, b) in enumerate(window.intervals):
        tk = t[ids == k]
        if len(tk) == 0:
            out.append(np.array([b - a]))
            continue
        out.append(np.concatenate([[tk[0] - a], np.diff(tk), [b - tk[-1]]]))
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def _bad_frames(name: str, bad_frames: list[dict[str, Any]], window: Window) -> tuple[float, dict[str, Any]]:
    t_bad = np.array([int(b["t_ns"]) for b in bad_frames], dtype=np.int64)
    inside = window.mask(t_bad) if len(t_bad) else np.zeros(0, dtype=bool)
    kinds: dict[str, int] = {}
    for b, ok in zip(bad_frames, inside, strict=True):
        if ok:
            kinds[str(b.get("kind", "?"))] = kinds.get(str(b.get("kind", "?")), 0) + 1
    n = int(np.sum(inside))
    details: dict[str, Any] = {"by_kind": kinds}
    return (float(n) if name == "bad_frames" else n / window.duration_s), details


def _sequence(name: str, nav: np.ndarray, window: Window, bounds: EpochBounds) -> tuple[float, dict[str, Any]]:
    """The sequence and range checks over the epochs that arrived in the window or whose
    time of validity falls in it, in arrival order."""
    sel = window.mask(nav["t_ns"]) | window.mask(nav["rx_ns"])
    arrived = epochs.subset(nav, sel)
    if len(arrived) == 0:
        raise NoDataError(f"no DUT epoch in window {window.text()}")
    if name == "repeated":
        n, det = epochs.repeated(arrived["t_ns"])
    elif name == "out_of_order":
        n, det = epochs.out_of_order(arrived["t_ns"])
    elif name == "time_jumps":
        n, det = epochs.time_jumps(arrived["t_ns"], arrived["rx_ns"], bounds.jump_ns)
    elif name == "counter_faults":
        n, det = epochs.counter_faults(arrived)
    else:
        n, det = epochs.out_of_range(arrived, bounds)
    return float(n), {"epochs": len(arrived), "window": window.text(), **det}


def _delivered(t_unique: np.ndarray, window: Window) -> int:
    """Distinct times of validity inside the window's intervals taken half-open."""
    return sum(int(np.sum((t_unique >= a) & (t_unique < b))) for a, b in window.intervals)


def output_value(
    name: str,
    nav: np.ndarray | None,
    quality: np.ndarray | None,
    bad_frames: list[dict[str, Any]],
    window: Window,
    nominal_period_ns: int,
    bounds: EpochBounds | None = None,
) -> tuple[float, dict[str, Any]]:
    """Value (SI) of ``output.<name>`` over ``window``."""
    if window.empty:
        raise NoDataError(f"window {window.spec.name!r} selects no time in this run")
    if name in ("bad_frames", "bad_frame_rate"):
        return _bad_frames(name, bad_frames, window)
    if nav is None or len(nav) == 0:
        raise NoDataError("the recording holds no DUT output (/dut/nav_solution)")
    if name in _SEQUENCE:
        return _sequence(name, nav, window, bounds or EpochBounds())
    sel = window.mask(nav["t_ns"])
    arrived = epochs.subset(nav, sel)  # arrival order
    t_unique = epochs.distinct(arrived["t_ns"])
    details: dict[str, Any] = {"epochs": len(arrived), "window": window.text()}
    if name in ("missing_epochs", "missing_fraction", "max_gap"):
        gaps = _gaps(t_unique, window)
        missing = int(np.sum(np.maximum(0, np.rint(gaps / nominal_period_ns).astype(np.int64) - 1)))
        details["nominal_rate_hz"] = 1e9 / nominal_period_ns
        if name == "missing_epochs":
            return float(missing), details
        if name == "max_gap":
            return float(np.max(gaps)) * 1e-9, details
        total = missing + len(t_unique)
        return (missing / total if total else 1.0), details
    if name == "rate":
        details["delivered"] = _delivered(t_unique, window)
        return details["delivered"] / window.duration_s, details
    if len(arrived) == 0:
        raise NoDataError(f"no DUT epoch in window {window.text()}")
    if name == "invalid_fraction":
        return float(np.mean(arrived["valid"] == 0)), details
    if name == "quality_unmatched":
        qt = np.zeros(0, np.int64)
        if quality is not None:
            qt = epochs.distinct(quality["t_ns"][window.mask(quality["t_ns"])])
        both = np.intersect1d(t_unique, qt, assume_unique=True)
        return float(len(t_unique) + len(qt) - 2 * len(both)), details
    if name.startswith("latency"):
        lat = (arrived["rx_ns"] - arrived["t_ns"]).astype(np.float64) * 1e-9
        v = {"latency_mean": np.mean, "latency_max": np.max, "latency_p95": lambda x: np.percentile(x, 95)}[name](lat)
        return float(v), details
    if len(t_unique) < 2:
        raise NoDataError(f"fewer than two DUT epochs in window {window.text()}: no rate")
    if name == "median_rate":
        return 1e9 / float(np.median(np.diff(t_unique))), details
    if name == "mean_rate":
        return (len(t_unique) - 1) / ((t_unique[-1] - t_unique[0]) * 1e-9), details
    if name == "counter_gaps":
        ep = epochs.first_arrivals(arrived)["epoch"].astype(np.int64)
        step = (np.diff(ep) - 1) % 256
        return float(np.sum(step)), details
    raise KeyError(name)
