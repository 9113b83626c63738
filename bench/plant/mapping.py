"""Mapping files: an FMU's variables to the bench's quantities (names, units, frames, signs).

The bench needs, from any vehicle FMU, the body velocity over ground and the body's
angular rate relative to the local level (both 3-vectors), pitch and roll, and
optionally the odometer's wheel or sprocket speed; it drives the FMU's inputs from the
driver-command channels (``throttle``, ``brake``, ``steering``, ``left_lever``,
``right_lever``, ``grade``, ``bank``). A mapping file says which FMU variable carries
each, in which unit and with which sign, and in which body axes the FMU's vectors are::

    [mapping]
    body_frame = "FLU"                      # RFU (bench), FLU (x fwd, y left, z up), FRD
    [outputs]
    velocity = { vars = ["vx", "vy", "vz"], unit = "km/h" }
    angular_rate = { vars = ["p", "q", "r"], unit = "deg/s" }
    pitch = { var = "theta", unit = "deg", sign = -1 }   # FMU pitch is nose down positive
    roll = { var = "phi", unit = "deg" }
    odometer_speed = { var = "wheel_speed", unit = "km/h" }
    [inputs]
    throttle = { var = "pedal", unit = "%" }
    steering = { var = "steer", unit = "deg" }
    left_lever = { var = "lever_l", values = [1, 2, 3] } # FMU codes of bench positions 0, 1, 2

For every channel ``bench = sign * k * (fmu - offset)`` with ``k`` the SI value of one
``unit`` (:func:`bench.units.parse_unit`); inputs go the other way. Vectors are taken in
``body_frame`` and turned into the bench's RFU axes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.config.files import read_toml
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.units import parse_unit

__all__ = ["Channel", "VectorChannel", "PlantMapping", "load_mapping", "FRAMES", "INPUT_CHANNELS"]

#: Matrices M with v_RFU = M @ v_frame (proper rotations: rates transform alike).
FRAMES: dict[str, np.ndarray] = {
    "RFU": np.eye(3),
    "FLU": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    "FRD": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),
}

#: Bench input channels and the dimension of their values ('lever': integer position 0/1/2).
INPUT_CHANNELS = {
    "throttle": "1",
    "brake": "1",
    "steering": "rad",
    "grade": "rad",
    "bank": "rad",
    "left_lever": "lever",
    "right_lever": "lever",
}

_OUTPUT_DIMS = {"velocity": "m/s", "angular_rate": "rad/s", "pitch": "rad", "roll": "rad", "odometer_speed": "m/s"}


@dataclass(frozen=True)
class Channel:
    """One scalar: ``bench = sign * k * (fmu - offset)``; ``values`` maps lever positions."""

    var: str
    unit: str | None
    k: float = 1.0
    sign: float = 1.0
    offset: float = 0.0
    values: tuple[int, ...] | None = None

    def to_bench(self, raw: np.ndarray | float) -> np.ndarray | float:
        return self.sign * self.k * (raw - self.offset)

    def to_fmu(self, value: float) -> float:
        if self.values is not None:
            return float(self.values[round(value)])
        return self.offset + self.sign * value / self.k


@dataclass(frozen=True)
class VectorChannel:
    """Three FMU variables along the axes of ``frame``, converted to RFU and SI."""

    vars: tuple[str, str, str]
    unit: str | None
    k: float
    signs: tuple[float, float, float]
    frame: str

    def to_rfu(self, raw: np.ndarray) -> np.ndarray:
        """(N, 3) FMU values -> (N, 3) SI values in RFU axes."""
        return (raw * (self.k * np.asarray(self.signs))) @ FRAMES[self.frame].T


@dataclass
class PlantMapping:
    """A parsed mapping file."""

    body_frame: str
    velocity: VectorChannel
    angular_rate: VectorChannel
    pitch: Channel
    roll: Channel
    odometer_speed: Channel | None
    inputs: dict[str, Channel] = field(default_factory=dict)
    source: str = ""

    def output_vars(self) -> list[str]:
        """FMU variables read after every step, in the order :meth:`convert` expects."""
        names = [*self.velocity.vars, *self.angular_rate.vars, self.pitch.var, self.roll.var]
        if self.odometer_speed is not None:
            names.append(self.odometer_speed.var)
        return names

    def convert(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        """Columns of :meth:`output_vars` (N, k) -> bench quantities (SI, RFU)."""
        out = {
            "vel_b": self.velocity.to_rfu(raw[:, 0:3]),
            "omega_nb_b": self.angular_rate.to_rfu(raw[:, 3:6]),
            "pitch": self.pitch.to_bench(raw[:, 6]),
            "roll": self.roll.to_bench(raw[:, 7]),
        }
        if self.odometer_speed is not None:
            out["odometer_speed"] = self.odometer_speed.to_bench(raw[:, 8])
        return out

    def described_units(self) -> dict[str, str | None]:
        """FMU variable -> unit the mapping assumes for it (for checks against the FMU)."""
        units: dict[str, str | None] = {}
        for vec in (self.velocity, self.angular_rate):
            for v in vec.vars:
                units[v] = vec.unit
        for ch in (self.pitch, self.roll, self.odometer_speed, *self.inputs.values()):
            if ch is not None:
                units[ch.var] = ch.unit
        return units


def _unit_factor(unit: str | None, expect: str, file: str, key: str) -> float:
    if unit is None:
        return 1.0
    try:
        k, dim = parse_unit(str(unit))
    except Exception as exc:
        raise ConfigError(f"unknown unit {unit!r}: {exc}", file=file, key=key) from None
    if expect == "lever":
        raise ConfigError("lever channels take 'values', not a unit", file=file, key=key)
    if dim != parse_unit(expect)[1]:
        raise ConfigError(f"unit {unit!r} does not measure {expect!r}", file=file, key=key)
    return k


def _only(table: Mapping[str, Any], allowed: set[str], key: str, file: str) -> None:
    if not isinstance(table, Mapping):
        raise ConfigError(f"expected a table, found {table!r}", file=file, key=key or None)
    check_keys(table, allowed, file=file, key=key)


def _offset(value: Any, file: str, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"expected a finite number, found {value!r}", file=file, key=key)
    return float(value)


def _sign(value: Any, file: str, key: str) -> float:
    if value not in (1, -1):
        raise ConfigError(f"expected 1 or -1, found {value!r}", file=file, key=key)
    return float(value)


def _channel(t: Any, expect: str, file: str, key: str) -> Channel:
    if not isinstance(t, Mapping) or "var" not in t:
        raise ConfigError("expected a table with 'var'", file=file, key=key)
    _only(t, {"var", "unit", "sign", "offset", "values"}, key, file)
    values = None
    if "values" in t:
        codes = t["values"]
        if (
            expect != "lever"
            or not isinstance(codes, list)
            or len(codes) != 3
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in codes)
        ):
            raise ConfigError("'values' lists the FMU codes of lever positions 0, 1, 2", file=file, key=f"{key}.values")
        values = tuple(int(v) for v in t["values"])
    unit = t.get("unit")
    return Channel(
        var=str(t["var"]),
        unit=None if unit is None else str(unit),
        k=_unit_factor(unit, expect, file, f"{key}.unit") if expect != "lever" else 1.0,
        sign=_sign(t.get("sign", 1), file, f"{key}.sign"),
        offset=_offset(t.get("offset", 0.0), file, f"{key}.offset"),
        values=values,
    )


def _vector(t: Any, expect: str, frame: str, file: str, key: str) -> VectorChannel:
    if not isinstance(t, Mapping) or not isinstance(t.get("vars"), list) or len(t["vars"]) != 3:
        raise ConfigError("expected a table with 'vars' = three variable names", file=file, key=key)
    _only(t, {"vars", "unit", "signs"}, key, file)
    signs = t.get("signs", [1, 1, 1])
    if not isinstance(signs, list) or len(signs) != 3:
        raise ConfigError("expected three signs", file=file, key=f"{key}.signs")
    unit = t.get("unit")
    return VectorChannel(
        vars=tuple(str(v) for v in t["vars"]),  # type: ignore[arg-type]
        unit=None if unit is None else str(unit),
        k=_unit_factor(unit, expect, file, f"{key}.unit"),
        signs=tuple(_sign(s, file, f"{key}.signs") for s in signs),  # type: ignore[arg-type]
        frame=frame,
    )


def load_mapping(path: str | Path) -> PlantMapping:
    """Read and check a mapping file."""
    path = Path(path)
    file = str(path)
    doc = read_toml(path, what="mapping file")
    _only(doc, {"mapping", "outputs", "inputs"}, "", file)
    meta = doc.get("mapping", {})
    _only(meta, {"body_frame", "description"}, "mapping", file)
    frame = meta.get("body_frame", "RFU")
    if frame not in FRAMES:
        raise ConfigError(f"expected one of {', '.join(FRAMES)}, found {frame!r}", file=file, key="mapping.body_frame")
    outs = doc.get("outputs")
    if not isinstance(outs, Mapping):
        raise ConfigError("expected an [outputs] table", file=file, key="outputs")
    _only(outs, set(_OUTPUT_DIMS), "outputs", file)
    for need in ("velocity", "angular_rate", "pitch", "roll"):
        if need not in outs:
            raise ConfigError("missing output mapping", file=file, key=f"outputs.{need}")
    ins = doc.get("inputs", {})
    _only(ins, set(INPUT_CHANNELS), "inputs", file)
    return PlantMapping(
        body_frame=frame,
        velocity=_vector(outs["velocity"], "m/s", frame, file, "outputs.velocity"),
        angular_rate=_vector(outs["angular_rate"], "rad/s", frame, file, "outputs.angular_rate"),
        pitch=_channel(outs["pitch"], "rad", file, "outputs.pitch"),
        roll=_channel(outs["roll"], "rad", file, "outputs.roll"),
        odometer_speed=_channel(outs["odometer_speed"], "m/s", file, "outputs.odometer_speed")
        if "odometer_speed" in outs
        else None,
        inputs={name: _channel(t, INPUT_CHANNELS[name], file, f"inputs.{name}") for name, t in ins.items()},
        source=file,
    )
