"""The test-case schema, second part: scoring settings, windows and criteria.

See :mod:`bench.acceptance.schema` for the rest of a case and ``docs/test_cases.md`` for
every key.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

from bench.acceptance.case import ClockSpec, DutSpec, RunSpec
from bench.acceptance.criteria import AGGREGATES, COMPARATORS, Criterion, Limit, MonteCarlo
from bench.acceptance.integrity_criteria import parse_integrity
from bench.acceptance.requirements import SOURCES
from bench.config.table import Table, type_name
from bench.errors import ConfigError
from bench.scenario.motion import GNSS_FLAGS, SEGMENT_KINDS
from bench.scoring.faults import FLAGS, FaultSettings, target_bit
from bench.scoring.frameswitch import SwitchSettings
from bench.scoring.mapscore import MapSettings
from bench.scoring.metrics import METRICS, OPTION_CHOICES, ScoringSettings
from bench.scoring.windows import WindowSpec
from bench.units import quantity

__all__ = ["window_spec", "scoring_settings", "map_settings", "criteria"]

_ID = r"[A-Za-z0-9][A-Za-z0-9_.-]*"
_T = TypeVar("_T")


def _built(t: Table, make: Callable[..., _T], *args: Any, **kwargs: Any) -> _T:
    """``make(...)`` (a Limit, MonteCarlo or Criterion checking itself), its ConfigError
    given the file and the key within table ``t``."""
    try:
        return make(*args, **kwargs)
    except ConfigError as exc:
        key = exc.key
        if key and t.key.endswith(".monte_carlo"):
            key = key.removeprefix("monte_carlo").lstrip(".") or None
        raise t.error(key, exc.reason) from None


# -- scoring and windows -------------------------------------------------------------------
def _names(t: Table, name: str, choices: tuple[str, ...] | None = None) -> tuple[str, ...]:
    values = t.str_list(name)
    if choices is not None:
        for v in values:
            if v not in choices:
                raise t.error(name, f"expected one of {', '.join(choices)}, found {v!r}")
    return tuple(values)


def window_spec(value: Any, owner: Table, key: str, named: Mapping[str, WindowSpec]) -> WindowSpec:
    """A window as written in a criterion or in ``[scoring.windows]``."""
    if isinstance(value, str):
        if value == "all":
            return WindowSpec("all")
        if value == "converged":
            return WindowSpec("converged", converged=True)
        if value in named:
            return named[value]
        known = ", ".join(["all", "converged", *named])
        raise owner.error(key, f"unknown window {value!r}; expected one of: {known}, or a window table")
    if not isinstance(value, Mapping):
        raise owner.error(key, f"expected a window name or table, found {value!r} ({type_name(value)})")
    t = Table(value, owner.file, owner.path(key))
    name = t.str("name")
    converged = t.bool("converged", False)
    start = t.time_ns("start")
    end = t.time_ns("end")
    gnss = _names(t, "gnss", GNSS_FLAGS)
    kinds = _names(t, "kind", SEGMENT_KINDS)
    labels = _names(t, "label")
    targets = _names(t, "faults")
    seg_raw = t.raw("segments")
    t.finish()
    indices: tuple[int, ...] = ()
    if seg_raw is not None:
        if not isinstance(seg_raw, list) or not all(isinstance(i, int) and not isinstance(i, bool) for i in seg_raw):
            raise t.error("segments", f"expected an array of segment indices, found {seg_raw!r}")
        indices = tuple(seg_raw)
    if start is not None and end is not None and end <= start:
        raise t.error("end", f"expected end after start, found {start * 1e-9:g} s .. {end * 1e-9:g} s")
    spec = WindowSpec("", bool(converged), start, end, gnss, kinds, indices, labels, targets)
    return WindowSpec(name or spec.describe(), *list(spec.__dict__.values())[1:])


def map_settings(t: Table | None, base: Path | None, check_files: bool) -> MapSettings | None:
    """``[scoring.map]``: the road network (GeoJSON, relative to the case file) of the
    ``map.*`` metrics and their lateral tolerance; the file is loaded to check it."""
    if t is None:
        return None
    network = str(t.str("network", required=True, expect="a GeoJSON road network such as 'scenarios/roads.geojson'"))
    tolerance = float(t.quantity("tolerance", "length", "m", 5.0, positive=True))  # type: ignore[arg-type]
    t.finish()
    p = Path(network)
    path = p if p.is_absolute() else (base / p).resolve() if base is not None else None
    if check_files and path is not None:
        from bench.scoring.roadmap import RoadNetwork

        try:
            RoadNetwork.from_geojson(path)
        except ConfigError as exc:
            raise t.error("network", str(exc)) from None
    return MapSettings(network, path, tolerance)


def scoring_settings(
    t: Table | None, dut: DutSpec, clock: ClockSpec, base: Path | None = None, check_files: bool = False
) -> ScoringSettings:
    """``[scoring]``: convergence, named windows, fault, frame-switch, consistency,
    output-integrity and map settings."""
    period = round(1e9 / dut.output_rate_hz)
    budget = clock.budget_ns if clock.mode == "realtime" else None
    if t is None:
        return ScoringSettings(nominal_period_ns=period, budget_ns=budget)
    convergence = t.time_ns("convergence", 0)
    named: dict[str, WindowSpec] = {}
    wt = t.table("windows")
    if wt is not None:
        for wname in list(wt.data):
            if wname in ("all", "converged"):
                raise wt.error(wname, f"{wname!r} is a built-in window and cannot be redefined")
            spec = window_spec(wt.raw(wname), wt, wname, named)
            named[wname] = WindowSpec(wname, *list(spec.__dict__.values())[1:])
        wt.finish()
    faults = FaultSettings()
    ft = t.table("faults")
    if ft is not None:
        faults = FaultSettings(
            grace_ns=int(ft.time_ns("grace", 0)),  # type: ignore[arg-type]
            pre_ns=int(ft.time_ns("pre", "30 s", positive=True)),  # type: ignore[arg-type]
            after_ns=int(ft.time_ns("after", "30 s", positive=True)),  # type: ignore[arg-type]
            tolerance=float(ft.quantity("tolerance", "length", "m", 1.0, nonnegative=True)),  # type: ignore[arg-type]
            flag=str(ft.str("flag", "detected", choices=FLAGS)),
        )
        ft.finish()
    switches = SwitchSettings()
    st = t.table("frame_switch")
    if st is not None:
        switches = SwitchSettings(
            pre_ns=int(st.time_ns("pre", "30 s", positive=True)),  # type: ignore[arg-type]
            post_ns=int(st.time_ns("post", "60 s", positive=True)),  # type: ignore[arg-type]
            floor_position=float(st.quantity("floor_position", "length", "m", 0.1, nonnegative=True)),  # type: ignore[arg-type]
            floor_velocity=float(st.quantity("floor_velocity", "velocity", "m/s", 0.01, nonnegative=True)),  # type: ignore[arg-type]
            floor_heading=float(st.quantity("floor_heading", "angle", "arcmin", 0.1, nonnegative=True)),  # type: ignore[arg-type]
            reference_ns=int(st.time_ns("reference", "0 s")),  # type: ignore[arg-type]
        )
        if switches.reference_ns < 0:
            raise st.error("reference", "expected a duration of at least 0 s")
        st.finish()
    confidence = 0.95
    ct = t.table("consistency")
    if ct is not None:
        confidence = float(ct.quantity("confidence", "dimensionless", "1", 0.95))  # type: ignore[arg-type]
        ct.finish()
        if not 0.0 < confidence < 1.0:
            raise ct.error("confidence", f"expected a probability between 0 and 1 (or %), found {confidence:g}")
    integrity = parse_integrity(t.table("integrity"), int(convergence))  # type: ignore[arg-type]
    road = map_settings(t.table("map"), base, check_files)
    t.finish()
    return ScoringSettings(int(convergence), named, faults, switches, confidence, period, budget, integrity, road)  # type: ignore[arg-type]


# -- criteria ------------------------------------------------------------------------------
def _limit_value(t: Table, key: str, value: Any, dimension: str, unit: str) -> float:
    if dimension == "count":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise t.error(key, f"expected a number (a count), found {value!r} ({type_name(value)})")
        if not math.isfinite(value):
            raise t.error(key, f"expected a finite number (a count), found {value!r}")
        return float(value)
    return quantity(value, dimension, unit, file=t.file, key=t.path(key))


def _criterion(
    t: Table, index: int, scoring: ScoringSettings, requirements: tuple[str, ...], dut: DutSpec
) -> Criterion:
    cid = t.str("id", f"c{index + 1}", pattern=_ID, expect="an identifier")
    metric = t.str("metric", required=True, expect="a metric name such as 'accuracy.horizontal.rms'")
    if metric not in METRICS:
        close = difflib.get_close_matches(str(metric), METRICS, n=3, cutoff=0.6)
        hint = f"; did you mean {', '.join(close)}?" if close else "; see docs/scoring.md for the catalogue"
        raise t.error("metric", f"unknown metric {metric!r}{hint}")
    spec = METRICS[str(metric)]
    if spec.family == "map" and scoring.map is None:
        raise t.error("metric", f"metric {metric} needs a road network: add [scoring.map] with network = "
                      "'<file>.geojson' (relative to the case file)")
    reqs = t.str_list("requirement", required=True)
    if not reqs:
        raise t.error("requirement", "expected at least one requirement id")
    for r in reqs:
        if r not in requirements:
            raise t.error(
                "requirement", f"unknown requirement {r!r}; [case] requirements lists: {', '.join(requirements)}"
            )
    variant = t.str("variant")
    relative_to = t.str("relative_to")
    for k, v in (("variant", variant), ("relative_to", relative_to)):
        if v is not None and v not in dut.variants:
            raise t.error(k, f"unknown variant {v!r}; [dut.variants] defines: {', '.join(dut.variants) or 'none'}")
    if relative_to is not None and relative_to == variant:
        raise t.error("relative_to", "a variant cannot be compared with itself")
    if relative_to is not None and variant is None:
        raise t.error("variant", "missing field; a comparison (relative_to) names the variant it judges")
    controls = tuple(t.str_list("must_fail_on"))
    for v in controls:
        if v not in dut.variants:
            raise t.error("must_fail_on", f"unknown variant {v!r}; [dut.variants] defines: "
                          f"{', '.join(dut.variants) or 'none'}")
    if controls and relative_to is not None:  # before the limit, which a comparison reads as a ratio
        raise t.error("must_fail_on", "a comparison (relative_to) takes no negative control")
    dimension, unit_default = ("dimensionless", "1") if relative_to else (spec.dimension, spec.unit)
    unit = t.str("unit", unit_default)
    if dimension != "count" and unit != unit_default:
        quantity(f"1 {unit}", dimension, unit_default, file=t.file, key=t.path("unit"))
    window = window_spec(t.raw("window", "all"), t, "window", scoring.named_windows)
    given = [c for c in COMPARATORS if t.has(c)]
    for c in COMPARATORS:
        t.raw(c)
    if not given:  # a misspelt comparator is named, not reported as a missing limit
        for k in t.data:
            near = difflib.get_close_matches(str(k), COMPARATORS, n=1, cutoff=0.6)
            if near and k not in COMPARATORS:
                raise t.error(str(k), f"unknown key {k!r}; did you mean {near[0]!r}? (a criterion takes exactly "
                              f"one of {', '.join(COMPARATORS)})")
    if len(given) != 1:
        found = ", ".join(given) or "none"
        raise t.error(
            given[1] if len(given) > 1 else "at_most",
            f"expected exactly one of {', '.join(COMPARATORS)}; found {found}",
        )
    comp = given[0]
    raw = t.data[comp]
    lim_unit = unit if dimension != "count" else "1"
    if comp == "in_range":
        if not isinstance(raw, list) or len(raw) != 2:
            raise t.error(comp, f"expected [low, high], found {raw!r}")
        lo = _limit_value(t, f"{comp}[0]", raw[0], dimension, lim_unit)
        hi = _limit_value(t, f"{comp}[1]", raw[1], dimension, lim_unit)
        if not lo < hi:
            raise t.error(comp, f"expected low < high, found {raw!r}")
        limit = _built(t, Limit, comp, lo, hi)
    else:
        x = _limit_value(t, comp, raw, dimension, lim_unit)
        if comp == "within" and x < 0:
            raise t.error(comp, f"expected a non-negative tolerance, found {raw!r}")
        limit = _built(t, Limit, comp, x, None) if comp == "at_least" else _built(t, Limit, comp, None, x)
    marginal = marginal_rel = None
    if t.has("marginal") and t.has("marginal_relative"):
        raise t.error("marginal", "give either 'marginal' or 'marginal_relative', not both")
    if t.has("marginal"):
        marginal = _limit_value(t, "marginal", t.raw("marginal"), dimension, lim_unit)
        if marginal < 0:
            raise t.error("marginal", "expected a non-negative band")
    marginal_rel = t.quantity("marginal_relative", "dimensionless", "1", nonnegative=True)
    t.raw("marginal")
    options: dict[str, Any] = {}
    for opt in ("target", "flag", "layer", "to"):
        if not t.has(opt):
            t.raw(opt)
            continue
        if opt not in spec.options:
            raise t.error(
                opt,
                f"metric {metric} takes no option {opt!r}"
                + (f"; it takes: {', '.join(spec.options)}" if spec.options else ""),
            )
        if opt == "target":
            targets = t.str_list(opt)
            for tg in targets:
                if target_bit(tg) is None:
                    raise t.error(opt, f"expected a sensor (odometer, doppler, bds, imu), found {tg!r}")
            options[opt] = tuple(targets)
        else:
            options[opt] = t.str(opt, choices=OPTION_CHOICES[opt])
    mc = _monte_carlo(t.table("monte_carlo"), comp)
    tol = None
    if t.has("compare_tolerance"):  # bench compare: an absolute tolerance, in the metric's units
        tol = _limit_value(t, "compare_tolerance", t.raw("compare_tolerance"), dimension, lim_unit)
        if tol < 0:
            raise t.error("compare_tolerance", "expected a non-negative tolerance")
    tol_rel = t.quantity("compare_tolerance_relative", "dimensionless", "1", nonnegative=True)
    paper = t.str("paper", "")
    limit_source = t.str("limit_source", None, choices=SOURCES) or ""
    description = t.str("description", "")
    t.finish()
    return _built(
        t,
        Criterion,
        id=str(cid),
        requirements=tuple(reqs),
        metric=str(metric),
        window=window,
        limit=limit,
        unit=str(unit),
        dimension=dimension,
        marginal=marginal,
        marginal_relative=marginal_rel,
        paper=str(paper),
        limit_source=limit_source,
        description=str(description),
        variant=variant,
        relative_to=relative_to,
        must_fail_on=controls,
        options=options,
        monte_carlo=mc,
        compare_tolerance=tol,
        compare_tolerance_relative=tol_rel,
    )


def _monte_carlo(t: Table | None, comparator: str) -> MonteCarlo:
    if t is None:
        return MonteCarlo()
    pass_runs = t.int("pass_runs", minimum=1)
    pct = t.number("percentile")
    conf = t.quantity("confidence", "dimensionless", "1")
    agg = t.str("aggregate", choices=AGGREGATES)
    anees = t.quantity("anees", "dimensionless", "1")
    t.finish()
    modes = [m for m, v in (("pass_runs", pass_runs), ("percentile", pct), ("aggregate", agg), ("anees", anees))
             if v is not None]
    if len(modes) > 1:
        raise t.error(modes[1], f"expected one of pass_runs, percentile, aggregate, anees; found {', '.join(modes)}")
    if pct is not None:
        if not 0.0 < pct < 100.0:
            raise t.error("percentile", f"expected a percentile between 0 and 100, found {pct:g}")
        if conf is None:
            raise t.error("confidence", "missing field; a percentile criterion needs a confidence such as 0.9")
        if not 0.0 < conf < 1.0:
            raise t.error("confidence", f"expected a probability between 0 and 1 (or %), found {conf:g}")
        if comparator == "in_range":
            raise t.error("percentile", "a percentile bound applies to at_most, at_least or within, not in_range")
        return _built(t, MonteCarlo, "percentile", percentile=pct, confidence=conf)
    if conf is not None:
        raise t.error("confidence", "a confidence goes with a percentile")
    if pass_runs is not None:
        return _built(t, MonteCarlo, "pass_runs", pass_runs=pass_runs)
    if agg is not None:
        return _built(t, MonteCarlo, "aggregate", aggregate=agg)
    if anees is not None:
        if not 0.0 < anees < 1.0:
            raise t.error("anees", f"expected the band's confidence, a probability between 0 and 1 (or %), found "
                          f"{anees:g}")
        return _built(t, MonteCarlo, "anees", anees=anees)
    return MonteCarlo()


def criteria(
    tables: list[Table], scoring: ScoringSettings, requirements: tuple[str, ...], dut: DutSpec, run: RunSpec
) -> tuple[Criterion, ...]:
    """``[[criterion]]`` tables, checked against the case's requirements, variants and runs."""
    out: list[Criterion] = []
    seen: dict[str, int] = {}
    for i, t in enumerate(tables):
        c = _criterion(t, i, scoring, requirements, dut)
        if c.id in seen:
            raise t.error("id", f"duplicate criterion id {c.id!r} (also criterion[{seen[c.id]}])")
        if c.monte_carlo.pass_runs is not None and c.monte_carlo.pass_runs > len(run.seeds):
            raise t.error(
                "monte_carlo.pass_runs",
                f"{c.monte_carlo.pass_runs} passing runs are asked of {len(run.seeds)} runs ([run] seeds)",
            )
        seen[c.id] = i
        out.append(c)
    return tuple(out)
