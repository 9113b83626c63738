"""A mapping file checked against an FMU's declared variables."""

from __future__ import annotations

from bench.plant.fmi import FmuDescription
from bench.plant.mapping import PlantMapping
from bench.units import parse_unit

__all__ = ["mapping_problems"]


def _same_unit(a: str, b: str) -> bool | None:
    """True/False when both parse; None when either is unknown to the bench."""
    if a == b:
        return True
    try:
        ka, da = parse_unit(a)
        kb, db = parse_unit(b)
    except Exception:
        return None
    return da == db and abs(ka - kb) <= 1e-12 * max(abs(ka), abs(kb))


def mapping_problems(desc: FmuDescription, mapping: PlantMapping) -> list[str]:
    """What is wrong with ``mapping`` for this FMU (empty when it fits)."""
    problems: list[str] = []
    units = mapping.described_units()
    for name in mapping.output_vars():
        var = desc.variables.get(name)
        if var is None:
            problems.append(f"output {name!r} is not a variable of {desc.model_name}")
            continue
        if var.type != "Float64":
            problems.append(f"output {name!r} is {var.type}; the bench reads Float64/Real outputs")
        if var.causality not in ("output", "local"):
            problems.append(f"{name!r} has causality {var.causality}; expected output")
    for channel, ch in mapping.inputs.items():
        var = desc.variables.get(ch.var)
        if var is None:
            problems.append(f"input {channel} -> {ch.var!r} is not a variable of {desc.model_name}")
            continue
        if var.causality != "input" and not (var.causality == "parameter" and var.variability == "tunable"):
            problems.append(f"input {channel} -> {ch.var!r} has causality {var.causality}; expected input")
        if var.type not in ("Float64", "Int32"):
            problems.append(f"input {channel} -> {ch.var!r} is {var.type}; expected Float64 or Int32")
        if ch.values is not None and var.type == "Int32" and var.min is not None and var.max is not None:
            bad = [v for v in ch.values if not int(var.min) <= v <= int(var.max)]
            if bad:
                problems.append(f"input {channel}: codes {bad} are outside [{var.min}, {var.max}] of {ch.var!r}")
    for name, unit in units.items():
        var = desc.variables.get(name)
        if var is None or unit is None or not var.unit:
            continue
        same = _same_unit(unit, var.unit)
        if same is False:
            problems.append(f"{name!r}: the mapping reads it in {unit!r} but the FMU declares {var.unit!r}")
    return problems
