"""Fault detection and isolation, per recorded fault window.

Each sensor-layer fault window on ``/faults`` is matched to the NAV_QUALITY bit of its
sensor (bit 0 odometer, 1 Doppler, 2 BDS, 3 IMU; the target name is split into words
and the first word naming a sensor picks the bit). For each window ``[start, end)``:

* **detected** if the chosen flag (``fault_detected``, ``excluded``, or ``either``) is
  set at an epoch in ``[start, end + grace)``; **latency** = first such epoch - start;
* **exclusion** = fraction of the DUT's epochs in ``[start, end)`` with the sensor's
  ``excluded`` bit set;
* **growth** = max horizontal error in ``[start, end]`` - the error at the last epoch at
  or before ``start``;
* **recovery** = time from ``end`` until the horizontal error is back within
  ``tolerance`` of its pre-fault level (max over ``[start - pre, start)``); infinite if
  it never is before the run ends; **residual** = error at ``end + after`` minus the
  pre-fault level.

**False alarms**: stretches of epochs, within the criterion's window and outside
every fault window of that sensor (each extended by ``grace``), whose flag is set, one per
stretch: a flag raised outside the windows, and a flag held on past a window's end plus
``grace`` (latched) or already set where the criterion's window begins, each counts once;
the rate is per time outside the fault windows.

**Fault class** (odometer windows only, NAV_QUALITY byte 28 ``odo_fault_class``): the
*declared* class of a sensor-layer odometer window follows from its kind
(:data:`ODOMETER_FAULT_CLASSES`); odometer windows overlapping in time, directly or
through others, form one event and are all declared the event's class
(:func:`declared_classes`). The *reported* class is the most frequent nonzero
``odo_fault_class`` among the epochs in ``[start, end + grace)`` at which the chosen flag
of the odometer bit is set (ties: the class reported first), 0 if none.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.faults.schedule import FaultWindow
from bench.scoring.align import NavErrors
from bench.scoring.data import NoDataError
from bench.scoring.windows import Window, intersect, union

__all__ = [
    "SENSOR_BITS",
    "target_bit",
    "FaultSettings",
    "WindowOutcome",
    "FaultAnalysis",
    "analyse_faults",
    "FLAGS",
    "ODOMETER_BIT",
    "ODOMETER_FAULT_CLASSES",
    "declared_classes",
    "reported_class",
]

#: NAV_QUALITY bit of each sensor name (ICD 2.2, bytes 26-27).
SENSOR_BITS = {"odometer": 0, "odo": 0, "doppler": 1, "radar": 1, "bds": 2, "gnss": 2, "imu": 3}
FLAGS = ("detected", "excluded", "either")
ODOMETER_BIT = 0
#: ICD odometer fault class (NAV_QUALITY byte 28; the values of ``bench.wire.icd``
#: ``ODO_FAULT_*``, which scoring may not import) of each sensor-layer odometer fault kind:
#: 1 longitudinal, 2 lateral, 3 vertical.
ODOMETER_FAULT_CLASSES = {"idling": 1, "sliding": 1, "no_output": 1, "sideslip": 2, "bump": 3}
_LONGITUDINAL, _LATERAL = 1, 2


def target_bit(target: str) -> int | None:
    """The NAV_QUALITY bit of a fault target (``odometer``, ``can:ODOMETER`` -> 0), or None."""
    for word in re.split(r"[^a-z0-9]+", target.lower()):
        if word in SENSOR_BITS:
            return SENSOR_BITS[word]
    return None


@dataclass(frozen=True)
class FaultSettings:
    """Case-level settings of the fault metrics (ns; m)."""

    grace_ns: int = 0
    pre_ns: int = 30_000_000_000
    after_ns: int = 30_000_000_000
    tolerance: float = 1.0
    flag: str = "detected"


@dataclass
class WindowOutcome:
    """What the DUT did in one fault window (times s, errors m)."""

    id: int
    target: str
    kind: str
    start_s: float
    end_s: float
    detected: bool
    latency_s: float
    exclusion: float
    epochs: int
    growth_m: float
    recovery_s: float
    residual_m: float
    #: ICD odometer fault class the window's event declares, the DUT's reported one, and
    #: whether they agree; None for windows without a class (not an odometer sensor fault).
    declared_class: int | None = None
    reported_class: int | None = None
    class_ok: bool | None = None

    def to_json(self) -> dict[str, Any]:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in self.__dict__.items()}


@dataclass
class FaultAnalysis:
    """Per-window outcomes and false alarms over one criterion window."""

    outcomes: list[WindowOutcome] = field(default_factory=list)
    false_alarms: list[dict[str, Any]] = field(default_factory=list)
    clear_time_s: float = 0.0

    def value(self, name: str) -> float:
        """Aggregate ``faults.<name>`` (see :data:`bench.scoring.metrics`)."""
        o = self.outcomes
        if name == "windows":
            return float(len(o))
        if name == "false_alarms":
            return float(len(self.false_alarms))
        if name == "false_alarm_rate":
            if self.clear_time_s <= 0.0:
                raise NoDataError("no fault-free time in the window to count false alarms over")
            return len(self.false_alarms) / self.clear_time_s
        if name in ("class_correct", "class_wrong"):
            classed = [w for w in o if w.class_ok is not None]
            if not classed:
                raise NoDataError(
                    "no odometer sensor fault window (idling, sliding, no_output, sideslip, bump) of the selected"
                    " targets in the window: the fault class applies to odometer windows only"
                )
            right = sum(1 for w in classed if w.class_ok)
            return right / len(classed) if name == "class_correct" else float(len(classed) - right)
        if not o:
            raise NoDataError("no recorded fault window of the selected targets in the window")
        det = [w for w in o if w.detected]
        if name == "detected":
            return float(len(det))
        if name == "missed":
            return float(len(o) - len(det))
        if name == "detection_rate":
            return len(det) / len(o)
        if name == "latency_max":
            return max(w.latency_s for w in o)  # inf when one was missed
        if name == "latency_mean":
            return float(np.mean([w.latency_s for w in det])) if det else math.inf
        if name == "exclusion_min":
            return min(w.exclusion for w in o)
        if name == "exclusion_mean":
            return float(np.mean([w.exclusion for w in o]))
        if name == "growth_max":
            return max(w.growth_m for w in o)
        if name == "recovery_max":
            return max(w.recovery_s for w in o)
        if name == "residual_max":
            return max(w.residual_m for w in o)
        raise KeyError(name)

    def details(self) -> dict[str, Any]:
        return {
            "windows": [w.to_json() for w in self.outcomes],
            "false_alarms": self.false_alarms,
            "fault_free_s": self.clear_time_s,
        }


def _flag_bits(quality: np.ndarray, bit: int, flag: str) -> np.ndarray:
    m = np.uint8(1 << bit)
    det = (quality["fault_detected"] & m) != 0
    exc = (quality["excluded"] & m) != 0
    return {"detected": det, "excluded": exc, "either": det | exc}[flag]


def declared_classes(faults: Sequence[FaultWindow]) -> dict[FaultWindow, int]:
    """Declared ICD odometer fault class of each classed window.

    Classed windows are the sensor-layer windows on the odometer bit whose kind is in
    :data:`ODOMETER_FAULT_CLASSES`. Those overlapping in time (``[start, end)``, directly
    or through others) form one event, and every window of it is declared the event's
    class: lateral (2) or vertical (3) over longitudinal (1); with both 2 and 3, the class
    of the earliest-starting window of class 2 or 3, lateral on a tie.
    """
    odo = sorted(
        (
            w
            for w in faults
            if w.layer == "sensor" and target_bit(w.target) == ODOMETER_BIT and w.kind in ODOMETER_FAULT_CLASSES
        ),
        key=lambda w: (w.start_ns, w.end_ns, w.id),
    )
    groups: list[list[FaultWindow]] = []
    group_end = 0
    for w in odo:
        if groups and w.start_ns < group_end:
            groups[-1].append(w)
            group_end = max(group_end, w.end_ns)
        else:
            groups.append([w])
            group_end = w.end_ns
    out: dict[FaultWindow, int] = {}
    for g in groups:
        cls = _event_class(g)
        out.update((w, cls) for w in g)
    return out


def _event_class(group: Sequence[FaultWindow]) -> int:
    """Class of one event (overlapping odometer windows): see :func:`declared_classes`."""
    strong = [w for w in group if ODOMETER_FAULT_CLASSES[w.kind] != _LONGITUDINAL]
    if not strong:
        return _LONGITUDINAL
    first = min(w.start_ns for w in strong)
    at_first = {ODOMETER_FAULT_CLASSES[w.kind] for w in strong if w.start_ns == first}
    return _LATERAL if _LATERAL in at_first else min(at_first)


def reported_class(classes: np.ndarray) -> int:
    """The class a DUT reported over a window: the most frequent nonzero value of
    ``classes`` (the ``odo_fault_class`` of the flagged epochs, in time order), the one
    reported first on a tie; 0 when there is none."""
    c = np.asarray(classes)
    nz = c[c != 0]
    if len(nz) == 0:
        return 0
    values, first, counts = np.unique(nz, return_index=True, return_counts=True)
    best = np.flatnonzero(counts == counts.max())
    return int(values[best[np.argmin(first[best])]])


def _episodes(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Start times of runs of True in ``f``."""
    rising = f & ~np.concatenate([[False], f[:-1]])
    return t[rising]


def analyse_faults(
    faults: Sequence[FaultWindow],
    quality: np.ndarray | None,
    errors: NavErrors | None,
    window: Window,
    settings: FaultSettings,
    *,
    targets: Sequence[str] = (),
    flag: str | None = None,
    layer: str = "sensor",
) -> FaultAnalysis:
    """Outcomes of the fault windows starting inside ``window`` (filtered by target/layer)."""
    if quality is None or len(quality) == 0:
        raise NoDataError("the recording holds no DUT quality output (/dut/nav_quality)")
    if window.empty:
        raise NoDataError(f"window {window.spec.name!r} selects no time in this run")
    flag = flag or settings.flag
    order = np.argsort(quality["t_ns"], kind="stable")
    q = quality[order]
    tq = q["t_ns"].astype(np.int64)
    chosen = [
        w
        for w in faults
        if (layer == "any" or w.layer == layer)
        and target_bit(w.target) is not None
        and (not targets or w.target in targets or any(target_bit(t) == target_bit(w.target) for t in targets))
    ]
    bits = sorted({target_bit(t) for t in targets} - {None}) if targets else sorted({0, 1, 2, 3})
    declared = declared_classes(faults)
    out = FaultAnalysis()
    if errors is not None:
        e_h = np.hypot(errors.pos[:, 0], errors.pos[:, 1])[errors.usable]
        t_e = errors.t_ns[errors.usable]
    else:
        e_h = t_e = np.zeros(0)
    for w in chosen:
        if not window.mask(np.array([w.start_ns]))[0]:
            continue
        bit = target_bit(w.target)
        assert bit is not None
        f = _flag_bits(q, bit, flag)
        exc = _flag_bits(q, bit, "excluded")
        in_det = (tq >= w.start_ns) & (tq < w.end_ns + settings.grace_ns)
        in_win = (tq >= w.start_ns) & (tq < w.end_ns)
        if not np.any(in_win):
            raise NoDataError(f"no DUT quality epoch inside fault window {w.id} ({w.kind} on {w.target})")
        hits = np.flatnonzero(in_det & f)
        detected = len(hits) > 0
        latency = (tq[hits[0]] - w.start_ns) * 1e-9 if detected else math.inf
        growth = recovery = residual = math.nan
        if len(t_e):
            growth, recovery, residual = _error_course(t_e, e_h, w, settings)
        cls = declared.get(w)
        reported = reported_class(q["odo_fault_class"][hits]) if cls is not None else None
        out.outcomes.append(
            WindowOutcome(
                w.id,
                w.target,
                w.kind,
                w.start_ns * 1e-9,
                w.end_ns * 1e-9,
                bool(detected),
                float(latency),
                float(np.mean(exc[in_win])),
                int(np.sum(in_win)),
                growth,
                recovery,
                residual,
                cls,
                reported,
                None if cls is None else reported == cls,
            )
        )
    # false alarms, per sensor bit, over the criterion window
    in_crit = window.mask(tq)
    clear = window.intervals
    for bit in bits:
        mine = [w for w in faults if target_bit(w.target) == bit]
        f = _flag_bits(q, bit, flag)
        protected = np.zeros(len(tq), dtype=bool)
        for w in mine:
            protected |= (tq >= w.start_ns) & (tq < w.end_ns + settings.grace_ns)
        # a flag raised outside the windows, or held on out of one (or into the criterion
        # window), counts from its first epoch outside: a latched flag is no detection
        for t0 in _episodes(tq, f & in_crit & ~protected):
            out.false_alarms.append({"sensor_bit": bit, "t_s": int(t0) * 1e-9})
    all_faults = np.array([[w.start_ns, w.end_ns + settings.grace_ns] for w in faults], dtype=np.int64).reshape(-1, 2)
    busy = intersect(clear, union(all_faults)) if len(all_faults) else np.zeros((0, 2), dtype=np.int64)
    total = float(np.sum(clear[:, 1] - clear[:, 0]))
    out.clear_time_s = (total - float(np.sum(busy[:, 1] - busy[:, 0]) if len(busy) else 0.0)) * 1e-9
    out.false_alarms.sort(key=lambda a: a["t_s"])
    return out


def _error_course(t: np.ndarray, e: np.ndarray, w: FaultWindow, s: FaultSettings) -> tuple[float, float, float]:
    """(growth, recovery, residual) of the horizontal error around a fault window."""
    before = np.flatnonzero(t <= w.start_ns)
    during = np.flatnonzero((t >= w.start_ns) & (t <= w.end_ns))
    if len(during) == 0:
        return math.nan, math.nan, math.nan
    e0 = e[before[-1]] if len(before) else e[during[0]]
    growth = float(np.max(e[during]) - e0)
    pre = np.flatnonzero((t >= w.start_ns - s.pre_ns) & (t < w.start_ns))
    level = float(np.max(e[pre])) if len(pre) else float(e0)
    after = np.flatnonzero(t >= w.end_ns)
    ok = after[e[after] <= level + s.tolerance]
    recovery = float((t[ok[0]] - w.end_ns) * 1e-9) if len(ok) else math.inf
    later = np.flatnonzero(t >= w.end_ns + s.after_ns)
    residual = float(e[later[0]] - level) if len(later) else math.nan
    return growth, recovery, residual
