"""Sensor-level fault kinds: what they take, and what they do to a sensor's samples.

Importing this module registers the kinds (:mod:`bench.faults.sensor_kinds`, layer
``"sensor"``); the sensor models call the functions below on the samples of each
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
from bench.faults.schedule import FaultSchedule, FaultWindow
from bench.faults.sensor_kinds import (
    BDS_KINDS,
    DOPPLER_KINDS,
    IMU_KINDS,
    MOTION_KINDS,
    ODOMETER_KINDS,
    OUTAGE_STYLES,
    kinds_markdown,
    register_sensor_kinds,
)

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
