"""A mapping file checked against an FMU's declared variables.

:func:`mapping_problems` lists what makes the mapping unusable with the FMU (a missing
variable, a wrong causality or type, a unit that contradicts the FMU's, an FMU unit the
mapping would silently read as SI): errors. :func:`mapping_warnings` lists what the bench
takes on trust: an FMU variable that declares no unit, where the mapping's unit (or SI,
when the mapping gives none either) is assumed.
"""

from __future__ import annotations

from bench.plant.fmi import FmuDescription
from bench.plant.mapping import PlantMapping
from bench.units import parse_unit

__all__ = ["mapping_problems", "mapping_warnings"]


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


def _where(mapping: PlantMapping, var: str) -> str:
    key = mapping.channel_keys().get(var)
    return f"{var!r} ({mapping.source}: {key})" if key else repr(var)


def mapping_problems(desc: FmuDescription, mapping: PlantMapping) -> list[str]:
    """What is wrong with ``mapping`` for this FMU (empty when it fits)."""
    problems: list[str] = []
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
        var = desc.variables.get(ch.var or "")
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
    for name, ch in mapping.start.items():
        var = desc.variables.get(ch.var or "")
        if var is None:
            problems.append(f"start {name} -> {ch.var!r} is not a variable of {desc.model_name}")
        elif var.causality not in ("parameter", "input") or var.type != "Float64":
            problems.append(f"start {name} -> {ch.var!r} is a {var.type} {var.causality}; expected a Float64/Real "
                            "parameter or input")
    for ch in (*mapping.output_channels(), *mapping.inputs.values(), *mapping.start.values()):
        var = desc.variables.get(ch.var or "")
        if var is None or not var.unit:
            continue
        if ch.unit is not None:
            if _same_unit(ch.unit, var.unit) is False:
                problems.append(f"{_where(mapping, var.name)}: the mapping reads it in {ch.unit!r} but the FMU "
                                f"declares {var.unit!r}")
            continue
        try:
            k, dim = parse_unit(var.unit)
        except Exception:
            continue  # a unit the bench does not know: nothing to compare
        if ch.expect and ch.expect != "lever" and (dim != parse_unit(ch.expect)[1] or abs(k - 1.0) > 1e-12):
            problems.append(f"{_where(mapping, var.name)}: the FMU declares {var.unit!r} but the mapping gives no "
                            f"unit (it would be read as {ch.expect}); give unit = {var.unit!r}")
    return problems


def mapping_warnings(desc: FmuDescription, mapping: PlantMapping) -> list[str]:
    """What the bench takes on trust (empty when every mapped variable declares its unit)."""
    warnings: list[str] = []
    seen: set[str] = set()
    for ch in (*mapping.output_channels(), *mapping.inputs.values(), *mapping.start.values()):
        var = desc.variables.get(ch.var or "")
        if var is None or var.unit or var.name in seen or ch.expect in ("", "1", "lever"):
            continue
        seen.add(var.name)
        if ch.unit is not None:
            warnings.append(f"{_where(mapping, var.name)}: the FMU declares no unit; trusting the mapping's "
                            f"{ch.unit!r}")
        else:
            warnings.append(f"{_where(mapping, var.name)}: neither the FMU nor the mapping gives a unit; read as "
                            f"{ch.expect}")
    return warnings
