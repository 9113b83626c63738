"""Scenarios driven through an FMU: the ``[plant]`` table and ``[[command]]`` timeline.

::

    [plant]
    vehicle = "tracked_seed002"       # models/vehicles/<name>.toml (FMU, mapping, parameters)
    duration = "1685 s"
    step = "1 ms"                     # communication step (default 1 ms)
    sample = "10 ms"                  # spacing of the truth's spline samples (default 10 ms)
    command_rate = "100 Hz"           # driver commands are sampled and held at this rate
    # optional overrides: fmu, mapping, parameters = { name = value }
    # sha256 = "<64 hex>"             # the FMU's expected SHA-256 (default: fmu/build/SHA256SUMS)
    # trust = "unverified"            # explicit opt-in to an FMU with no trusted hash (recorded)

The start position, heading and speed come from ``[initial]``, the default surface and sky
view from ``[defaults]``. :func:`plant_trajectory` runs the plant and returns the truth.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bench.config.bounds import bounded_quantity, check
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.plant.driver import parse_commands
from bench.plant.mapping import load_mapping
from bench.plant.runner import PlantSetup, run_plant
from bench.plant.trajectory import FmuTrajectory
from bench.plant.vehicle import load_vehicle, parameter_value, resolve_fmu
from bench.units import quantity

__all__ = ["PLANT_KEYS", "plant_setup", "plant_trajectory"]

PLANT_KEYS = {"vehicle", "fmu", "mapping", "sha256", "manifest", "duration", "step", "sample", "command_rate",
              "parameters", "trust"}  # manifest: refused with the reason (see plant_setup)
_TRUST = ("verified", "unverified")


def _resolve(ref: str, base: Path) -> Path:
    p = Path(ref)
    return p if p.is_absolute() else (base / p).resolve()


def plant_setup(doc: Mapping[str, Any], *, file: str, base: Path) -> PlantSetup:
    """Parse ``[plant]``, ``[initial]``, ``[defaults]`` and ``[[command]]`` into a run set-up."""
    from bench.scenario.motion import parse_latlon

    plant = doc.get("plant")
    if not isinstance(plant, Mapping):
        raise ConfigError("expected a [plant] table", file=file, key="plant")
    check_keys(plant, PLANT_KEYS, file=file, key="plant")
    vehicle = load_vehicle(str(plant["vehicle"]), base) if "vehicle" in plant else None
    fmu_ref = plant.get("fmu") or (vehicle.fmu if vehicle else None)
    if fmu_ref is None:
        raise ConfigError("give 'vehicle' or 'fmu'", file=file, key="plant.fmu")
    fmu = resolve_fmu(str(fmu_ref), base if "fmu" in plant else (vehicle.path.parent if vehicle else base))
    if "mapping" in plant:
        mapping_path = _resolve(str(plant["mapping"]), base)
    elif vehicle is not None:
        mapping_path = vehicle.mapping
    else:
        raise ConfigError("give 'vehicle' or 'mapping'", file=file, key="plant.mapping")
    mapping = load_mapping(mapping_path)
    if "duration" not in plant:
        raise ConfigError("missing field", file=file, key="plant.duration")
    duration = bounded_quantity(plant["duration"], "time", "s", "duration", file=file, key="plant.duration")
    step = quantity(plant.get("step", "1 ms"), "time", "s", file=file, key="plant.step")
    sample = bounded_quantity(plant.get("sample", "10 ms"), "time", "s", "duration", file=file, key="plant.sample")
    rate = bounded_quantity(plant.get("command_rate", "100 Hz"), "frequency", "Hz", "rate", file=file,
                            key="plant.command_rate")
    if not 0.0 < step <= 0.1:
        raise ConfigError(f"expected a communication step within (0, 100 ms], found {plant.get('step')!r}", file=file,
                          key="plant.step")
    check("points", round(duration / step), file=file, key="plant.duration",
          shown=f"{round(duration / step)} steps ({duration:g} s / {step:g} s)")
    decimate = round(sample / step)
    if decimate < 1 or abs(decimate * step - sample) > 1e-9:
        raise ConfigError("the sample spacing must be a whole number of communication steps", file=file,
                          key="plant.sample")
    init = doc.get("initial", {})
    for k in ("latitude", "longitude"):
        if k not in init:
            raise ConfigError("missing field", file=file, key=f"initial.{k}")
    lat0 = parse_latlon(init["latitude"], "lat", file=file, key="initial.latitude")
    lon0 = parse_latlon(init["longitude"], "lon", file=file, key="initial.longitude")
    h0 = quantity(init.get("height", 0.0), "length", "m", file=file, key="initial.height")
    heading0 = quantity(init.get("heading", 0.0), "angle", "deg", file=file, key="initial.heading")
    speed0 = quantity(init.get("speed", 0.0), "velocity", "m/s", file=file, key="initial.speed")
    if speed0 != 0.0 and "speed" not in mapping.start:
        raise ConfigError(f"a start speed needs the FMU's start-speed parameter in the mapping's [start] speed "
                          f"({mapping.source})", file=file, key="initial.speed")
    defaults = doc.get("defaults", {})
    script = parse_commands(
        doc.get("command"), duration, file=file, surface=defaults.get("surface", "asphalt"),
        gnss=defaults.get("gnss", "open"), rate_hz=rate,
    )
    if "manifest" in plant:
        raise ConfigError("a manifest file is not trusted (whoever can change the FMU can rewrite it); give the "
                          "FMU's sha256 = \"<64 hex>\" in [plant] instead", file=file, key="plant.manifest")
    trust = plant.get("trust", "verified")
    if trust not in _TRUST:
        raise ConfigError(f"expected one of {', '.join(_TRUST)}, found {trust!r}", file=file, key="plant.trust")
    sha256 = plant.get("sha256")
    if sha256 is not None and not (isinstance(sha256, str) and len(sha256.strip()) == 64
                                   and all(c in "0123456789abcdefABCDEF" for c in sha256.strip())):
        raise ConfigError(f"expected the FMU's SHA-256 as 64 hex digits, found {sha256!r}", file=file,
                          key="plant.sha256")
    params = dict(vehicle.parameters) if vehicle else {}
    for k, v in plant.get("parameters", {}).items():
        params[k] = parameter_value(v, file=file, key=f"plant.parameters.{k}")
    return PlantSetup(
        fmu=fmu, mapping=mapping, script=script, lat0=lat0, lon0=lon0, h0=h0, heading0=heading0, step_s=step,
        decimate=decimate, parameters=params, surfaces=vehicle.surfaces if vehicle else {},
        heading_parameter=vehicle.heading_parameter if vehicle else None,
        sha256=sha256, unverified=trust == "unverified", source=file, speed0=speed0,
    )


def plant_trajectory(doc: Mapping[str, Any], *, file: str, base: Path) -> FmuTrajectory:
    """Run the scenario's plant and return its truth trajectory."""
    setup = plant_setup(doc, file=file, base=base)
    return FmuTrajectory(run_plant(setup), setup.script)
