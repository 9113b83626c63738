"""Mapping files: an FMU's variables to the bench's quantities (names, units, frames, signs).

The bench's truth needs, from a vehicle FMU, either its body motion (body velocity over
ground and body rate relative to the local level, 3-vectors, integrated by the bench) or
its own pose (heading, and optionally position: local east/north[/up] in metres from the
start point, or latitude/longitude[/height]), plus pitch and roll (a variable or a
constant), and optionally the odometer's wheel or sprocket speed. It drives the FMU's
inputs from the driver-command channels and writes the scenario's start state (position,
heading, speed) into FMU parameters. A mapping file says which FMU variable carries each,
in which unit, scale, sign, offset and angle convention, and in which body axes::

    [mapping]
    body_frame = "FLU"                      # RFU (bench), FLU (x fwd, y left, z up), FRD
    [outputs]
    velocity = { vars = ["vx", "vy", "vz"], unit = "km/h" }          # one unit for all three
    angular_rate = { x = { value = 0 }, y = { value = 0 }, z = { var = "r", unit = "deg/s" } }
    pitch = { var = "theta", unit = "deg", sign = -1 }   # FMU pitch is nose down positive
    roll = { value = 0 }                                 # a planar model: a constant
    heading = { var = "yaw", unit = "rad", convention = "ccw_from_east" }
    position = { east = { var = "x", unit = "m" }, north = { var = "y", unit = "m" } }
    odometer_speed = { var = "wheel_speed", unit = "km/h" }
    [inputs]
    throttle = { var = "pedal", unit = "%" }
    left_lever = { var = "lever_l", values = [1, 2, 3] } # FMU codes of bench positions 0, 1, 2
    [start]
    heading = { var = "yaw0", unit = "rad", convention = "ccw_from_east", wrap = "symmetric" }
    speed = { var = "v0", unit = "km/h" }

Channels are described in :mod:`bench.plant.channels`; inputs and start values go the
other way (the exact inverse). Vectors are taken in ``body_frame`` and turned into RFU.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.config.files import read_toml
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.plant.channels import FRAMES, Channel, VectorChannel, parse_channel, parse_vector

__all__ = ["Channel", "VectorChannel", "PlantMapping", "load_mapping", "FRAMES", "INPUT_CHANNELS", "START_KEYS",
           "POSITION_KEYS"]

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
#: Start-state values written into FMU parameters, and their dimension.
START_KEYS = {"heading": "rad", "speed": "m/s", "east": "m", "north": "m", "up": "m", "latitude": "rad",
              "longitude": "rad", "height": "m"}
#: Position outputs: local (metres from the start point) or geodetic.
POSITION_KEYS = {"local": ("east", "north", "up"), "geodetic": ("latitude", "longitude", "height")}
_OUTPUTS = {"velocity", "angular_rate", "pitch", "roll", "odometer_speed", "heading", "position"}


@dataclass
class PlantMapping:
    """A parsed mapping file (see the module docstring)."""

    body_frame: str
    velocity: VectorChannel | None
    angular_rate: VectorChannel | None
    pitch: Channel
    roll: Channel
    odometer_speed: Channel | None
    inputs: dict[str, Channel] = field(default_factory=dict)
    source: str = ""
    heading: Channel | None = None
    position: dict[str, Channel] | None = None
    position_kind: str = ""  # "local" or "geodetic" when position is mapped
    start: dict[str, Channel] = field(default_factory=dict)

    @property
    def pose_truth(self) -> bool:
        """True when the FMU's own position (and heading) make the truth."""
        return self.position is not None

    def output_channels(self) -> list[Channel]:
        """Every output channel (constants included)."""
        chans: list[Channel] = []
        for vec in (self.velocity, self.angular_rate):
            if vec is not None:
                chans.extend(vec.components)
        chans += [self.pitch, self.roll]
        chans += [c for c in (self.heading, self.odometer_speed) if c is not None]
        chans += list((self.position or {}).values())
        return chans

    def output_vars(self) -> list[str]:
        """FMU variables read after every step (each once), the columns :meth:`convert` takes."""
        names: list[str] = []
        for ch in self.output_channels():
            if ch.var is not None and ch.var not in names:
                names.append(ch.var)
        return names

    def convert(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        """Columns of :meth:`output_vars` (N, k) -> bench quantities (SI, RFU).

        Keys: ``pitch``, ``roll``; ``vel_b``, ``omega_nb_b`` (N, 3) when mapped; ``psi``
        (heading clockwise from north, as the FMU gives it: not unwrapped), ``pos_enu``
        (N, 3, metres from the start point) or ``lat``, ``lon``, ``h`` when mapped;
        ``odometer_speed``.
        """
        col = {name: i for i, name in enumerate(self.output_vars())}
        n = raw.shape[0]

        def one(ch: Channel) -> np.ndarray:
            return ch.constant(n) if ch.var is None else np.asarray(ch.to_bench(raw[:, col[ch.var]]))

        out = {"pitch": one(self.pitch), "roll": one(self.roll)}
        for name, vec in (("vel_b", self.velocity), ("omega_nb_b", self.angular_rate)):
            if vec is not None:
                out[name] = vec.to_rfu([raw[:, col[c.var]] if c.var else np.zeros(n) for c in vec.components])
        if self.heading is not None:
            out["psi"] = one(self.heading)
        if self.position is not None:
            p = self.position
            if self.position_kind == "local":
                up = one(p["up"]) if "up" in p else np.zeros(n)
                out["pos_enu"] = np.column_stack([one(p["east"]), one(p["north"]), up])
            else:
                out["lat"], out["lon"] = one(p["latitude"]), one(p["longitude"])
                if "height" in p:
                    out["h"] = one(p["height"])
        if self.odometer_speed is not None:
            out["odometer_speed"] = one(self.odometer_speed)
        return out

    def start_values(self, *, heading: float, speed: float, lat: float, lon: float, h: float) -> dict[str, float]:
        """FMU variable -> value of the ``[start]`` channels for a start state (bench units:
        heading clockwise from north, rad; speed m/s; the start point is east = north =
        up = 0, latitude/longitude in rad, height in m), through the inverse conversions."""
        bench = {"heading": heading, "speed": speed, "east": 0.0, "north": 0.0, "up": 0.0, "latitude": lat,
                 "longitude": lon, "height": h}
        return {ch.var: ch.to_fmu(bench[name]) for name, ch in self.start.items() if ch.var is not None}

    def described_units(self) -> dict[str, str | None]:
        """FMU variable -> unit the mapping assumes for it (for checks against the FMU)."""
        units: dict[str, str | None] = {}
        for ch in (*self.output_channels(), *self.inputs.values(), *self.start.values()):
            if ch.var is not None:
                units[ch.var] = ch.unit
        return units

    def channel_keys(self) -> dict[str, str]:
        """FMU variable -> the mapping key that names it (for messages)."""
        keys: dict[str, str] = {}
        for ch in (*self.output_channels(), *self.inputs.values(), *self.start.values()):
            if ch.var is not None:
                keys.setdefault(ch.var, ch.key)
        return keys


def _only(table: Any, allowed: set[str], key: str, file: str) -> None:
    if not isinstance(table, Mapping):
        raise ConfigError(f"expected a table, found {table!r}", file=file, key=key or None)
    check_keys(table, allowed, file=file, key=key)


def _position(t: Any, file: str) -> tuple[str, dict[str, Channel]]:
    key = "outputs.position"
    if not isinstance(t, Mapping):
        raise ConfigError("expected a table with east/north[/up] or latitude/longitude[/height]", file=file, key=key)
    kinds = [k for k, names in POSITION_KEYS.items() if any(n in t for n in names)]
    if len(kinds) != 1:
        raise ConfigError("expected either east/north[/up] (metres from the start point) or "
                          "latitude/longitude[/height]", file=file, key=key)
    kind = kinds[0]
    names = POSITION_KEYS[kind]
    _only(t, set(names), key, file)
    for need in names[:2]:
        if need not in t:
            raise ConfigError("missing position component", file=file, key=f"{key}.{need}")
    dims = {"east": "m", "north": "m", "up": "m", "latitude": "rad", "longitude": "rad", "height": "m"}
    return kind, {n: parse_channel(t[n], dims[n], file, f"{key}.{n}") for n in names if n in t}


def load_mapping(path: str | Path) -> PlantMapping:
    """Read and check a mapping file."""
    path = Path(path)
    file = str(path)
    doc = read_toml(path, what="mapping file")
    _only(doc, {"mapping", "outputs", "inputs", "start"}, "", file)
    meta = doc.get("mapping", {})
    _only(meta, {"body_frame", "description"}, "mapping", file)
    frame = meta.get("body_frame", "RFU")
    if frame not in FRAMES:
        raise ConfigError(f"expected one of {', '.join(FRAMES)}, found {frame!r}", file=file, key="mapping.body_frame")
    outs = doc.get("outputs")
    if not isinstance(outs, Mapping):
        raise ConfigError("expected an [outputs] table", file=file, key="outputs")
    _only(outs, _OUTPUTS, "outputs", file)
    for need in ("pitch", "roll"):
        if need not in outs:
            raise ConfigError("missing output mapping (give 'value = 0' for a model without it)", file=file,
                              key=f"outputs.{need}")
    if "position" in outs and "heading" not in outs:
        raise ConfigError("a position needs the FMU's heading too", file=file, key="outputs.heading")
    if "position" not in outs:
        need = ("velocity",) if "heading" in outs else ("velocity", "angular_rate")
        for k in need:
            if k not in outs:
                raise ConfigError("missing output mapping (the truth needs body velocity and angular rate, or "
                                  "the FMU's heading with velocity, or its heading and position)", file=file,
                                  key=f"outputs.{k}")
    ins = doc.get("inputs", {})
    _only(ins, set(INPUT_CHANNELS), "inputs", file)
    start = doc.get("start", {})
    _only(start, set(START_KEYS), "start", file)
    kind, position = _position(outs["position"], file) if "position" in outs else ("", None)
    vec = {k: parse_vector(outs[k], d, frame, file, f"outputs.{k}") if k in outs else None
           for k, d in (("velocity", "m/s"), ("angular_rate", "rad/s"))}
    return PlantMapping(
        body_frame=frame,
        velocity=vec["velocity"],
        angular_rate=vec["angular_rate"],
        pitch=parse_channel(outs["pitch"], "rad", file, "outputs.pitch"),
        roll=parse_channel(outs["roll"], "rad", file, "outputs.roll"),
        odometer_speed=parse_channel(outs["odometer_speed"], "m/s", file, "outputs.odometer_speed", constant=False)
        if "odometer_speed" in outs
        else None,
        inputs={name: parse_channel(t, INPUT_CHANNELS[name], file, f"inputs.{name}", constant=False)
                for name, t in ins.items()},
        source=file,
        heading=parse_channel(outs["heading"], "rad", file, "outputs.heading", constant=False, angle=True)
        if "heading" in outs
        else None,
        position=position,
        position_kind=kind,
        start={name: parse_channel(t, START_KEYS[name], file, f"start.{name}", constant=False,
                                   angle=name == "heading") for name, t in start.items()},
    )
