"""The aiding-sensor suite of a run, built from a scenario's (or test case's) tables.

A scenario enables a sensor by its table; every key is optional::

    [doppler]
    model = "seed000"          # models/sensors/doppler/seed000.toml (else the defaults)
    rate = "50 Hz"             # any parameter overrides the set's value
    name = "doppler"           # instance name: topic /doppler, fault target "doppler"
    enabled = true

The same for ``[odometer]``, ``[bds]`` and ``[driver]``. Faults come from the scenario's
``[[fault]]`` tables and from fault files (``[[fault]]`` tables too, e.g.
``test_cases/faults/S002_odometer.toml``); :func:`fault_schedule` reads both, numbering the
windows in order. See ``docs/sensors.md``.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.config.files import read_toml
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.faults.schedule import FaultSchedule, FaultWindow, parse_schedule
from bench.faults.sensor import windows_for
from bench.sensors.base import SensorModel
from bench.sensors.bds import BDS_PARAMS, BdsReceiver
from bench.sensors.doppler import DOPPLER_PARAMS, DopplerRadar
from bench.sensors.driver import DRIVER_PARAMS, DriverInput
from bench.sensors.imu.faulty import FaultyImu
from bench.sensors.imu.model import LaserImu
from bench.sensors.odometer import ODOMETER_PARAMS, Odometer
from bench.sensors.params import Param, Resolved, resolve

__all__ = ["SENSOR_KINDS", "SensorSuite", "build_suite", "fault_schedule", "load_fault_kinds"]

#: Table name -> parameter declarations.
SENSOR_KINDS: dict[str, dict[str, Param]] = {
    "doppler": DOPPLER_PARAMS,
    "odometer": ODOMETER_PARAMS,
    "bds": BDS_PARAMS,
    "driver": DRIVER_PARAMS,
}


def load_fault_kinds() -> None:
    """Import the modules that register fault kinds (sensor, and wire when present)."""
    importlib.import_module("bench.faults.sensor")
    if importlib.util.find_spec("bench.faults.wire") is not None:
        importlib.import_module("bench.faults.wire")


def fault_schedule(
    doc: Mapping[str, Any], *, file: str | None = None, extra: Sequence[str | Path] = ()
) -> FaultSchedule:
    """The windows of the document's ``[[fault]]`` tables, then of each file in ``extra``."""
    load_fault_kinds()
    windows: list[FaultWindow] = list(parse_schedule(doc.get("fault"), file=file))
    for path in extra:
        p = Path(path)
        fdoc = read_toml(p, what="fault file")
        check_keys(fdoc, ("fault", "description", "reference"), file=str(p))
        if "fault" not in fdoc:
            raise ConfigError("expected [[fault]] tables", file=str(p), key="fault")
        windows += list(parse_schedule(fdoc["fault"], file=str(p), first_id=len(windows)))
    return FaultSchedule(windows)


@dataclass
class SensorSuite:
    """The aiding sensors of a run, their parameters and the fault schedule."""

    models: list[SensorModel]
    schedule: FaultSchedule
    params: dict[str, Resolved] = field(default_factory=dict)

    def sources(self) -> list[Path]:
        """Parameter-set files the sensors were built from (to attach to recordings)."""
        return sorted({r.model_path for r in self.params.values() if r.model_path is not None})

    def wrap_imu(self, imu: LaserImu) -> SensorModel:
        """``imu`` with the schedule's IMU windows applied (itself when there are none)."""
        windows = windows_for(self.schedule, imu.name)
        return FaultyImu(imu, windows) if windows else imu

    def record(self) -> dict[str, Any]:
        """Parameters of every sensor, JSON-friendly (for the recording's metadata)."""
        return {name: {"model": r.model_name, **r.record()} for name, r in self.params.items()}


def build_suite(
    doc: Mapping[str, Any],
    *,
    seed: int,
    file: str | None = None,
    schedule: FaultSchedule | None = None,
    imu_name: str = "imu",
) -> SensorSuite:
    """Build the sensors the document's tables enable, with their fault windows.

    Raises
    ------
    ConfigError
        For a bad parameter, or a sensor-layer fault aimed at a sensor the run lacks.
    """
    schedule = schedule if schedule is not None else FaultSchedule()
    models: list[SensorModel] = []
    params: dict[str, Resolved] = {}
    for kind, specs in SENSOR_KINDS.items():
        table = doc.get(kind)
        if table is None:
            continue
        if not isinstance(table, Mapping):
            raise ConfigError("expected a table", file=file, key=kind)
        enabled = table.get("enabled", True)
        if not isinstance(enabled, bool):
            raise ConfigError(f"expected true or false, found {enabled!r}", file=file, key=f"{kind}.enabled")
        if not enabled:
            continue
        name = table.get("name", kind)
        if not isinstance(name, str) or not name.isidentifier() or not name.startswith(kind):
            raise ConfigError(
                f"expected a name starting with {kind!r} (letters, digits, _), found {name!r}",
                file=file,
                key=f"{kind}.name",
            )
        res = resolve(kind, table, specs, file=file, where=kind, allow=("enabled", "name"))
        faults = windows_for(schedule, name)
        if kind == "doppler":
            models.append(DopplerRadar(res, seed, name, faults))
        elif kind == "odometer":
            models.append(Odometer(res, seed, name, faults))
        elif kind == "bds":
            try:
                models.append(BdsReceiver(res, seed, name, faults))
            except ConfigError as exc:
                raise ConfigError(exc.reason, file=file, key=exc.key) from None
        else:
            models.append(DriverInput(res, name))
        params[name] = res
    names = {*params, imu_name}
    for w in schedule:
        if w.layer == "sensor" and w.target not in names:
            raise ConfigError(
                f"fault {w.id} ({w.kind}) aims at {w.target!r}, but the run has no such sensor "
                f"(sensors: {', '.join(sorted(names))})",
                file=file,
                key=f"fault[{w.id}].target",
            )
    return SensorSuite(models, schedule, params)
