"""Scoring windows: the stretches of bench time a metric is computed over.

A window is a sorted list of disjoint half-open intervals ``[start_ns, end_ns)`` (an
``(K, 2)`` int64 array). It is described by a :class:`WindowSpec` and resolved against a
run (its truth span, segments, faults and the case's convergence time):

* the base is the whole run (``all``), or from the convergence time on (``converged``);
* selectors narrow it; values within one selector are united, different selectors
  intersect: ``gnss`` flags of segments (``blocked`` = outages), segment ``kinds``,
  segment ``indices``, segment ``labels``, fault ``targets`` (the recorded fault windows
  of those targets, ``*`` for every target);
* ``start``/``end`` clip the result.

The last interval is closed at the end of the truth so the last epoch counts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bench.faults.schedule import FaultWindow

__all__ = ["WindowSpec", "Window", "resolve_window", "intersect", "union", "in_window"]


@dataclass(frozen=True)
class WindowSpec:
    """How a window is chosen (see the module docstring). Times in ns."""

    name: str = "all"
    converged: bool = False
    start_ns: int | None = None
    end_ns: int | None = None
    gnss: tuple[str, ...] = ()
    kinds: tuple[str, ...] = ()
    indices: tuple[int, ...] = ()
    labels: tuple[str, ...] = ()
    fault_targets: tuple[str, ...] = ()

    def describe(self) -> str:
        """Human-readable description for reports."""
        parts = ["after convergence" if self.converged else "whole run"]
        if self.gnss:
            parts.append(f"GNSS {'/'.join(self.gnss)} segments")
        if self.kinds:
            parts.append(f"{'/'.join(self.kinds)} segments")
        if self.indices:
            parts.append(f"segments {', '.join(str(i) for i in self.indices)}")
        if self.labels:
            parts.append(f"segments labelled {', '.join(self.labels)}")
        if self.fault_targets:
            parts.append(f"fault windows on {', '.join(self.fault_targets)}")
        if self.start_ns is not None:
            parts.append(f"from {self.start_ns * 1e-9:g} s")
        if self.end_ns is not None:
            parts.append(f"to {self.end_ns * 1e-9:g} s")
        return ", ".join(parts)


@dataclass(frozen=True)
class Window:
    """A resolved window: its spec, its intervals (K, 2) ns, and the end of the run."""

    spec: WindowSpec
    intervals: np.ndarray
    run_end_ns: int

    @property
    def empty(self) -> bool:
        return len(self.intervals) == 0

    @property
    def duration_s(self) -> float:
        return float(np.sum(self.intervals[:, 1] - self.intervals[:, 0])) * 1e-9 if len(self.intervals) else 0.0

    def mask(self, t_ns: np.ndarray) -> np.ndarray:
        """Which times fall in the window (an interval ending at the run's end includes it)."""
        return in_window(t_ns, self.intervals, self.run_end_ns)

    def interval_ids(self, t_ns: np.ndarray) -> np.ndarray:
        """Index of the interval holding each time, -1 outside."""
        out = np.full(len(t_ns), -1, dtype=np.int64)
        for k, (a, b) in enumerate(self.intervals):
            sel = (t_ns >= a) & ((t_ns < b) | ((b >= self.run_end_ns) & (t_ns <= b)))
            out[sel] = k
        return out

    def text(self) -> str:
        spans = ", ".join(f"{a * 1e-9:g}-{b * 1e-9:g} s" for a, b in self.intervals[:6])
        more = f" (+{len(self.intervals) - 6} more)" if len(self.intervals) > 6 else ""
        return f"{self.spec.name}: {spans or 'empty'}{more}"


def _norm(iv: list[tuple[int, int]]) -> np.ndarray:
    iv = sorted((a, b) for a, b in iv if b > a)
    out: list[list[int]] = []
    for a, b in iv:
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def union(*windows: np.ndarray) -> np.ndarray:
    """Union of interval arrays."""
    return _norm([(int(a), int(b)) for w in windows for a, b in w])


def intersect(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Intersection of two interval arrays."""
    out: list[tuple[int, int]] = []
    for a, b in x:
        for c, d in y:
            lo, hi = max(a, c), min(b, d)
            if hi > lo:
                out.append((int(lo), int(hi)))
    return _norm(out)


def in_window(t_ns: np.ndarray, intervals: np.ndarray, run_end_ns: int) -> np.ndarray:
    """Boolean mask of ``t_ns`` inside ``intervals``; an interval ending at or after
    ``run_end_ns`` is closed on the right."""
    t_ns = np.asarray(t_ns)
    m = np.zeros(len(t_ns), dtype=bool)
    for a, b in intervals:
        m |= (t_ns >= a) & ((t_ns < b) | ((b >= run_end_ns) & (t_ns <= b)))
    return m


def _segments(segments: Sequence[dict], pred) -> np.ndarray:
    return _norm([(round(s["start_s"] * 1e9), round(s["end_s"] * 1e9)) for s in segments if pred(s)])


def resolve_window(
    spec: WindowSpec,
    span_ns: tuple[int, int],
    *,
    convergence_ns: int = 0,
    segments: Sequence[dict] = (),
    faults: Sequence[FaultWindow] = (),
) -> Window:
    """Resolve ``spec`` against a run's truth span, segments and recorded faults."""
    t0, t1 = span_ns
    base = np.array([[t0, t1]], dtype=np.int64)
    if spec.converged:
        base = intersect(base, np.array([[convergence_ns, t1]], dtype=np.int64))
    selectors: list[np.ndarray] = []
    if spec.gnss:
        selectors.append(_segments(segments, lambda s: s.get("gnss") in spec.gnss))
    if spec.kinds:
        selectors.append(_segments(segments, lambda s: s.get("kind") in spec.kinds))
    if spec.indices:
        selectors.append(_segments(segments, lambda s: s.get("index") in spec.indices))
    if spec.labels:
        selectors.append(_segments(segments, lambda s: s.get("label") in spec.labels))
    if spec.fault_targets:
        every = "*" in spec.fault_targets
        selectors.append(_norm([(w.start_ns, w.end_ns) for w in faults if every or w.target in spec.fault_targets]))
    out = base
    for sel in selectors:
        out = intersect(out, sel)
    lo = spec.start_ns if spec.start_ns is not None else t0
    hi = spec.end_ns if spec.end_ns is not None else t1
    out = intersect(out, np.array([[lo, hi]], dtype=np.int64))
    return Window(spec, out, t1)
