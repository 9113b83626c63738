"""The test-case schema: section by section checks of a parsed case file.

Each ``_section`` function reads one table with :class:`~bench.acceptance.tomlcheck.Table`
(types, units, choices, unknown keys) and returns the dataclass of
:mod:`bench.acceptance.case`. ``docs/test_cases.md`` documents every key.
"""

from __future__ import annotations

import difflib
import re
import string
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from bench.acceptance.case import (
    CLOCK_MODES,
    DUT_KINDS,
    ClockSpec,
    Command,
    DutSpec,
    RunSpec,
    ScenarioRef,
    SensorSet,
    TestCase,
    merge_tables,
)
from bench.acceptance.criteria import AGGREGATES, COMPARATORS, Criterion, Limit, MonteCarlo
from bench.acceptance.tomlcheck import Table, type_name
from bench.errors import ConfigError
from bench.faults.schedule import FaultSchedule, parse_schedule
from bench.scenario.motion import GNSS_FLAGS, SEGMENT_KINDS
from bench.scoring.faults import FLAGS, FaultSettings, target_bit
from bench.scoring.frameswitch import SwitchSettings
from bench.scoring.metrics import METRICS, OPTION_CHOICES, ScoringSettings
from bench.scoring.windows import WindowSpec
from bench.units import quantity

__all__ = ["build_case", "SENSORS", "register_sensor_validator", "LINK_KEYS", "COMMAND_PLACEHOLDERS"]

TOP_KEYS = (
    "case",
    "scenario",
    "sensors",
    "fault",
    "fault_files",
    "command",
    "dut",
    "clock",
    "run",
    "scoring",
    "criterion",
)
SENSORS = ("imu", "doppler", "odometer", "bds", "driver")
COMMANDS = {"grid": 1, "geographic": 2, "reset": 3}
COMMAND_PLACEHOLDERS = ("can_interface", "can_channel", "imu_port", "gnss_port", "config")
#: link name -> key -> (checker kind, description)
LINK_KEYS: dict[str, dict[str, str]] = {
    "can": {"interface": "str", "channel": "str", "bitrate": "int", "data_bitrate": "int", "fd": "bool"},
    "imu": {"port": "str", "baud": "int"},
    "gnss": {"port": "str", "baud": "int", "talker": "str"},
}
_ID = r"[A-Za-z0-9][A-Za-z0-9_.-]*"

#: sensor name -> validator(table, file, key) of its inline parameters (registered by sensors)
_SENSOR_VALIDATORS: dict[str, Callable[[Mapping[str, Any], str, str], None]] = {}


def register_sensor_validator(sensor: str, fn: Callable[[Mapping[str, Any], str, str], None]) -> None:
    """Let a sensor model check its inline parameters in test cases (raise ConfigError)."""
    _SENSOR_VALIDATORS[sensor] = fn


def build_case(
    doc: Mapping[str, Any], *, text: str, file: str, base: Path | None, check_files: bool, path: Path | None
) -> TestCase:
    """Check every section of a parsed case and assemble the :class:`TestCase`."""
    top = Table(doc, file)
    for k in doc:
        if k not in TOP_KEYS:
            raise ConfigError(f"unknown table {k!r}; expected one of: {', '.join(TOP_KEYS)}", file=file, key=k)
    c = top.table("case", required=True)
    assert c is not None
    case_id = c.str("id", required=True, pattern=_ID, expect="an identifier such as 'S000-AP'")
    title = c.str("title", required=True)
    requirements = c.str_list("requirements", required=True)
    if not requirements:
        raise c.error("requirements", "expected at least one requirement id")
    description = c.str("description", "")
    reference = c.str("reference", "")
    assumed = c.str_list("assumed")
    shortened = c.str("shortened", "")
    c.finish()

    scenario = _scenario(top.table("scenario", required=True), base, check_files)  # type: ignore[arg-type]
    sensors = _sensors(top.table("sensors"), check_files)
    _load_fault_kinds()
    faults = parse_schedule(top.raw("fault"), file=file, key="fault")
    fault_files = top.str_list("fault_files", allow_single=False)
    if fault_files and check_files:
        faults = _fault_files(top, fault_files, faults, base)
    commands = tuple(_command(t) for t in top.tables("command"))
    dut = _dut(top.table("dut", required=True), base, check_files)  # type: ignore[arg-type]
    clock = _clock(top.table("clock"))
    run = _run(top.table("run"))
    scoring = _scoring(top.table("scoring"), dut, clock)
    criteria = _criteria(top.tables("criterion"), scoring, tuple(requirements), dut, run)
    if not criteria:
        raise ConfigError("expected at least one [[criterion]] table", file=file, key="criterion")
    top.raw("criterion")
    top.finish()
    return TestCase(
        id=str(case_id),
        title=str(title),
        requirements=tuple(requirements),
        file=file,
        text=text,
        path=path,
        scenario=scenario,
        sensors=sensors,
        faults=faults,
        fault_files=tuple(fault_files),
        commands=commands,
        dut=dut,
        clock=clock,
        run=run,
        scoring=scoring,
        criteria=criteria,
        description=str(description),
        reference=str(reference),
        assumed=tuple(assumed),
        shortened=str(shortened),
    )


# -- scenario, sensors, commands ------------------------------------------------------------
def _scenario(t: Table, base: Path | None, check_files: bool) -> ScenarioRef:
    script = t.str("script")
    fmu = t.str("fmu")
    driver = t.str("driver")
    vehicle = t.str("vehicle")
    duration = t.quantity("duration", "time", "s", positive=True)
    t.finish()
    if (script is None) == (fmu is None):
        raise t.error("script", "expected either 'script' (a motion script or track) or 'fmu' with 'driver'")
    if fmu is not None and driver is None:
        raise t.error("driver", "missing field; an FMU scenario needs a driver script")
    if script is not None and (driver is not None or vehicle is not None):
        raise t.error("driver" if driver else "vehicle", "only an FMU scenario takes a driver script and vehicle")
    ref = ScenarioRef(script, fmu, driver, vehicle, duration, base)
    if check_files:
        if script is not None:
            p = ref.resolve(script)
            if p is None or not p.exists():
                from bench.scenario.loader import find_scenario

                try:
                    find_scenario(script)
                except ConfigError as exc:
                    raise t.error("script", f"no scenario file {script!r} next to the case, and {exc}") from None
        for name, value in (("driver", driver), ("vehicle", vehicle)):
            p = ref.resolve(value)
            if p is not None and not p.exists():
                raise t.error(name, f"file not found: {p}")
    return ref


def _check_imu(params: Mapping[str, Any], file: str, key: str) -> None:
    from bench.sensors.imu.grade import load_grade

    t = Table(params, file, key)
    grade = t.str("grade")
    t.quantity("rate", "frequency", "Hz", positive=True)
    t.finish()
    if grade is not None:
        try:
            load_grade(grade)
        except ConfigError as exc:
            raise ConfigError(f"unknown IMU grade {grade!r}: {exc.reason}", file=file, key=f"{key}.grade") from None


def _check_sensor(kind: str, params: Mapping[str, Any], file: str, key: str) -> None:
    from bench.sensors.params import resolve
    from bench.sensors.suite import SENSOR_KINDS

    resolve(kind, params, SENSOR_KINDS[kind], file=file, where=key, allow=("enabled", "name"))


def _sensors(t: Table | None, check_files: bool) -> dict[str, SensorSet]:
    """``[sensors]``: per sensor a parameter-set name or a table as a scenario's sensor
    tables take it (``imu``: ``grade``, ``rate``; others: ``model``, parameters,
    ``name``, ``enabled``; see docs/sensors.md)."""
    out: dict[str, SensorSet] = {}
    if t is None:
        return out
    for name in list(t.data):
        if name not in SENSORS:
            raise t.error(name, f"unknown sensor {name!r}; expected one of: {', '.join(SENSORS)}")
        v = t.raw(name)
        named = "grade" if name == "imu" else "model"
        if isinstance(v, str):
            params: dict[str, Any] = {named: v}
        elif isinstance(v, Mapping):
            params = dict(v)
        else:
            raise t.error(name, f"expected a parameter set name or a table, found {v!r} ({type_name(v)})")
        key = t.path(name)
        if check_files:
            if name == "imu":
                _check_imu(params, t.file or "", key)
            elif name in _SENSOR_VALIDATORS:
                _SENSOR_VALIDATORS[name](params, t.file or "", key)
            else:
                _check_sensor(name, params, t.file or "", key)
        preset = params.get(named)
        out[name] = SensorSet(name, preset if isinstance(preset, str) else None, params)
    t.finish()
    return out


def _load_fault_kinds() -> None:
    """Import the modules that register fault kinds (sensor level; wire level when present)."""
    import importlib
    import importlib.util

    for mod in ("bench.faults.sensor", "bench.faults.wire"):
        if importlib.util.find_spec(mod) is not None:
            importlib.import_module(mod)


def _fault_files(top: Table, names: list[str], inline: FaultSchedule, base: Path | None) -> FaultSchedule:
    """Inline windows, then those of each fault file (``[[fault]]`` tables, numbered on)."""
    from bench.scenario.loader import read_toml

    windows = list(inline)
    for i, name in enumerate(names):
        p = Path(name)
        if not p.is_absolute() and base is not None:
            p = base / p
        if not p.exists():
            raise top.error(f"fault_files[{i}]", f"file not found: {p}")
        doc = read_toml(p)
        for k in doc:
            if k not in ("fault", "description", "reference"):
                raise ConfigError(f"unknown key {k!r}; expected [[fault]] tables", file=str(p), key=k)
        windows += list(parse_schedule(doc.get("fault"), file=str(p), first_id=len(windows)))
    return FaultSchedule(windows)


def _command(t: Table) -> Command:
    at = t.time_ns("at", required=True)
    cmd = t.str("command", required=True, choices=COMMANDS)
    t.finish()
    return Command(int(at), str(cmd))  # type: ignore[arg-type]


# -- DUT, clock, run -----------------------------------------------------------------------
def _links(t: Table | None) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    if t is None:
        return out
    for name in list(t.data):
        if name not in LINK_KEYS:
            raise t.error(name, f"unknown link {name!r}; expected one of: {', '.join(LINK_KEYS)}")
        lt = t.table(name)
        assert lt is not None
        vals: dict[str, Any] = {}
        for k, kind in LINK_KEYS[name].items():
            v = {"str": lt.str, "int": lt.int, "bool": lt.bool}[kind](k)
            if v is not None:
                vals[k] = v
        lt.finish()
        out[name] = vals
    t.finish()
    return out


def _dut(t: Table, base: Path | None, check_files: bool) -> DutSpec:
    from bench.acceptance.synthetic_spec import parse_synthetic

    kind = t.str("kind", required=True, choices=DUT_KINDS)
    name = t.str("name")
    command = t.str("command")
    raw_config = t.raw("config", {})
    config: dict[str, Any] = {}
    config_file = None
    if isinstance(raw_config, str):
        config_file = raw_config
        if check_files and base is not None and not (base / raw_config).exists() and not Path(raw_config).exists():
            raise t.error("config", f"file not found: {raw_config}")
    elif isinstance(raw_config, Mapping):
        config = dict(raw_config)
    else:
        raise t.error("config", f"expected a table or a file name, found {raw_config!r} ({type_name(raw_config)})")
    rate = t.quantity("output_rate", "frequency", "Hz", 100.0, positive=True)
    startup = t.quantity("startup_timeout", "time", "s", 5.0, positive=True)
    shutdown = t.quantity("shutdown_timeout", "time", "s", 5.0, positive=True)
    links = _links(t.table("links"))
    description = t.str("description", "")
    synthetic_raw = t.raw("synthetic", None)
    variants_t = t.table("variants")
    t.finish()
    if kind == "in_process" and not name:
        raise t.error("name", "missing field; an in_process DUT needs the registered estimator name")
    if kind == "external":
        if not command:
            raise t.error("command", "missing field; an external DUT needs its command line")
        for _, field_name, _, _ in string.Formatter().parse(command):
            if field_name is not None and field_name not in COMMAND_PLACEHOLDERS:
                raise t.error(
                    "command",
                    f"unknown placeholder {{{field_name}}}; expected: "
                    + ", ".join("{" + p + "}" for p in COMMAND_PLACEHOLDERS),
                )
    if kind != "external" and command:
        raise t.error("command", f"a command line is for an external DUT, not {kind!r}")
    if synthetic_raw is not None and kind != "synthetic":
        raise t.error("synthetic", f"[dut.synthetic] describes the synthetic stand-in, but kind is {kind!r}")
    synthetic = None
    if kind == "synthetic":
        synthetic = parse_synthetic(Table(synthetic_raw or {}, t.file, t.path("synthetic")))
    variants: dict[str, dict[str, Any]] = {}
    if variants_t is not None:
        for vname in list(variants_t.data):
            if not isinstance(vname, str) or not re.fullmatch(_ID, vname):
                raise variants_t.error(vname, f"expected a variant name such as 'with_detection', found {vname!r}")
            vt = variants_t.table(vname)
            assert vt is not None
            vconfig = vt.raw("config", {})
            if not isinstance(vconfig, Mapping):
                raise vt.error("config", f"expected a table, found {type_name(vconfig)}")
            vsyn = vt.raw("synthetic", None)
            vdesc = vt.str("description", "")
            vt.finish()
            entry: dict[str, Any] = {"config": dict(vconfig), "description": vdesc}
            if vsyn is not None:
                if kind != "synthetic":
                    raise vt.error("synthetic", f"only a synthetic DUT takes [synthetic] overrides, not {kind!r}")
                if not isinstance(vsyn, Mapping):
                    raise vt.error("synthetic", f"expected a table, found {type_name(vsyn)}")
                merged = merge_tables(synthetic_raw or {}, vsyn)
                entry["_synthetic"] = parse_synthetic(Table(merged, t.file, vt.path("synthetic")))
            variants[vname] = entry
        variants_t.finish()
    return DutSpec(
        kind=str(kind),
        name=name,
        command=command,
        config=config,
        config_file=config_file,
        output_rate_hz=float(rate),  # type: ignore[arg-type]
        startup_timeout_s=float(startup),  # type: ignore[arg-type]
        shutdown_timeout_s=float(shutdown),  # type: ignore[arg-type]
        links=links,
        variants=variants,
        synthetic=synthetic,
        description=str(description),
    )


def _clock(t: Table | None) -> ClockSpec:
    if t is None:
        return ClockSpec()
    mode = t.str("mode", "lockstep", choices=CLOCK_MODES)
    step = t.time_ns("step", "10 ms", positive=True)
    timeout = t.time_ns("timeout", "5 s", positive=True)
    budget = t.time_ns("budget", positive=True)
    t.finish()
    return ClockSpec(str(mode), int(step), int(timeout), budget)  # type: ignore[arg-type]


def _run(t: Table | None) -> RunSpec:
    if t is None:
        return RunSpec()
    seeds_raw = t.raw("seeds")
    mc = t.int("monte_carlo", minimum=1)
    first = t.int("first_seed", 1, minimum=0)
    truth_rate = t.quantity("truth_rate", "frequency", "Hz", 100.0, positive=True)
    t.finish()
    if seeds_raw is not None and mc is not None:
        raise t.error("monte_carlo", "give either 'seeds' or 'monte_carlo', not both")
    if seeds_raw is not None:
        if (
            not isinstance(seeds_raw, list)
            or not seeds_raw
            or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds_raw)
        ):
            raise t.error("seeds", f"expected a non-empty array of non-negative integers, found {seeds_raw!r}")
        if len(set(seeds_raw)) != len(seeds_raw):
            raise t.error("seeds", f"expected distinct seeds, found {seeds_raw!r}")
        seeds = tuple(seeds_raw)
    elif mc is not None:
        seeds = tuple(range(int(first), int(first) + mc))  # type: ignore[arg-type]
    else:
        seeds = (int(first),)  # type: ignore[arg-type]
    if not 1.0 <= truth_rate <= 1000.0:  # type: ignore[operator]
        raise t.error("truth_rate", f"expected 1 .. 1000 Hz, found {truth_rate:g} Hz")
    return RunSpec(seeds, float(truth_rate))  # type: ignore[arg-type]


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


def _scoring(t: Table | None, dut: DutSpec, clock: ClockSpec) -> ScoringSettings:
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
        )
        st.finish()
    confidence = 0.95
    ct = t.table("consistency")
    if ct is not None:
        confidence = float(ct.quantity("confidence", "dimensionless", "1", 0.95))  # type: ignore[arg-type]
        ct.finish()
        if not 0.0 < confidence < 1.0:
            raise ct.error("confidence", f"expected a probability between 0 and 1 (or %), found {confidence:g}")
    t.finish()
    return ScoringSettings(int(convergence), named, faults, switches, confidence, period, budget)  # type: ignore[arg-type]


# -- criteria ------------------------------------------------------------------------------
def _limit_value(t: Table, key: str, value: Any, dimension: str, unit: str) -> float:
    if dimension == "count":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise t.error(key, f"expected a number (a count), found {value!r} ({type_name(value)})")
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
    dimension, unit_default = ("dimensionless", "1") if relative_to else (spec.dimension, spec.unit)
    unit = t.str("unit", unit_default)
    if dimension != "count" and unit != unit_default:
        quantity(f"1 {unit}", dimension, unit_default, file=t.file, key=t.path("unit"))
    window = window_spec(t.raw("window", "all"), t, "window", scoring.named_windows)
    given = [c for c in COMPARATORS if t.has(c)]
    for c in COMPARATORS:
        t.raw(c)
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
        limit = Limit(comp, lo, hi)
    else:
        x = _limit_value(t, comp, raw, dimension, lim_unit)
        if comp == "within" and x < 0:
            raise t.error(comp, f"expected a non-negative tolerance, found {raw!r}")
        limit = Limit(comp, x, None) if comp == "at_least" else Limit(comp, None, x)
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
    paper = t.str("paper", "")
    description = t.str("description", "")
    t.finish()
    return Criterion(
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
        description=str(description),
        variant=variant,
        relative_to=relative_to,
        options=options,
        monte_carlo=mc,
    )


def _monte_carlo(t: Table | None, comparator: str) -> MonteCarlo:
    if t is None:
        return MonteCarlo()
    pass_runs = t.int("pass_runs", minimum=1)
    pct = t.number("percentile")
    conf = t.quantity("confidence", "dimensionless", "1")
    agg = t.str("aggregate", choices=AGGREGATES)
    t.finish()
    modes = [m for m, v in (("pass_runs", pass_runs), ("percentile", pct), ("aggregate", agg)) if v is not None]
    if len(modes) > 1:
        raise t.error(modes[1], f"expected one of pass_runs, percentile, aggregate; found {', '.join(modes)}")
    if pct is not None:
        if not 0.0 < pct < 100.0:
            raise t.error("percentile", f"expected a percentile between 0 and 100, found {pct:g}")
        if conf is None:
            raise t.error("confidence", "missing field; a percentile criterion needs a confidence such as 0.9")
        if not 0.0 < conf < 1.0:
            raise t.error("confidence", f"expected a probability between 0 and 1 (or %), found {conf:g}")
        if comparator == "in_range":
            raise t.error("percentile", "a percentile bound applies to at_most, at_least or within, not in_range")
        return MonteCarlo("percentile", percentile=pct, confidence=conf)
    if conf is not None:
        raise t.error("confidence", "a confidence goes with a percentile")
    if pass_runs is not None:
        return MonteCarlo("pass_runs", pass_runs=pass_runs)
    if agg is not None:
        return MonteCarlo("aggregate", aggregate=agg)
    return MonteCarlo()


def _criteria(
    tables: list[Table], scoring: ScoringSettings, requirements: tuple[str, ...], dut: DutSpec, run: RunSpec
) -> tuple[Criterion, ...]:
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
