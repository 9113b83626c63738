"""Vehicle parameter sets (``models/vehicles/*.toml``) and where FMUs are found.

A vehicle file names its FMU and mapping and gives the FMU's parameters and, per
surface, the tunable parameters of that ground::

    [vehicle]
    name = "..."
    fmu = "TrackedVehicle"              # fmu/build/TrackedVehicle.fmu, or a path
    mapping = "mappings/bench.toml"     # relative to this file
    heading_parameter = "heading0"      # FMU parameter taking the scenario's start heading
    [parameters]
    m = 15000.0                         # numbers: in the FMU's own unit
    B = "2.55 m"                        # strings with a unit: converted to SI
    [surface.cement]
    A1 = "0.4520 m"
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.config.files import read_toml
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.paths import fmu_dir, models_dir
from bench.units import parse_unit

__all__ = ["Vehicle", "load_vehicle", "resolve_fmu", "parameter_value"]


@dataclass
class Vehicle:
    """A parsed vehicle file."""

    name: str
    path: Path
    fmu: str
    mapping: Path
    parameters: dict[str, float] = field(default_factory=dict)
    surfaces: dict[str, dict[str, float]] = field(default_factory=dict)
    heading_parameter: str | None = None
    description: str = ""


def parameter_value(value: Any, *, file: str, key: str) -> float:
    """A finite number as is (the FMU's unit), or ``"<number> <unit>"`` converted to SI."""
    if isinstance(value, bool):
        raise ConfigError(f"expected a number, found {value!r}", file=file, key=key)
    if isinstance(value, (int, float)):
        x = float(value)
    elif isinstance(value, str):
        parts = value.strip().split(None, 1)
        try:
            number = float(parts[0])
            scale = parse_unit(parts[1])[0] if len(parts) > 1 else 1.0
        except Exception:
            raise ConfigError(f"expected a number with an optional unit, found {value!r}", file=file, key=key) from None
        x = number * scale
    else:
        raise ConfigError(f"expected a number, found {value!r}", file=file, key=key)
    if not math.isfinite(x):
        raise ConfigError(f"expected a finite number, found {value!r}", file=file, key=key)
    return x


def resolve_fmu(ref: str, base: Path | None = None) -> Path:
    """An FMU given by path (absolute, or relative to ``base``) or by name in ``fmu/build``."""
    p = Path(ref)
    candidates = [p] if p.is_absolute() else ([base / p] if base else []) + [p]
    if p.suffix != ".fmu":
        candidates.append(fmu_dir() / "build" / f"{ref}.fmu")
    for c in candidates:
        if c.is_file():
            return c.resolve()
    hint = " (build the bench's FMUs with 'make fmus')" if p.suffix != ".fmu" else ""
    raise ConfigError(f"FMU {ref!r} not found; looked at {', '.join(str(c) for c in candidates)}{hint}")


def load_vehicle(ref: str, base: Path | None = None) -> Vehicle:
    """Load a vehicle by path or by name in ``models/vehicles``."""
    p = Path(ref)
    if p.suffix != ".toml":
        p = models_dir() / "vehicles" / f"{ref}.toml"
    elif not p.is_absolute() and base is not None and (base / p).exists():
        p = base / p
    file = str(p)
    doc = read_toml(p, what="vehicle file")
    check_keys(doc, ("vehicle", "parameters", "surface"), file=file, noun="table")
    meta = doc.get("vehicle", {})
    for k in ("fmu", "mapping"):
        if k not in meta:
            raise ConfigError("missing field", file=file, key=f"vehicle.{k}")
    params = {k: parameter_value(v, file=file, key=f"parameters.{k}") for k, v in doc.get("parameters", {}).items()}
    surfaces = {
        s: {k: parameter_value(v, file=file, key=f"surface.{s}.{k}") for k, v in table.items()}
        for s, table in doc.get("surface", {}).items()
    }
    return Vehicle(
        name=str(meta.get("name", p.stem)),
        path=p,
        fmu=str(meta["fmu"]),
        mapping=(p.parent / meta["mapping"]).resolve(),
        parameters=params,
        surfaces=surfaces,
        heading_parameter=meta.get("heading_parameter"),
        description=str(meta.get("description", "")),
    )
