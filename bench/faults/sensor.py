"""Sensor-level fault kinds: what they take, and what they do to a sensor's samples.

Importing this module registers the kinds with :func:`bench.faults.schedule.register_kind`
(layer ``"sensor"``); the sensor models call the functions below on the samples of each
window. A fault window covers bench times ``start <= t < end`` (``t`` the time of
validity of a sample). Targets are sensor instance names: ``odometer``, ``doppler``,
``bds``, ``imu`` (or any name starting so, e.g. ``odometer_left``).

Two odometer kinds are motions of the vehicle rather than of the sensor: ``sideslip`` (the
body slides sideways) and the vertical jolt of ``bump``. They change the truth through
:class:`bench.faults.motion.FaultedTrajectory`, so the IMU, Doppler radar and BDS
receiver sense them as they would, and the odometer, which measures its wheel, does not.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from bench.errors import ConfigError
from bench.faults.schedule import FaultSchedule, FaultWindow, ParamSpec, register_kind, registered_kinds

__all__ = [
    "ODOMETER_KINDS",
    "DOPPLER_KINDS",
    "BDS_KINDS",
    "IMU_KINDS",
    "MOTION_KINDS",
    "register_sensor_kinds",
    "windows_for",
    "in_window",
    "bump_shape",
    "odometer_wheel_speed",
    "odometer_silenced",
    "doppler_apply",
    "bds_apply",
    "imu_apply",
    "OUTAGE_STYLES",
    "kinds_markdown",
]

ODOMETER_KINDS = ("idling", "sliding", "sideslip", "no_output", "bump")
DOPPLER_KINDS = ("dropout", "bias_step")
BDS_KINDS = ("outage", "jump", "drift", "multipath")
IMU_KINDS = ("bias_step", "axis_failure", "saturation")
#: Odometer kinds that move the vehicle body (applied to the truth).
MOTION_KINDS = ("sideslip", "bump")
#: Outage styles on the ``/bds`` records (``outage_style`` field).
OUTAGE_STYLES = {"none": 0, "no_fix": 1, "silent": 2}

_P = ParamSpec


def register_sensor_kinds() -> None:
    """Register every sensor-level kind (idempotent; done on import)."""
    odo = ("odometer*",)
    register_kind(
        "sensor",
        odo,
        "idling",
        {
            "ratio": _P("dimensionless", "1", 0.3, "the wheel turns this fraction faster than the body moves"),
            "speed": _P("velocity", "m/s", 0.0, "and this much faster again (idling while the body stands)"),
        },
        "the wheel or track spins faster than the body moves: the odometer reads distance not travelled",
    )
    register_kind(
        "sensor",
        odo,
        "sliding",
        {"ratio": _P("dimensionless", "1", 1.0, "fraction of the body speed the wheel loses (1: locked)")},
        "the body moves, the wheel turns slower or is locked: the odometer reads too little",
    )
    register_kind(
        "sensor",
        odo,
        "sideslip",
        {
            "speed": _P("velocity", "m/s", 0.5, "lateral body speed, positive to the right"),
            "ramp": _P("time", "s", 0.5, "smooth rise and fall time of the lateral speed"),
        },
        "the body slides sideways (truth changes); the odometer does not see it",
    )
    register_kind(
        "sensor",
        odo,
        "no_output",
        {"flag_invalid": _P("boolean", "", False, "also clear the ICD valid bit (else frames claim valid)")},
        "no pulses: count frozen, speed zero",
    )
    register_kind(
        "sensor",
        odo,
        "bump",
        {
            "speed": _P("velocity", "m/s", 2.0, "peak of the wheel-speed spike, in the direction of travel"),
            "height": _P("length", "m", 0.05, "peak vertical jolt of the body (truth changes)"),
        },
        "vertical jolt: the body bounces, the wheel speed spikes",
    )
    dop = ("doppler*",)
    register_kind(
        "sensor",
        dop,
        "dropout",
        {"low_signal": _P("boolean", "", True, "set the low-signal bit as well as clearing valid")},
        "no usable echo: valid cleared, speed zero",
    )
    register_kind(
        "sensor",
        dop,
        "bias_step",
        {
            "bias": _P("velocity", "m/s", 0.5, "velocity bias added to the forward ground speed"),
            "scale_factor": _P("dimensionless", "1", 0.0, "scale-factor error added"),
        },
        "a step in the radar's bias and scale factor",
    )
    bds = ("bds*",)
    register_kind(
        "sensor",
        bds,
        "outage",
        {"style": _P("text", "", "", "no_fix or silent; empty: the receiver's configured outage_style")},
        "no fix (tunnel, jamming)",
    )
    register_kind(
        "sensor",
        bds,
        "jump",
        {
            "east": _P("length", "m", 0.0, "position offset east"),
            "north": _P("length", "m", 0.0, "position offset north"),
            "up": _P("length", "m", 0.0, "position offset up"),
        },
        "the fixed position jumps by an offset for the window (the reported sigma does not change)",
    )
    register_kind(
        "sensor",
        bds,
        "drift",
        {
            "east": _P("velocity", "m/s", 0.0, "drift rate east"),
            "north": _P("velocity", "m/s", 0.0, "drift rate north"),
            "up": _P("velocity", "m/s", 0.0, "drift rate up"),
        },
        "position error grows at a constant rate from the window start; velocity carries the rate",
    )
    register_kind(
        "sensor",
        bds,
        "multipath",
        {
            "factor": _P("dimensionless", "1", 3.0, "error level multiplier (sigma, HDOP and satellites follow)"),
            "bias": _P("length", "m", 5.0, "horizontal position bias"),
            "azimuth": _P("angle", "deg", 0.0, "direction of the bias, clockwise from north"),
            "up": _P("length", "m", 0.0, "vertical position bias"),
        },
        "degraded fixes: a multipath step and a higher error level",
    )
    imu = ("imu*",)
    register_kind(
        "sensor",
        imu,
        "bias_step",
        {
            "gyro": _P("angular_rate", "deg/h", 0.0, "gyro bias step (one value or x, y, z)"),
            "accel": _P("acceleration", "ug", 0.0, "accelerometer bias step (one value or x, y, z)"),
        },
        "a step in the gyro and accelerometer biases",
    )
    register_kind(
        "sensor",
        imu,
        "axis_failure",
        {
            "sensor": _P("text", "", "gyro", "gyro or accel"),
            "axis": _P("text", "", "z", "x, y or z"),
            "mode": _P("text", "", "zero", "zero (dead axis) or stuck (last value held)"),
            "flag": _P("boolean", "", True, "clear the axis's valid bit and set the BIT-fault bit"),
        },
        "one axis fails",
    )
    register_kind(
        "sensor",
        imu,
        "saturation",
        {
            "gyro_range": _P("angular_rate", "deg/s", 10.0, "gyro range during the window (0: unchanged)"),
            "accel_range": _P("acceleration", "g", 0.0, "accelerometer range during the window (0: unchanged)"),
        },
        "the output clips at a reduced range; status bit 7 on clipped samples",
    )


register_sensor_kinds()


def windows_for(schedule: FaultSchedule | Iterable[FaultWindow] | None, target: str) -> list[FaultWindow]:
    """The sensor-layer windows aimed at ``target``, checked for values TOML types cannot."""
    if schedule is None:
        return []
    out = [w for w in schedule if w.layer == "sensor" and w.target == target]
    for w in out:
        p = w.params
        where = f"fault {w.id} ({w.target} {w.kind})"
        if w.kind == "multipath" and not p.get("factor", 1.0) > 0.0:
            raise ConfigError(f"{where}: factor must be positive, found {p.get('factor')!r}")
        if w.kind in ("idling", "sliding") and p.get("ratio", 0.0) < 0.0:
            raise ConfigError(f"{where}: ratio must not be negative, found {p['ratio']!r}")
        if w.kind == "outage" and p.get("style", "") not in ("", "no_fix", "silent"):
            raise ConfigError(f"{where}: style must be no_fix or silent, found {p['style']!r}")
        if w.kind == "axis_failure":
            for key, allowed in (("sensor", ("gyro", "accel")), ("axis", ("x", "y", "z")), ("mode", ("zero", "stuck"))):
                if p.get(key) not in allowed:
                    raise ConfigError(f"{where}: {key} must be one of {', '.join(allowed)}, found {p.get(key)!r}")
        if w.kind == "bias_step" and w.target.startswith("imu"):
            for key in ("gyro", "accel"):
                v = p.get(key, 0.0)
                if isinstance(v, list) and len(v) != 3:
                    raise ConfigError(f"{where}: {key} takes one value or three, found {len(v)}")
    return out


def in_window(w: FaultWindow, t_ns: np.ndarray) -> np.ndarray:
    """Mask of the times ``t_ns`` (int64 ns) the window covers."""
    return (t_ns >= w.start_ns) & (t_ns < w.end_ns)


def bump_shape(w: FaultWindow, t_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pulse ``64 (x (1 - x))^3`` over the window (x = 0..1), peak 1 at the middle, with its
    first and second time derivatives (1/s, 1/s^2); zero outside the window."""
    T = (w.end_ns - w.start_ns) * 1e-9
    x = np.clip((t_ns - w.start_ns) * 1e-9 / T, 0.0, 1.0)
    u = x * (1.0 - x)
    du = 1.0 - 2.0 * x
    f = 64.0 * u**3
    df = 64.0 * 3.0 * u**2 * du / T
    d2f = 64.0 * (6.0 * u * du**2 - 6.0 * u**2) / T**2
    return f, df, d2f


def _direction(v: np.ndarray) -> np.ndarray:
    return np.where(v < 0.0, -1.0, 1.0)


def odometer_wheel_speed(windows: Sequence[FaultWindow], t_ns: np.ndarray, v_wheel: np.ndarray) -> np.ndarray:
    """Wheel surface speed (m/s, forward positive) with idling, sliding and bump applied."""
    v = np.array(v_wheel, dtype=float)
    for w in windows:
        if w.kind not in ("idling", "sliding", "bump"):
            continue
        m = in_window(w, t_ns)
        if not m.any():
            continue
        if w.kind == "idling":
            v[m] = v[m] * (1.0 + w.params["ratio"]) + _direction(v[m]) * w.params["speed"]
        elif w.kind == "sliding":
            v[m] = v[m] * (1.0 - w.params["ratio"])
        else:
            f, _, _ = bump_shape(w, t_ns[m])
            v[m] = v[m] + _direction(v[m]) * w.params["speed"] * f
    return v


def odometer_silenced(windows: Sequence[FaultWindow], t_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Masks ``(no pulses, valid bit cleared)`` of the ``no_output`` windows."""
    silent = np.zeros(len(t_ns), dtype=bool)
    invalid = np.zeros(len(t_ns), dtype=bool)
    for w in windows:
        if w.kind == "no_output":
            m = in_window(w, t_ns)
            silent |= m
            if w.params["flag_invalid"]:
                invalid |= m
    return silent, invalid


def doppler_apply(
    windows: Sequence[FaultWindow],
    t_ns: np.ndarray,
    speed: np.ndarray,
    true_speed: np.ndarray,
    valid: np.ndarray,
    low_signal: np.ndarray,
) -> None:
    """Bias steps, then dropouts, on Doppler samples (arrays changed in place)."""
    for w in windows:
        if w.kind == "bias_step":
            m = in_window(w, t_ns)
            speed[m] += w.params["bias"] + w.params["scale_factor"] * true_speed[m]
    for w in windows:
        if w.kind == "dropout":
            m = in_window(w, t_ns)
            valid[m] = 0
            speed[m] = 0.0
            if w.params["low_signal"]:
                low_signal[m] = 1


def bds_apply(
    windows: Sequence[FaultWindow],
    t_ns: np.ndarray,
    level: np.ndarray,
    offset_enu: np.ndarray,
    vel_offset_enu: np.ndarray,
    outage: np.ndarray,
    style: np.ndarray,
) -> None:
    """Outages, jumps, drifts and multipath on BDS epochs (arrays changed in place).

    ``level`` (n,) multiplies the error level; ``offset_enu``/``vel_offset_enu`` (n, 3)
    add to the position/velocity errors; ``outage`` (n,) bool; ``style`` (n,) outage
    style codes (:data:`OUTAGE_STYLES`, 0 where the receiver's own applies).
    """
    for w in windows:
        m = in_window(w, t_ns)
        if not m.any():
            continue
        p = w.params
        if w.kind == "outage":
            outage[m] = True
            if p["style"]:
                style[m] = OUTAGE_STYLES[p["style"]]
        elif w.kind == "jump":
            offset_enu[m] += np.array([p["east"], p["north"], p["up"]])
        elif w.kind == "drift":
            rate = np.array([p["east"], p["north"], p["up"]])
            dt = (t_ns[m] - w.start_ns) * 1e-9
            offset_enu[m] += dt[:, None] * rate
            vel_offset_enu[m] += rate
        elif w.kind == "multipath":
            level[m] *= p["factor"]
            az = p["azimuth"]
            offset_enu[m] += np.array([p["bias"] * np.sin(az), p["bias"] * np.cos(az), p["up"]])


def _triple(v: float | list[float]) -> np.ndarray:
    return np.asarray(v, dtype=float) * np.ones(3)


def imu_apply(
    windows: Sequence[FaultWindow],
    t_ns: np.ndarray,
    dtheta: np.ndarray,
    dvel: np.ndarray,
    status: np.ndarray,
    T: float,
    held: dict[int, np.ndarray],
    last: np.ndarray,
) -> None:
    """IMU faults on measured increments (arrays changed in place), in schedule order.

    ``T`` is the IMU interval (s). ``last`` (6,) is the last sample before this block
    (dtheta then dvel); ``held`` keeps, per window id, the value a stuck axis holds, so
    a window spanning several blocks holds the same value.
    """
    for w in windows:
        m = in_window(w, t_ns)
        if not m.any():
            continue
        p = w.params
        if w.kind == "bias_step":
            dtheta[m] += _triple(p["gyro"]) * T
            dvel[m] += _triple(p["accel"]) * T
        elif w.kind == "saturation":
            for data, rng, bit in ((dtheta, p["gyro_range"], 0x80), (dvel, p["accel_range"], 0x80)):
                if rng > 0.0:
                    lim = rng * T
                    over = (np.abs(data) > lim).any(axis=1) & m
                    data[m] = np.clip(data[m], -lim, lim)
                    status[over] |= bit
        elif w.kind == "axis_failure":
            ax = "xyz".index(p["axis"])
            data = dtheta if p["sensor"] == "gyro" else dvel
            col = ax + (0 if p["sensor"] == "gyro" else 3)
            if p["mode"] == "zero":
                data[m, ax] = 0.0
            else:
                if w.id not in held:
                    first = int(np.argmax(m))
                    held[w.id] = np.array(
                        last[col] if first == 0 else (dtheta if col < 3 else dvel)[first - 1, ax], dtype=float
                    )
                data[m, ax] = held[w.id]
            if p["flag"]:
                status[m] &= np.uint8(~(1 << col) & 0xFF)
                status[m] |= 0x40


def kinds_markdown() -> str:
    """The sensor-level kinds as a Markdown table (for ``docs/sensors.md``)."""
    rows = ["| target | kind | parameter | unit | default | meaning |", "|---|---|---|---|---|---|"]
    for k in registered_kinds():
        if k.layer != "sensor":
            continue
        target = ", ".join(t.rstrip("*") for t in k.targets)
        rows.append(f"| {target} | `{k.kind}` | | | | {k.description} |")
        for name, p in k.params.items():
            unit = p.unit if p.dimension not in ("text", "boolean", "integer") else p.dimension
            if isinstance(p.default, bool):
                default = "true" if p.default else "false"
            elif isinstance(p.default, str):
                default = f'"{p.default}"'
            else:
                default = f"{p.default:g}"
            rows.append(f"| | | `{name}` | {unit} | {default} | {p.description} |")
    return "\n".join(rows)
