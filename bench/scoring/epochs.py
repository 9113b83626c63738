"""Integrity of the DUT's epochs: their sequence in time and the physical range of their values.

These are the measures behind the output-integrity metrics of :mod:`bench.scoring.output`
(``repeated``, ``out_of_order``, ``time_jumps``, ``counter_faults``, ``out_of_range``).
Each takes NAV_SOLUTION records in arrival order; what they count:

* ``repeated`` -- arrivals whose time of validity was already delivered;
* ``out_of_order`` -- arrivals whose time of validity is before the previous arrival's;
* ``time_jumps`` -- steps between consecutive arrivals where the time of validity went
  back by more than ``jump``, or forward by more than ``jump`` beyond both the arrival
  step and the DUT's own period (a silent DUT that resumes, or a burst of late epochs,
  is not a jump: its times of validity follow the bench's clock);
* ``counter_faults`` -- epochs whose epoch counter (+1 per epoch, modulo 256) does not
  step by the number of the DUT's periods its time of validity stepped (a stuck, skipped
  or reset counter); steps of an ambiguous length (more than a quarter period off the
  grid) are not judged;
* ``out_of_range`` -- epochs flagged valid with a value that is not finite or outside
  its physical range: latitude [-90, 90] deg, longitude [-180, 180] deg, heading
  [0, 360) deg, pitch [-90, 90] deg, roll [-180, 180] deg, height and speed within
  :class:`EpochBounds`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "EpochBounds",
    "OutputIntegrity",
    "repeated",
    "out_of_order",
    "time_jumps",
    "counter_faults",
    "out_of_range",
    "first_arrivals",
    "distinct",
    "subset",
]

_HALF_PI = math.pi / 2.0
_TWO_PI = 2.0 * math.pi
_EPS = 1e-12  # rad: the ICD's 1e-7 deg grid is far coarser


@dataclass(frozen=True)
class EpochBounds:
    """What counts as a time jump (ns) and the physical range of height (m) and speed (m/s)."""

    jump_ns: int = 1_000_000_000
    height_m: tuple[float, float] = (-1000.0, 20000.0)
    speed_mps: float = 300.0


@dataclass(frozen=True)
class OutputIntegrity:
    """``[scoring.integrity]`` of a case as parsed: the bounds the metrics use, the limits
    the case loosened (check -> SI limit), the checks it switched off (check -> reason),
    why, and when the invalid-flag and NAV_QUALITY checks start (None: at convergence)."""

    bounds: EpochBounds = field(default_factory=EpochBounds)
    limits: Mapping[str, float] = field(default_factory=dict)
    waived: Mapping[str, str] = field(default_factory=dict)
    reason: str = ""
    invalid_after_ns: int | None = None


def subset(records: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``records[mask]``, or ``records`` itself when the mask selects all (no copy)."""
    return records if bool(np.all(mask)) else records[mask]


def distinct(t_ns: np.ndarray) -> np.ndarray:
    """The distinct values of ``t_ns``, sorted (by sorting: faster than hashing here)."""
    s = np.sort(np.asarray(t_ns, dtype=np.int64))
    return s[np.concatenate([[True], s[1:] != s[:-1]])] if len(s) else s


def repeated(t_ns: np.ndarray) -> tuple[int, dict]:
    """Arrivals (in arrival order) whose time of validity was delivered before."""
    n = len(t_ns) - len(distinct(t_ns))
    if n == 0:
        return 0, {}
    _, first = np.unique(t_ns, return_index=True)
    again = np.ones(len(t_ns), dtype=bool)
    again[first] = False
    return n, {"first_t_s": float(t_ns[np.argmax(again)]) * 1e-9}


def out_of_order(t_ns: np.ndarray) -> tuple[int, dict]:
    """Arrivals whose time of validity is before the previous arrival's."""
    back = np.diff(t_ns.astype(np.int64)) < 0
    first = int(t_ns[1:][back][0]) if back.any() else None
    return int(np.sum(back)), ({"first_t_s": first * 1e-9} if first is not None else {})


def _period(t_ns: np.ndarray) -> int:
    """The DUT's own period: the median step of its distinct times of validity (ns)."""
    u = distinct(t_ns)
    return int(np.median(np.diff(u))) if len(u) > 1 else 0


def time_jumps(t_ns: np.ndarray, rx_ns: np.ndarray, jump_ns: int) -> tuple[int, dict]:
    """Steps where the time of validity jumped (see the module docstring)."""
    if len(t_ns) < 2:
        return 0, {}
    dt = np.diff(t_ns.astype(np.int64))
    drx = np.diff(rx_ns.astype(np.int64))
    period = _period(t_ns)
    fwd = dt > np.maximum(drx, period) + jump_ns
    back = dt < -jump_ns
    details: dict = {"forward": int(np.sum(fwd)), "backward": int(np.sum(back)), "jump_s": jump_ns * 1e-9}
    bad = np.flatnonzero(fwd | back)
    if len(bad):
        details["first_at_s"] = float(t_ns[bad[0]]) * 1e-9
        details["first_step_s"] = float(dt[bad[0]]) * 1e-9
    return len(bad), details


def first_arrivals(nav: np.ndarray) -> np.ndarray:
    """The first arrival of each distinct time of validity, in time order (``nav`` itself,
    not a copy, when its times of validity already rise strictly)."""
    if bool(np.all(np.diff(nav["t_ns"]) > 0)):
        return nav
    _, first = np.unique(nav["t_ns"], return_index=True)
    return nav[first]


def counter_faults(nav: np.ndarray) -> tuple[int, dict]:
    """Epochs whose counter disagrees with the step of their time of validity."""
    t, first = np.unique(nav["t_ns"], return_index=True)  # the first arrivals, in time order
    period = _period(t)
    if len(t) < 2 or period <= 0:
        return 0, {}
    steps = np.diff(t.astype(np.int64)) / period
    k = np.rint(steps)
    clear = np.abs(steps - k) <= 0.25
    dep = np.diff(nav["epoch"][first].astype(np.int64)) % 256
    bad = clear & (dep != (k.astype(np.int64) % 256))
    stuck = bad & (dep == 0)
    details: dict = {"stuck": int(np.sum(stuck)), "other": int(np.sum(bad & ~stuck)), "period_s": period * 1e-9}
    if bad.any():
        details["first_at_s"] = float(t[1:][bad][0]) * 1e-9
    return int(np.sum(bad)), details


def out_of_range(nav: np.ndarray, bounds: EpochBounds) -> tuple[int, dict]:
    """Epochs flagged valid with a value not finite or outside its physical range."""
    v = subset(nav, nav["valid"] != 0)
    lo_h, hi_h = bounds.height_m
    speed = np.linalg.norm(v["vel_n"], axis=1) if len(v) else np.zeros(0)
    checks = {
        "latitude": np.abs(v["lat"]) <= _HALF_PI + _EPS,
        "longitude": np.abs(v["lon"]) <= math.pi + _EPS,
        "heading": (v["heading"] >= -_EPS) & (v["heading"] < _TWO_PI),
        "pitch": np.abs(v["pitch"]) <= _HALF_PI + _EPS,
        "roll": np.abs(v["roll"]) <= math.pi + _EPS,
        "height": (v["h"] >= lo_h) & (v["h"] <= hi_h),
        "speed": speed <= bounds.speed_mps,
    }
    bad = np.zeros(len(v), dtype=bool)
    by_field: dict[str, int] = {}
    for name, ok in checks.items():  # NaN compares False: not finite is out of range
        n = int(np.sum(~ok))
        if n:
            by_field[name] = n
        bad |= ~ok
    details: dict = {"by_field": by_field}
    if bad.any():
        details["first_at_s"] = float(v["t_ns"][bad][0]) * 1e-9
    return int(np.sum(bad)), details
