"""The XML of the bench's FMUs: ``modelDescription.xml`` (FMI 3.0 and 2.0) and the FMI 3.0
``buildDescription.xml``, from a model spec read by ``build.py`` (``model.toml``).
"""

from __future__ import annotations

from xml.sax.saxutils import escape

__all__ = ["UNITS", "gen_md3", "gen_md2", "gen_build_description"]

#: Units the model files may use: base-unit exponents (FMI BaseUnit attributes) and factor.
UNITS: dict[str, dict[str, float]] = {
    "kg": {"kg": 1},
    "m": {"m": 1},
    "s": {"s": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "km/h": {"m": 1, "s": -1, "factor": 1 / 3.6},
    "rad": {"rad": 1},
    "deg": {"rad": 1, "factor": 0.017453292519943295},
    "rad/s": {"rad": 1, "s": -1},
    "deg/s": {"rad": 1, "s": -1, "factor": 0.017453292519943295},
    "N": {"kg": 1, "m": 1, "s": -2},
    "W": {"kg": 1, "m": 2, "s": -3},
    "N.s/m": {"kg": 1, "s": -1},
    "N/m": {"kg": 1, "s": -2},
    "N/rad": {"kg": 1, "m": 1, "s": -2, "rad": -1},
    "Hz": {"s": -1},
    "m2": {"m": 2},
    "kg/m3": {"kg": 1, "m": -3},
    "kg.m2": {"kg": 1, "m": 2},
    "rad.s2/m": {"rad": 1, "s": 2, "m": -1},
    "%": {"factor": 0.01},
}

def _attr(**kw: object) -> str:
    return "".join(f' {k}="{escape(str(v), {chr(34): "&quot;"})}"' for k, v in kw.items() if v is not None)


def _num(x: float | int, type_: str) -> str:
    return str(int(x)) if type_ == "Int32" else repr(float(x))


def _units_xml(vs: list[dict], indent: str) -> list[str]:
    used = sorted({v["unit"] for v in vs if v.get("unit", "1") != "1"})
    out = [f"{indent}<UnitDefinitions>"]
    for u in used:
        base = {k: (repr(float(e)) if k == "factor" else int(e)) for k, e in UNITS[u].items()}
        out.append(f'{indent}  <Unit name="{escape(u)}"><BaseUnit{_attr(**base)}/></Unit>')
    out.append(f"{indent}</UnitDefinitions>")
    return out


def _variable_attrs(vr: int, v: dict) -> dict[str, object]:
    """The attributes every FMI version gives a variable."""
    return {
        "name": v["name"],
        "valueReference": vr,
        "description": v.get("description"),
        "causality": v["causality"],
        "variability": v["variability"],
    }


def _value_attrs(v: dict) -> dict[str, object]:
    """Unit, range and start of a variable (FMI 3.0: on the variable; 2.0: on its type element)."""
    kw: dict[str, object] = {}
    if v["type"] == "Float64" and v.get("unit", "1") != "1":
        kw["unit"] = v["unit"]
    if v["causality"] in ("parameter", "input"):
        if "min" in v:
            kw["min"] = _num(v["min"], v["type"])
        if "max" in v:
            kw["max"] = _num(v["max"], v["type"])
        kw["start"] = _num(v["start"], v["type"])
    return kw


def gen_md3(spec: dict, stamp: str) -> str:
    """FMI 3.0 modelDescription.xml."""
    m, vs = spec["model"], spec["variables"]
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        "<fmiModelDescription"
        + _attr(
            fmiVersion="3.0",
            modelName=m["name"],
            description=m["description"],
            version=m.get("version"),
            instantiationToken=spec["token"],
            generationTool="nav-hil-bench fmu/build.py",
            generationDateAndTime=stamp,
            variableNamingConvention="flat",
            license="BSD-3-Clause",
        )
        + ">",
        "  <CoSimulation"
        + _attr(
            modelIdentifier=m["identifier"],
            canHandleVariableCommunicationStepSize="true",
            canGetAndSetFMUState="true",
            canSerializeFMUState="true",
            hasEventMode="false",
            providesIntermediateUpdate="false",
        )
        + "/>",
        *_units_xml(vs, "  "),
        "  <LogCategories>",
        '    <Category name="logStatusError" description="errors: failed steps, refused calls"/>',
        "  </LogCategories>",
        "  <DefaultExperiment"
        + _attr(startTime=m["start_time"], stopTime=m["stop_time"], stepSize=m["step_size"])
        + "/>",
        "  <ModelVariables>",
    ]
    for i, v in enumerate(vs):
        out.append(f"    <{v['type']}{_attr(**_variable_attrs(i, v), **_value_attrs(v))}/>")
    out.append("  </ModelVariables>")
    out.append("  <ModelStructure>")
    outputs = [i for i, v in enumerate(vs) if v["causality"] == "output"]
    out += [f'    <Output valueReference="{i}"/>' for i in outputs]
    out += [f'    <InitialUnknown valueReference="{i}"/>' for i in outputs]
    out += ["  </ModelStructure>", "</fmiModelDescription>", ""]
    return "\n".join(out)


def gen_md2(spec: dict, stamp: str) -> str:
    """FMI 2.0 modelDescription.xml."""
    m, vs = spec["model"], spec["variables"]
    sources = [*m["sources"], "solver.c", "fmi2_glue.c"]
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        "<fmiModelDescription"
        + _attr(
            fmiVersion="2.0",
            modelName=m["name"],
            guid=spec["token"],
            description=m["description"],
            version=m.get("version"),
            generationTool="nav-hil-bench fmu/build.py",
            generationDateAndTime=stamp,
            variableNamingConvention="flat",
            numberOfEventIndicators=0,
            license="BSD-3-Clause",
        )
        + ">",
        "  <CoSimulation"
        + _attr(
            modelIdentifier=m["identifier"],
            canHandleVariableCommunicationStepSize="true",
            canGetAndSetFMUstate="true",
            canSerializeFMUstate="true",
            canNotUseMemoryManagementFunctions="true",
        )
        + ">",
        "    <SourceFiles>",
        *[f'      <File name="{s}"/>' for s in sources],
        "    </SourceFiles>",
        "  </CoSimulation>",
        *_units_xml(vs, "  "),
        "  <LogCategories>",
        '    <Category name="logStatusError" description="errors: failed steps, refused calls"/>',
        "  </LogCategories>",
        "  <DefaultExperiment"
        + _attr(startTime=m["start_time"], stopTime=m["stop_time"], stepSize=m["step_size"])
        + "/>",
        "  <ModelVariables>",
    ]
    for i, v in enumerate(vs):
        kw = _variable_attrs(i, v)
        if v["causality"] == "output":
            kw["initial"] = "calculated"
        tname = "Real" if v["type"] == "Float64" else "Integer"
        out.append(f"    <ScalarVariable{_attr(**kw)}><{tname}{_attr(**_value_attrs(v))}/></ScalarVariable>")
    out.append("  </ModelVariables>")
    out.append("  <ModelStructure>")
    idx = [i + 1 for i, v in enumerate(vs) if v["causality"] == "output"]
    out.append("    <Outputs>")
    out += [f'      <Unknown index="{i}"/>' for i in idx]
    out.append("    </Outputs>")
    out.append("    <InitialUnknowns>")
    out += [f'      <Unknown index="{i}"/>' for i in idx]
    out.append("    </InitialUnknowns>")
    out += ["  </ModelStructure>", "</fmiModelDescription>", ""]
    return "\n".join(out)


def gen_build_description(spec: dict) -> str:
    """FMI 3.0 ``sources/buildDescription.xml``."""
    m = spec["model"]
    files = [*m["sources"], "solver.c", "fmi3_glue.c"]
    return "\n".join(
        [
            '<?xml version="1.0" encoding="UTF-8"?>',
            '<fmiBuildDescription fmiVersion="3.0">',
            f'  <BuildConfiguration modelIdentifier="{m["identifier"]}">',
            '    <SourceFileSet language="C99">',
            *[f'      <SourceFile name="{f}"/>' for f in files],
            "    </SourceFileSet>",
            "  </BuildConfiguration>",
            "</fmiBuildDescription>",
            "",
        ]
    )
