"""The test-case schema: section by section checks of a parsed case file.

Each ``_section`` function reads one table with :class:`~bench.config.table.Table`
(types, units, choices, unknown keys) and returns the dataclass of
:mod:`bench.acceptance.case`. ``docs/test_cases.md`` documents every key.
"""

from __future__ import annotations

import ipaddress
import re
import string
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from bench.acceptance.case import (
    DUT_KINDS,
    Command,
    DutSpec,
    ScenarioRef,
    SensorSet,
    TestCase,
    merge_tables,
)
from bench.acceptance.criteria_schema import criteria as parse_criteria
from bench.acceptance.criteria_schema import scoring_settings
from bench.acceptance.integrity_criteria import REQUIREMENT as INTEGRITY_REQUIREMENT
from bench.acceptance.integrity_criteria import with_integrity
from bench.acceptance.run_schema import clock_spec, run_spec
from bench.config.files import expand_case_dir, read_toml, regular_file
from bench.config.table import Table, check_keys, type_name
from bench.errors import ConfigError
from bench.faults.schedule import FaultSchedule, parse_schedule

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
    "sweep",  # parameter sweeps of `bench campaign` (bench.campaign.sweep); one case runs as written
)
SENSORS = ("imu", "doppler", "odometer", "bds", "driver")
COMMANDS = {"grid": 1, "geographic": 2, "reset": 3}
COMMAND_PLACEHOLDERS = ("can_interface", "can_channel", "can_port", "imu_port", "gnss_port", "config", "python")
#: link name -> key -> (checker kind, description)
LINK_KEYS: dict[str, dict[str, str]] = {
    "can": {"interface": "str", "channel": "str", "bitrate": "int", "data_bitrate": "int", "fd": "bool",
            "port": "port", "interface_address": "str"},
    "imu": {"port": "str", "baud": "int"},
    "gnss": {"port": "str", "baud": "int", "talker": "str"},
}
_ID = r"[A-Za-z0-9][A-Za-z0-9_.-]*"

#: sensor name -> validator(table, file, key) of its inline parameters (registered by sensors)
_SENSOR_VALIDATORS: dict[str, Callable[[Mapping[str, Any], str, str], None]] = {}


def _waivers(c: Table, requirements: list[str]) -> dict[str, str]:
    """``[case] waived``: requirement id -> why the case names it but judges it nowhere
    (each a requirement of the case, each reason written out)."""
    w = c.table("waived")
    if w is None:
        return {}
    out: dict[str, str] = {}
    for req in list(w.data):
        if req not in requirements:
            raise w.error(req, f"waives {req!r}, which [case] requirements does not list "
                               f"({', '.join(requirements)})")
        if req == INTEGRITY_REQUIREMENT:
            raise w.error(req, "the output-integrity checks are switched off one by one, with a reason, in "
                               "[scoring.integrity]")
        reason = w.str(req, required=True)
        if not str(reason).strip():
            raise w.error(req, "expected the reason the requirement is not judged here, found an empty string")
        out[str(req)] = str(reason).strip()
    w.finish()
    return out


def register_sensor_validator(sensor: str, fn: Callable[[Mapping[str, Any], str, str], None]) -> None:
    """Let a sensor model check its inline parameters in test cases (raise ConfigError)."""
    _SENSOR_VALIDATORS[sensor] = fn


def build_case(
    doc: Mapping[str, Any], *, text: str, file: str, base: Path | None, check_files: bool, path: Path | None
) -> TestCase:
    """Check every section of a parsed case and assemble the :class:`TestCase`."""
    top = Table(doc, file)
    check_keys(doc, TOP_KEYS, file=file, noun="table")
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
    waived = _waivers(c, requirements)
    c.finish()

    scenario = _scenario(top.table("scenario", required=True), base, check_files)  # type: ignore[arg-type]
    sensors = _sensors(top.table("sensors"), check_files)
    if scenario.log is not None and sensors:
        raise ConfigError("a case built on field logs ([scenario] log) takes its sensors' data from the logs: "
                          "remove [sensors]", file=file, key="sensors")
    _load_fault_kinds()
    faults = parse_schedule(top.raw("fault"), file=file, key="fault")
    fault_files = top.str_list("fault_files", allow_single=False)
    if fault_files and check_files:
        faults = _fault_files(top, fault_files, faults, base)
    commands = tuple(_command(t) for t in top.tables("command"))
    dut = _dut(top.table("dut", required=True), base, check_files)  # type: ignore[arg-type]
    if scenario.log is not None and dut.kind not in ("in_process", "external", "hardware"):
        raise ConfigError(f"a case built on field logs ([scenario] log) replays them into an in_process, external or "
                          f"hardware DUT, not {dut.kind!r}", file=file, key="dut.kind")
    clock = clock_spec(top.table("clock"))
    run = run_spec(top.table("run"))
    scoring = scoring_settings(top.table("scoring"), dut, clock, base, check_files)
    criteria = parse_criteria(top.tables("criterion"), scoring, tuple(requirements), dut, run)
    if not criteria:
        raise ConfigError("expected at least one [[criterion]] table", file=file, key="criterion")
    criteria, case_requirements = with_integrity(criteria, scoring, tuple(requirements), file)
    top.raw("criterion")
    top.raw("sweep")  # checked and expanded by bench campaign (bench.campaign.sweep)
    top.finish()
    return TestCase(
        id=str(case_id),
        title=str(title),
        requirements=case_requirements,
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
        waived=waived,
    )


# -- scenario, sensors, commands ------------------------------------------------------------
def _scenario(t: Table, base: Path | None, check_files: bool) -> ScenarioRef:
    script = t.str("script")
    fmu = t.str("fmu")
    driver = t.str("driver")
    vehicle = t.str("vehicle")
    duration = t.quantity("duration", "time", "s", positive=True, bound="duration")
    log_table = t.table("log")
    t.finish()
    if sum(x is not None for x in (script, fmu, log_table)) != 1:
        raise t.error("script", "expected exactly one of 'script' (a motion script or track), 'fmu' with 'driver', "
                      "or 'log' (field logs of a real drive)")
    if log_table is not None:
        if duration is not None:
            raise t.error("duration", "a case built on field logs runs the whole log")
        return ScenarioRef(None, None, None, None, duration, base, log=_log_source(log_table, base, check_files))
    if fmu is not None and driver is None:
        raise t.error("driver", "missing field; an FMU scenario needs a driver script")
    if script is not None and (driver is not None or vehicle is not None):
        raise t.error("driver" if driver else "vehicle", "only an FMU scenario takes a driver script and vehicle")
    ref = ScenarioRef(script, fmu, driver, vehicle, duration, base)
    if check_files:
        if script is not None:
            from bench.scenario.loader import find_scenario, load_scenario

            p = ref.resolve(script)
            if p is None or not p.exists():
                try:
                    p = find_scenario(script)
                except ConfigError as exc:
                    raise t.error("script", f"no scenario file {script!r} next to the case, and {exc}") from None
            try:
                load_scenario(p)  # a regular file of bounded size, its values checked up front
            except ConfigError as exc:
                raise t.error("script", str(exc)) from None
        for name, value in (("driver", driver), ("vehicle", vehicle)):
            p = ref.resolve(value)
            if p is not None and not p.exists():
                raise t.error(name, f"file not found: {p}")
            if p is not None:
                regular_file(p, what=f"{name} file")
    return ref


#: ``[scenario] log`` keys naming files (resolved against the case file)
LOG_FILES = ("imu", "gnss", "can", "truth")


def _log_source(t: Table, base: Path | None, check_files: bool) -> dict[str, Any]:
    """``[scenario] log``: the field logs of a drive and how to read them, as ``bench
    replay`` takes them (docs/test_cases.md, "[scenario]"); checked here, read by the run."""
    out: dict[str, Any] = {}
    for name in LOG_FILES:
        value = t.str(name)
        if value is not None:
            out[name] = value
    out["imu_format"] = t.str("imu_format", choices=("icd", "psins", "kfgins", "gnss-ins-sim", "declared"))
    out["gnss_format"] = t.str("gnss_format", choices=("nmea", "kfgins"))
    out["truth_format"] = t.str("truth_format", "smartloc", choices=("smartloc", "csv", "kfgins"))
    out["truth_time"] = t.str("truth_time", "bench", choices=("bench", "utc"))
    out["epoch"] = t.str("epoch")
    out["gps_week"] = t.int("gps_week", minimum=0, maximum=9999)
    rate = t.quantity("imu_rate", "frequency", "Hz", positive=True, bound="imu_rate")
    out["imu_rate_hz"] = rate
    t.finish()
    if not any(name in out for name in ("imu", "gnss", "can")):
        raise t.error("imu", "expected at least one log: 'imu', 'gnss' or 'can'")
    if check_files:
        for name in LOG_FILES:
            if name in out:
                p = Path(out[name])
                p = p if p.is_absolute() or base is None else (base / p).resolve()
                if not p.exists():
                    raise t.error(name, f"file not found: {p}")
                regular_file(p, what=f"{name} log" if name != "truth" else "truth file")
    return out


def _check_imu(params: Mapping[str, Any], file: str, key: str) -> None:
    from bench.sensors.imu.grade import load_grade

    t = Table(params, file, key)
    grade = t.str("grade")
    t.quantity("rate", "frequency", "Hz", positive=True, bound="imu_rate")
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
    windows = list(inline)
    for i, name in enumerate(names):
        p = Path(name)
        if not p.is_absolute() and base is not None:
            p = base / p
        if not p.exists():
            raise top.error(f"fault_files[{i}]", f"file not found: {p}")
        try:
            doc = read_toml(p, what="fault file")
        except ConfigError as exc:
            raise top.error(f"fault_files[{i}]", str(exc)) from None
        check_keys(doc, ("fault", "description", "reference"), file=str(p))
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
            get = {"str": lt.str, "bool": lt.bool}.get(kind)
            if get:
                v = get(k)
            elif kind == "port":
                v = lt.int(k, minimum=1, maximum=65_535)
            else:
                v = lt.int(k, minimum=1, bound="baud")  # baud and bit rates
            if v is not None:
                vals[k] = v
        lt.finish()
        if name == "can":
            _udp_keys(lt, vals)
        out[name] = vals
    t.finish()
    return out


def _hardware_links(t: Table, links: Mapping[str, Mapping[str, Any]], config: Any) -> None:
    """A hardware DUT is on real links the bench does not make: its serial lines are device
    paths (or pyserial URLs), never the ``pty`` pairs the bench makes for a process it starts,
    its CAN interface is named, and it takes no ``[dut] config`` (nothing hands it over)."""
    if config:
        raise t.error("config", "a hardware DUT takes no [dut] config: the bench starts nothing to hand it to")
    for name in ("imu", "gnss"):
        port = links.get(name, {}).get("port")
        if port is None or port == "pty":
            raise t.error(f"links.{name}.port", "a hardware DUT needs the serial port its line is on (a device path "
                          f"such as /dev/ttyUSB0, or a pyserial URL), found {port!r}")
    if "interface" not in links.get("can", {}):
        raise t.error("links.can.interface", "a hardware DUT needs its CAN interface named (socketcan, "
                      "udp_multicast, pcan ...)")


def _external_links(t: Table, links: Mapping[str, Mapping[str, Any]]) -> None:
    """An external DUT is another process: python-can's ``virtual`` bus (the default when
    ``[dut.links] can`` names no interface) lives in the bench's process and reaches no other,
    so such a DUT never hears BENCH_TIME and the bench never hears it."""
    can = links.get("can", {})
    if can.get("interface", "virtual") != "virtual":
        return
    said = "is python-can's 'virtual' bus" if "interface" in can else \
        "names no interface, so it is python-can's 'virtual' bus"
    raise t.error("links.can.interface" if "interface" in can else "links.can",
                  f"the CAN link {said}, which lives in the bench's process and cannot reach another process: "
                  "an external DUT never hears it. Name the bus the DUT is on, e.g. "
                  "can = { interface = \"udp_multicast\", channel = \"239.74.163.2\" } (this machine's loopback, "
                  "no root) or can = { interface = \"socketcan\", "
                  "channel = \"vcan0\" } (docs/run_engine.md, \"Cross-process CAN\")")


def _udp_keys(t: Table, vals: Mapping[str, Any]) -> None:
    """``port`` and ``interface_address`` are udp_multicast's; its channel is an IPv4
    multicast group and its interface address an IPv4 address."""
    iface = vals.get("interface", "virtual")
    udp = iface == "udp_multicast"
    for k in ("port", "interface_address"):
        if k in vals and not udp:
            raise t.error(k, f"{k} is a udp_multicast setting, but the interface is {iface!r}")
    if not udp:
        return
    for k, want in (("channel", "an IPv4 multicast group (224.0.0.0/4, e.g. 239.74.163.2)"),
                    ("interface_address", "the IPv4 address of an interface (127.0.0.1 for the loopback)")):
        if k not in vals:
            continue
        try:
            addr = ipaddress.ip_address(vals[k])
        except ValueError:
            addr = None
        if not isinstance(addr, ipaddress.IPv4Address) or (k == "channel" and not addr.is_multicast):
            raise t.error(k, f"expected {want}, found {vals[k]!r}")


def _dut(t: Table, base: Path | None, check_files: bool) -> DutSpec:
    from bench.acceptance.batch_spec import parse_batch
    from bench.acceptance.synthetic_spec import parse_synthetic

    kind = t.str("kind", required=True, choices=DUT_KINDS)
    name = t.str("name")
    command, batch = parse_batch(t, str(kind))
    raw_config = t.raw("config", {})
    config: dict[str, Any] = {}
    config_file = None
    if isinstance(raw_config, str):
        config_file = raw_config
        if check_files and base is not None:
            found = [p for p in (base / raw_config, Path(raw_config)) if p.exists()]
            if not found:
                raise t.error("config", f"file not found: {raw_config}")
            regular_file(found[0], what="DUT configuration file")
    elif isinstance(raw_config, Mapping):
        config = expand_case_dir(raw_config, base)
    else:
        raise t.error("config", f"expected a table or a file name, found {raw_config!r} ({type_name(raw_config)})")
    rate = t.quantity("output_rate", "frequency", "Hz", 100.0, positive=True, bound="rate")
    startup = t.quantity("startup_timeout", "time", "s", 5.0, positive=True, bound="timeout")
    shutdown = t.quantity("shutdown_timeout", "time", "s", 5.0, positive=True, bound="timeout")
    links = _links(t.table("links"))
    description = t.str("description", "")
    version = t.str("version", "")
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
        _external_links(t, links)
    if kind != "external" and command:
        raise t.error("command", f"a command line is for an external DUT, not {kind!r}")
    if kind == "hardware":
        _hardware_links(t, links, config or config_file)
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
            vname_est = vt.str("name")
            vt.finish()
            entry: dict[str, Any] = {"config": expand_case_dir(vconfig, base), "description": vdesc}
            if vname_est is not None:
                if kind != "in_process":
                    raise vt.error("name", f"only an in_process DUT's variants name another estimator, not {kind!r}")
                entry["name"] = vname_est
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
        batch=batch,
        description=str(description),
        version=str(version),
    )
