"""Driver-command scripts: timelines of levers, pedals, steering and terrain.

A scenario driven through an FMU lists ``[[command]]`` tables in time order. Each sets
channels at ``at``; a channel holds its value until set again. A value is a step
(``throttle = 0.6``, ``grade = "-3 deg"``, ``left_lever = 1``) or a linear ramp from the
current value (``throttle = { to = 0.8, over = "10 s" }``). Lever positions are 0 (most
former, 1:1), 1 (position I) and 2 (position II, locked), or the names ``"former"``,
``"I"``, ``"II"``. ``label``, ``surface`` and ``gnss`` describe the stretch that starts
there (the trajectory's segments).

Commands reach the FMU at the command rate (100 Hz by default): at each command tick the
channels' values are sampled and held until the next tick, as a driver's controls are
read by a vehicle's electronics; :meth:`DriverScript.held` gives exactly what was applied.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.config.bounds import bounded_quantity
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.scenario.trajectory import SegmentInfo
from bench.units import quantity

__all__ = ["CHANNELS", "DriverScript", "parse_commands", "driving_state"]

#: Channel -> (dimension, default unit, initial value).
CHANNELS: dict[str, tuple[str, str, float]] = {
    "throttle": ("dimensionless", "1", 0.0),
    "brake": ("dimensionless", "1", 0.0),
    "steering": ("angle", "deg", 0.0),
    "grade": ("angle", "deg", 0.0),
    "bank": ("angle", "deg", 0.0),
    "left_lever": ("lever", "", 0.0),
    "right_lever": ("lever", "", 0.0),
}
_LEVER_NAMES = {"former": 0, "most_former": 0, "I": 1, "II": 2}
_EVENT_KEYS = {"at", "label", "surface", "gnss", *CHANNELS}


@dataclass
class _Piece:
    t0: float
    t1: float
    v0: float
    v1: float


@dataclass
class DriverScript:
    """Parsed command timeline.

    Attributes
    ----------
    duration_s: end of the drive, s.
    pieces: channel -> linear pieces (t0, t1, v0, v1); the value holds after the last.
    events: (time, label, surface, gnss, channels set) in time order.
    rate_hz: command rate.
    """

    duration_s: float
    pieces: dict[str, list[_Piece]]
    events: list[dict[str, Any]]
    rate_hz: float = 100.0
    initial: dict[str, float] = field(default_factory=dict)

    def value(self, name: str, t: np.ndarray) -> np.ndarray:
        """Channel ``name`` at times ``t`` (s) as scripted (continuous ramps)."""
        t = np.asarray(t, dtype=float)
        out = np.full(t.shape, self.initial[name])
        for p in self.pieces[name]:
            if p.t1 > p.t0:
                x = np.clip((t - p.t0) / (p.t1 - p.t0), 0.0, 1.0)
                out = np.where(t >= p.t0, p.v0 + (p.v1 - p.v0) * x, out)
            else:
                out = np.where(t >= p.t0, p.v1, out)
        return out

    def held(self, name: str, t: np.ndarray) -> np.ndarray:
        """What the FMU was given at times ``t``: the value at the last command tick."""
        t = np.asarray(t, dtype=float)
        tick = np.floor(t * self.rate_hz + 1e-9) / self.rate_hz
        return self.value(name, tick)

    def channels_used(self) -> list[str]:
        """Channels the script sets at least once."""
        return [c for c in CHANNELS if self.pieces[c]]

    def ticks(self, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """Command ticks where any of ``names`` changes: (tick times (M,), values (M, len(names))).

        The first row is the initial tick (t = 0).
        """
        n = math.floor(self.duration_s * self.rate_hz + 1e-9) + 1
        t = np.arange(n) / self.rate_hz
        vals = np.stack([self.value(c, t) for c in names], axis=1) if names else np.zeros((n, 0))
        changed = np.ones(n, dtype=bool)
        if n > 1:
            changed[1:] = np.any(vals[1:] != vals[:-1], axis=1)
        return t[changed], vals[changed]

    def segments(self) -> list[SegmentInfo]:
        """One segment per command, named by the driving state it sets up."""
        out = []
        for i, ev in enumerate(self.events):
            end = self.events[i + 1]["at"] if i + 1 < len(self.events) else self.duration_s
            if end <= ev["at"]:
                continue
            state = {c: float(self.value(c, np.array([end - 1e-6]))[0]) for c in CHANNELS}
            out.append(
                SegmentInfo(
                    index=len(out), kind=driving_state(state), start_s=ev["at"], end_s=end,
                    gnss=ev["gnss"], surface=ev["surface"], label=ev["label"],
                    params={k: v for k, v in ev["raw"].items() if k in CHANNELS},
                )
            )
        return out

    def surface_changes(self) -> list[tuple[float, str]]:
        """(time, surface) where the ground changes, the first at t = 0."""
        out: list[tuple[float, str]] = []
        for ev in self.events:
            if not out or out[-1][1] != ev["surface"]:
                out.append((ev["at"], ev["surface"]))
        return out


def driving_state(v: Mapping[str, float]) -> str:
    """Name of the driving state set by channel values (seed 002 section 3 for levers)."""
    left, right = round(v.get("left_lever", 0)), round(v.get("right_lever", 0))
    if left == 2 and right == 2:
        return "parked"
    if v.get("brake", 0.0) > 0.0:
        return "braking"
    if (left == 2) != (right == 2):
        return "turning_in_place"
    if left != right:
        return "turning_in_curve"
    if abs(v.get("steering", 0.0)) > 1e-6:
        return "turning"
    if v.get("throttle", 0.0) <= 0.0:
        return "coasting"
    return "straight_low" if left == 1 else "straight"


def _value(name: str, raw: Any, file: str, key: str) -> float:
    dim, unit, _ = CHANNELS[name]
    if dim == "lever":
        if isinstance(raw, str) and raw in _LEVER_NAMES:
            return float(_LEVER_NAMES[raw])
        if isinstance(raw, int) and not isinstance(raw, bool) and raw in (0, 1, 2):
            return float(raw)
        raise ConfigError(f"expected a lever position 0, 1, 2 (or former, I, II), found {raw!r}", file=file, key=key)
    value = quantity(raw, dim, unit, file=file, key=key)
    if name in ("throttle", "brake") and not 0.0 <= value <= 1.0:
        raise ConfigError(f"expected a pedal position within 0..1, found {raw!r}", file=file, key=key)
    return value


def parse_commands(
    commands: Any, duration_s: float, *, file: str, surface: str = "asphalt", gnss: str = "open",
    rate_hz: float = 100.0, initial: Mapping[str, float] | None = None,
) -> DriverScript:
    """Parse a list of ``[[command]]`` tables (see the module docstring)."""
    from bench.scenario.motion import GNSS_FLAGS, SURFACES

    if not isinstance(commands, list) or not commands:
        raise ConfigError("expected at least one [[command]] table", file=file, key="command")
    init = {c: CHANNELS[c][2] for c in CHANNELS}
    init.update(initial or {})
    pieces: dict[str, list[_Piece]] = {c: [] for c in CHANNELS}
    current = dict(init)
    events: list[dict[str, Any]] = []
    last_t = -1.0
    for i, ev in enumerate(commands):
        key = f"command[{i}]"
        if not isinstance(ev, Mapping):
            raise ConfigError("expected a table", file=file, key=key)
        check_keys(ev, _EVENT_KEYS, file=file, key=key)
        if "at" not in ev:
            raise ConfigError("missing field", file=file, key=f"{key}.at")
        t = bounded_quantity(ev["at"], "time", "s", "time", file=file, key=f"{key}.at")
        if t <= last_t or (i == 0 and t != 0.0):
            raise ConfigError(f"commands must start at 0 s and increase in time, found {t:g} s after {last_t:g} s",
                              file=file, key=f"{key}.at")
        if t >= duration_s:
            raise ConfigError(f"command at {t:g} s is not before the end of the drive ({duration_s:g} s)", file=file,
                              key=f"{key}.at")
        last_t = t
        surface = ev.get("surface", surface)
        gnss = ev.get("gnss", gnss)
        if surface not in SURFACES:
            raise ConfigError(
                f"expected one of {', '.join(SURFACES)}, found {surface!r}", file=file, key=f"{key}.surface"
            )
        if gnss not in GNSS_FLAGS:
            raise ConfigError(f"expected one of {', '.join(GNSS_FLAGS)}, found {gnss!r}", file=file, key=f"{key}.gnss")
        for name in CHANNELS:
            if name not in ev:
                continue
            raw = ev[name]
            ck = f"{key}.{name}"
            if isinstance(raw, Mapping):
                if set(raw) != {"to", "over"} or CHANNELS[name][0] == "lever":
                    raise ConfigError("a ramp is { to = VALUE, over = DURATION } (levers only step)", file=file, key=ck)
                target = _value(name, raw["to"], file, f"{ck}.to")
                over = bounded_quantity(raw["over"], "time", "s", "offset", file=file, key=f"{ck}.over")
                if over <= 0.0:
                    raise ConfigError("expected a positive ramp duration", file=file, key=f"{ck}.over")
                pieces[name].append(_Piece(t, t + over, current[name], target))
            else:
                target = _value(name, raw, file, ck)
                pieces[name].append(_Piece(t, t, current[name], target))
            current[name] = target
        events.append({"at": t, "label": str(ev.get("label", "")), "surface": surface, "gnss": gnss, "raw": dict(ev)})
    for name, ps in pieces.items():
        for a, b in itertools.pairwise(ps):
            if b.t0 < a.t1 - 1e-9:
                raise ConfigError(f"{name}: a new command at {b.t0:g} s starts before the ramp ending at {a.t1:g} s",
                                  file=file, key="command")
    return DriverScript(duration_s=duration_s, pieces=pieces, events=events, rate_hz=rate_hz, initial=init)
