"""The metric catalogue and the :class:`Scorer` that computes metrics from one recording.

Every metric has a dotted name, a physical dimension (checked against the units of a
criterion's limits), a display unit and the options a criterion may pass to it:

* ``accuracy.<quantity>.<stat>`` -- :mod:`bench.scoring.accuracy`;
* ``faults.<aggregate>`` -- :mod:`bench.scoring.faults` (options ``target``, ``flag``,
  ``layer``);
* ``frameswitch.<aggregate>`` -- :mod:`bench.scoring.frameswitch` (option ``to``);
* ``consistency.<quantity>.<stat>`` -- :mod:`bench.scoring.consistency` (the bench's own
  option ``nees_grid_ns``, set for a criterion judged by ANEES over the runs: the details
  carry the NEES sampled on that grid);
* ``output.<name>`` -- :mod:`bench.scoring.output` (the integrity measures in
  :mod:`bench.scoring.epochs`);
* ``map.<name>`` -- :mod:`bench.scoring.mapscore` (the case's ``[scoring.map]`` road
  network);
* ``receiver.<quantity>.<stat>`` and ``versus_receiver.<quantity>.<stat>`` --
  :mod:`bench.scoring.receiver` (the BDS receiver alone on the same run, and the DUT's
  figure over it).

Values are SI floats (counts as floats, fractions as fractions); ``inf`` is a real
measurement (a fault never detected, an error that never settles).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.scoring.accuracy import QUANTITIES, QUANTITY_STATS, accuracy_value
from bench.scoring.align import NavErrors, cumulative_distance, nav_errors
from bench.scoring.consistency import CONSISTENCY_QUANTITIES, consistency_value
from bench.scoring.data import NoDataError, RunData
from bench.scoring.epochs import OutputIntegrity
from bench.scoring.faults import FLAGS, FaultAnalysis, FaultSettings, analyse_faults
from bench.scoring.frameswitch import FRAMES, SWITCH_QUANTITIES, SwitchAnalysis, SwitchSettings, analyse_switches
from bench.scoring.integrity import Integrity, check_integrity
from bench.scoring.mapscore import MAP_METRICS, MapSettings, load_network, map_window
from bench.scoring.output import OUTPUT_METRICS, output_value
from bench.scoring.receiver import (
    RATIO_STATS,
    RECEIVER_QUANTITIES,
    RECEIVER_STATS,
    receiver_value,
    versus_receiver_value,
)
from bench.scoring.windows import Window, WindowSpec, resolve_window

if TYPE_CHECKING:
    from bench.scoring.roadmap import RoadNetwork

__all__ = ["MetricSpec", "METRICS", "metric_spec", "ScoringSettings", "MetricValue", "Scorer", "OPTION_CHOICES"]


@dataclass(frozen=True)
class MetricSpec:
    """A metric: name, family, dimension (``bench.units`` name or ``count``), display
    unit, description, and the criterion options it takes."""

    name: str
    family: str
    dimension: str
    unit: str
    description: str
    options: tuple[str, ...] = ()


#: Allowed values of metric options (``target`` takes any sensor name).
OPTION_CHOICES: dict[str, tuple[str, ...]] = {
    "flag": FLAGS,
    "layer": ("sensor", "wire", "any"),
    "to": tuple(FRAMES.values()),
}

_FAULTS = {
    "windows": ("count", "1", "fault windows scored"),
    "detected": ("count", "1", "fault windows detected"),
    "missed": ("count", "1", "fault windows missed"),
    "detection_rate": ("dimensionless", "%", "fraction of fault windows detected"),
    "latency_max": ("time", "s", "largest detection latency (infinite if one was missed)"),
    "latency_mean": ("time", "s", "mean detection latency of the detected windows"),
    "exclusion_min": ("dimensionless", "%", "smallest fraction of a fault window with the sensor excluded"),
    "exclusion_mean": ("dimensionless", "%", "mean fraction of the fault windows with the sensor excluded"),
    "false_alarms": ("count", "1", "flag episodes starting outside the fault windows"),
    "false_alarm_rate": ("frequency", "1/h", "false alarms per fault-free time"),
    "growth_max": ("length", "m", "largest horizontal error growth during a fault window"),
    "recovery_max": ("time", "s", "longest time to return to the pre-fault error level"),
    "residual_max": ("length", "m", "largest error left after a fault window (at end + after)"),
    "class_correct": ("dimensionless", "%", "fraction of odometer fault windows whose reported fault class is right"),
    "class_wrong": ("count", "1", "odometer fault windows whose reported fault class is wrong (or missed)"),
}
_SWITCH_MEASURES = {
    "jump": "jump across the switch beyond the truth's change",
    "step": "largest epoch-to-epoch change of the error before the switch (the DUT's ordinary updates)",
    "jump_excess": "jump across the switch beyond the largest epoch-to-epoch change before it",
    "step_after": "largest epoch-to-epoch change of the error in the post window (the switch's included)",
    "step_ratio": "step_after over the largest epoch-to-epoch change before the switch",
    "amplitude": "peak excursion after the switch from the pre-switch mean",
    "excess": "peak excursion beyond the pre-switch band",
    "band": "the pre-switch band (the pre window's, or the ordinary excursions' when larger)",
    "ordinary": "largest excursion over a post-window stretch before the switch (with a reference period)",
    "settling": "time to settle back into the pre-switch band",
    "rms_ratio": "RMS after / RMS before the switch",
}
_SWITCH_UNITS = {"position": ("length", "m"), "velocity": ("velocity", "m/s"), "heading": ("angle", "arcmin")}
_CONSISTENCY = {
    "nees": "mean NEES / degrees of freedom (1 when consistent)",
    "within": "fraction of epochs inside the chi-square interval",
    "above": "fraction of epochs above the chi-square interval (over-confident)",
    "below": "fraction of epochs below the chi-square interval (pessimistic)",
}


def _catalogue() -> dict[str, MetricSpec]:
    out: dict[str, MetricSpec] = {}
    for q, (dim, unit, _, text) in QUANTITIES.items():
        for s in QUANTITY_STATS[q]:
            d, u = ("dimensionless", "%") if s.endswith("of_distance") else (dim, unit)
            name = f"accuracy.{q}.{s}"
            out[name] = MetricSpec(name, "accuracy", d, u, f"{s} of the {text}")
    for n, (dim, unit, text) in _FAULTS.items():
        out[f"faults.{n}"] = MetricSpec(f"faults.{n}", "faults", dim, unit, text, ("target", "flag", "layer"))
    out["frameswitch.count"] = MetricSpec("frameswitch.count", "frameswitch", "count", "1", "frame switches", ("to",))
    out["frameswitch.delay"] = MetricSpec(
        "frameswitch.delay", "frameswitch", "time", "s", "largest delay from a BENCH_CMD to the switch", ("to",)
    )
    for m, text in _SWITCH_MEASURES.items():
        for q in SWITCH_QUANTITIES:
            dim, unit = _SWITCH_UNITS[q]
            if m == "settling":
                dim, unit = "time", "s"
            elif m in ("rms_ratio", "step_ratio"):
                dim, unit = "dimensionless", "1"
            name = f"frameswitch.{m}_{q}"
            out[name] = MetricSpec(name, "frameswitch", dim, unit, f"{q}: {text} (max over switches)", ("to",))
    for q in CONSISTENCY_QUANTITIES:
        for s, text in _CONSISTENCY.items():
            name = f"consistency.{q}.{s}"
            unit = "1" if s == "nees" else "%"
            out[name] = MetricSpec(name, "consistency", "dimensionless", unit, f"{q} NEES: {text}")
    for n, (dim, unit, text) in OUTPUT_METRICS.items():
        out[f"output.{n}"] = MetricSpec(f"output.{n}", "output", dim, unit, text)
    for n, (dim, unit, text) in MAP_METRICS.items():
        out[f"map.{n}"] = MetricSpec(f"map.{n}", "map", dim, unit, text)
    for q, (dim, unit, text) in RECEIVER_QUANTITIES.items():
        for s in RECEIVER_STATS[q]:
            name = f"receiver.{q}.{s}"
            out[name] = MetricSpec(name, "receiver", dim, unit, f"{s} of the BDS receiver's own {text} (its fixes)")
        for s in RATIO_STATS[q]:
            name = f"versus_receiver.{q}.{s}"
            out[name] = MetricSpec(
                name, "versus_receiver", "dimensionless", "1", f"{s} of the {text} over the receiver's own, same window"
            )
    return out


METRICS: dict[str, MetricSpec] = _catalogue()


def metric_spec(name: str) -> MetricSpec:
    """The spec of a metric name (KeyError if unknown)."""
    return METRICS[name]


@dataclass(frozen=True)
class ScoringSettings:
    """Case-level scoring settings (see docs/test_cases.md, ``[scoring]``)."""

    convergence_ns: int = 0
    named_windows: Mapping[str, WindowSpec] = field(default_factory=dict)
    faults: FaultSettings = field(default_factory=FaultSettings)
    switches: SwitchSettings = field(default_factory=SwitchSettings)
    confidence: float = 0.95
    nominal_period_ns: int = 10_000_000
    budget_ns: int | None = None
    output_integrity: OutputIntegrity = field(default_factory=OutputIntegrity)
    map: MapSettings | None = None


@dataclass
class MetricValue:
    """A computed metric: SI value and details for the report."""

    value: float
    details: dict[str, Any] = field(default_factory=dict)


class Scorer:
    """Computes metrics of one recording, caching the shared work (alignment, analyses)."""

    def __init__(self, run: RunData, settings: ScoringSettings | None = None):
        self.run = run
        self.settings = settings or ScoringSettings()
        self._windows: dict[WindowSpec, Window] = {}
        self._faults: dict[tuple, FaultAnalysis] = {}
        self._switches: dict[tuple, SwitchAnalysis] = {}
        self._map: dict[WindowSpec, tuple[dict[str, float], dict[str, Any]]] = {}

    @cached_property
    def errors(self) -> NavErrors:
        """The DUT's errors at its epochs (NoDataError without truth or DUT output)."""
        return nav_errors(self.run.require_truth(), self.run.require_nav())

    @cached_property
    def _distance_table(self) -> tuple[np.ndarray, np.ndarray]:
        tr = self.run.require_truth()
        return tr["t_ns"], cumulative_distance(tr)

    def integrity(self) -> Integrity:
        return check_integrity(self.run, self.settings.budget_ns)

    def window(self, spec: WindowSpec) -> Window:
        if spec not in self._windows:
            self._windows[spec] = resolve_window(
                spec,
                self.run.span_ns,
                convergence_ns=self.settings.convergence_ns,
                segments=self.run.segments,
                faults=self.run.faults,
            )
        return self._windows[spec]

    def distance(self, window: Window) -> float:
        """Distance the truth drove inside ``window``, m."""
        t, d = self._distance_table
        total = 0.0
        for a, b in window.intervals:
            da, db = np.interp([a, b], t, d)
            total += float(db - da)
        return total

    def metric(self, name: str, spec: WindowSpec, options: Mapping[str, Any] | None = None) -> MetricValue:
        """Compute metric ``name`` over the window ``spec`` with criterion ``options``.

        Raises :class:`~bench.scoring.data.NoDataError` (ERROR) or
        :class:`~bench.scoring.data.DutDataError` (FAIL) when it cannot be measured.
        """
        options = dict(options or {})
        ms = METRICS[name]
        window = self.window(spec)
        parts = name.split(".")
        if ms.family == "accuracy":
            v, det = accuracy_value(parts[1], parts[2], self.errors, window, self.distance)
            return MetricValue(v, det)
        if ms.family == "consistency":
            v, det = consistency_value(
                parts[1], parts[2], self.errors, self.run.quality, window, self.settings.confidence,
                options.get("nees_grid_ns"),
            )
            return MetricValue(v, det)
        if ms.family == "output":
            v, det = output_value(
                parts[1],
                self.run.nav,
                self.run.quality,
                self.run.bad_frames,
                window,
                self.settings.nominal_period_ns,
                self.settings.output_integrity.bounds,
            )
            return MetricValue(v, det)
        if ms.family == "faults":
            fa = self.fault_analysis(spec, options)
            return MetricValue(fa.value(parts[1]), fa.details())
        if ms.family == "frameswitch":
            sa = self.switch_analysis(spec, options.get("to"))
            return MetricValue(sa.value(parts[1]), sa.details())
        if ms.family == "receiver":
            v, det = receiver_value(parts[1], parts[2], self.run, window)
            return MetricValue(v, det)
        if ms.family == "versus_receiver":
            v, det = versus_receiver_value(parts[1], parts[2], self.run, self.errors, window)
            return MetricValue(v, det)
        if ms.family == "map":
            values, det = self.map_analysis(spec)
            return MetricValue(values[name.removeprefix("map.")], dict(det))
        raise KeyError(name)

    @cached_property
    def network(self) -> RoadNetwork:
        """The case's road network (NoDataError when the case has none or it cannot be read)."""
        if self.settings.map is None:
            raise NoDataError("the case names no road network ([scoring.map] network)")
        return load_network(self.run, self.settings.map)

    def map_analysis(self, spec: WindowSpec) -> tuple[dict[str, float], dict[str, Any]]:
        """Every ``map.*`` value over window ``spec`` and their details."""
        if spec not in self._map:
            net = self.network
            assert self.settings.map is not None
            self._map[spec] = map_window(net, self.run, self.errors, self.window(spec), self.settings.map.tolerance)
        return self._map[spec]

    def fault_analysis(self, spec: WindowSpec, options: Mapping[str, Any]) -> FaultAnalysis:
        targets = options.get("target", ())
        targets = (targets,) if isinstance(targets, str) else tuple(targets)
        key = (spec, targets, options.get("flag"), options.get("layer", "sensor"))
        if key not in self._faults:
            try:
                errors: NavErrors | None = self.errors
            except NoDataError:
                errors = None
            self._faults[key] = analyse_faults(
                self.run.faults,
                self.run.quality,
                errors,
                self.window(spec),
                self.settings.faults,
                targets=targets,
                flag=options.get("flag"),
                layer=options.get("layer", "sensor"),
            )
        return self._faults[key]

    def switch_analysis(self, spec: WindowSpec, to: str | None = None) -> SwitchAnalysis:
        key = (spec, to)
        if key not in self._switches:
            frames = self.run.require_nav()["frame"][self.errors.index]
            self._switches[key] = analyse_switches(
                self.errors, frames, self.window(spec), self.settings.switches, commands=self.run.commands, to=to
            )
        return self._switches[key]

    def overview(self) -> dict[str, Any]:
        """A fixed set of figures for the report, whatever the criteria: accuracy (and the
        map metrics of a case with a road network, the receiver alone and the DUT over it
        for a run with a BDS receiver) over the whole run and after convergence, per
        segment, and output quality."""
        out: dict[str, Any] = {}
        rows = [("all", WindowSpec("all")), ("converged", WindowSpec("converged", converged=True))]
        road = ("map.on_road", "map.lateral.rms", "map.distractor_max") if self.settings.map is not None else ()
        rx = ("receiver.position.rms", "versus_receiver.position.rms") if self.run.receiver is not None else ()
        for label, spec in rows:
            block: dict[str, Any] = {}
            for m in (
                "accuracy.horizontal.rms",
                "accuracy.horizontal.max",
                "accuracy.horizontal.cep95",
                "accuracy.vertical.rms",
                "accuracy.velocity.rms",
                "accuracy.heading.rms",
                "accuracy.heading.max",
                "accuracy.level.max",
                *road,
                *rx,
            ):
                try:
                    block[m] = _finite(self.metric(m, spec).value)
                except Exception as exc:
                    block[m] = f"n/a: {exc}"
            out[label] = block
        segs = []
        for s in self.run.segments:
            spec = WindowSpec(f"segment {s.get('index')}", indices=(int(s.get("index", -1)),))
            row = {k: s.get(k) for k in ("index", "kind", "start_s", "end_s", "gnss", "label")}
            for m in ("accuracy.horizontal.rms", "accuracy.horizontal.max", "accuracy.heading.rms"):
                try:
                    row[m] = _finite(self.metric(m, spec).value)
                except Exception:
                    row[m] = None
            segs.append(row)
        out["segments"] = segs
        return out


def _finite(v: float) -> float | None:
    return v if math.isfinite(v) else None
