"""Motion scripts: a start state and a list of segments, read from TOML.

The verbs are those users know from PSINS and gnss-ins-sim; see ``docs/motion_scripts.md``
for the full reference. Each segment starts its manoeuvre at the segment start, shapes it
within the limits (acceleration, jerk, angular acceleration, pitch rate) and holds the
result until the segment ends. A segment too short for its manoeuvre is an error that
says how long it needs to be.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from bench.config.bounds import check
from bench.errors import ConfigError
from bench.scenario.profile import SMOOTHSTEP_PEAK_SLOPE, Channel, ProfileTrajectory
from bench.scenario.script_values import Limits, _flag, _limits, _only, _opt, _table, check_script_size, parse_latlon
from bench.scenario.trajectory import SegmentInfo
from bench.units import G0, quantity

__all__ = ["SEGMENT_KINDS", "GNSS_FLAGS", "SURFACES", "parse_latlon", "build_profile", "Limits"]

SEGMENT_KINDS = (
    "static",
    "stop",
    "uniform",
    "accelerate",
    "decelerate",
    "turn",
    "coordinated_turn",
    "climb",
    "descend",
)
GNSS_FLAGS = ("open", "urban", "blocked")
SURFACES = ("asphalt", "cement", "gravel", "dirt", "sand", "mud", "grass", "snow", "ice", "wet", "water")

_SEGMENT_KEYS = {
    "common": {"kind", "duration", "gnss", "surface", "label", "repeat"},
    "static": set(),
    "stop": {"accel", "jerk"},
    "uniform": set(),
    "accelerate": {"speed", "accel", "jerk"},
    "decelerate": {"speed", "accel", "jerk"},
    "turn": {"angle", "direction", "rate", "radius", "angular_accel", "max_rate"},
    "coordinated_turn": {"angle", "direction", "rate", "radius", "angular_accel", "max_rate"},
    "climb": {"angle", "height", "pitch_rate"},
    "descend": {"angle", "height", "pitch_rate"},
}


class _Builder:
    """Turns segments into channels, keeping the vehicle state between them."""

    def __init__(self, speed0: float, heading0: float, pitch0: float, roll0: float, file: str | None):
        self.t = 0.0
        self.speed = speed0
        self.heading = heading0
        self.file = file
        self.accel = Channel(0.0)
        self.rate = Channel(0.0)
        self.pitch = Channel(pitch0)
        self.roll = Channel(roll0)

    # speed change with a smoothstep-shaped trapezoidal acceleration
    def speed_change(self, t0: float, target: float, a_max: float, jerk: float) -> float:
        dv = target - self.speed
        if dv == 0.0:
            return 0.0
        sign = 1.0 if dv > 0 else -1.0
        t_ramp = SMOOTHSTEP_PEAK_SLOPE * a_max / jerk
        if abs(dv) < a_max * t_ramp:  # never reaches a_max
            a_max = math.sqrt(abs(dv) * jerk / SMOOTHSTEP_PEAK_SLOPE)
            t_ramp = SMOOTHSTEP_PEAK_SLOPE * a_max / jerk
        t_hold = abs(dv) / a_max - t_ramp
        self.accel.ramp(t0, t_ramp, sign * a_max)
        self.accel.ramp(t0 + t_ramp + t_hold, t_ramp, 0.0)
        self.speed = target
        return 2.0 * t_ramp + t_hold

    def heading_change(self, t0: float, dpsi: float, rate: float, alpha: float, roll_per_rate: float | None) -> float:
        """Turn by ``dpsi`` (signed) at up to ``rate`` (> 0); returns the time it takes."""
        sign = 1.0 if dpsi > 0 else -1.0
        t_ramp = SMOOTHSTEP_PEAK_SLOPE * rate / alpha
        if abs(dpsi) < rate * t_ramp:
            rate = math.sqrt(abs(dpsi) * alpha / SMOOTHSTEP_PEAK_SLOPE)
            t_ramp = SMOOTHSTEP_PEAK_SLOPE * rate / alpha
        t_hold = abs(dpsi) / rate - t_ramp
        self.rate.ramp(t0, t_ramp, sign * rate)
        self.rate.ramp(t0 + t_ramp + t_hold, t_ramp, 0.0)
        if roll_per_rate is not None:
            bank = math.atan(roll_per_rate * sign * rate)
            base = self.roll.value
            self.roll.ramp(t0, t_ramp, base + bank)
            self.roll.ramp(t0 + t_ramp + t_hold, t_ramp, base)
        self.heading += dpsi
        return 2.0 * t_ramp + t_hold

    def pitch_hill(self, t0: float, angle: float, pitch_rate: float, hold: float) -> float:
        t_ramp = SMOOTHSTEP_PEAK_SLOPE * abs(angle) / pitch_rate
        base = self.pitch.value
        self.pitch.ramp(t0, t_ramp, base + angle)
        self.pitch.ramp(t0 + t_ramp + hold, t_ramp, base)
        return 2.0 * t_ramp + hold


def _ramp_height(speed: float, angle: float, t_ramp: float) -> float:
    """Height gained over one smoothstep pitch ramp 0 -> angle of length t_ramp at speed."""
    import numpy as np

    x, w = np.polynomial.legendre.leggauss(16)
    u = 0.5 * (x + 1.0)
    s = u**3 * (10 - 15 * u + 6 * u * u)
    return float(speed * t_ramp * 0.5 * np.sum(w * np.sin(angle * s)))


def build_profile(
    doc: Mapping[str, Any],
    *,
    file: str | None = None,
    internal_rate_hz: float = 1000.0,
) -> ProfileTrajectory:
    """Build the trajectory of a motion-script document (the parsed TOML).

    Raises
    ------
    ConfigError
        Naming the file and key of anything that is wrong.
    """
    init = _table(doc, "initial", file)
    _only(init, {"latitude", "longitude", "height", "speed", "heading", "pitch", "roll"}, "initial", file)
    for k in ("latitude", "longitude", "height", "heading"):
        if k not in init:
            raise ConfigError("missing field", file=file, key=f"initial.{k}")
    lat0 = parse_latlon(init["latitude"], "lat", file=file, key="initial.latitude")
    lon0 = parse_latlon(init["longitude"], "lon", file=file, key="initial.longitude")
    h0 = quantity(init["height"], "length", "m", file=file, key="initial.height")
    speed0 = quantity(init.get("speed", 0.0), "velocity", "m/s", file=file, key="initial.speed")
    heading0 = quantity(init["heading"], "angle", "deg", file=file, key="initial.heading")
    pitch0 = quantity(init.get("pitch", 0.0), "angle", "deg", file=file, key="initial.pitch")
    roll0 = quantity(init.get("roll", 0.0), "angle", "deg", file=file, key="initial.roll")

    limits = Limits()
    lim_doc = doc.get("limits", {})
    _only(lim_doc, set(Limits.__dataclass_fields__), "limits", file)
    limits = _limits(lim_doc, limits, "limits", file)
    defaults = doc.get("defaults", {})
    _only(defaults, {"gnss", "surface"}, "defaults", file)
    gnss0 = _flag(defaults.get("gnss", "open"), GNSS_FLAGS, "defaults.gnss", file)
    surface0 = _flag(defaults.get("surface", "asphalt"), SURFACES, "defaults.surface", file)

    segments = doc.get("segment")
    if not isinstance(segments, list) or not segments:
        raise ConfigError("expected at least one [[segment]] table", file=file, key="segment")
    check_script_size(segments, file=file)  # repeats, segment count and declared durations bounded

    b = _Builder(speed0, heading0, pitch0, roll0, file)
    infos: list[SegmentInfo] = []
    for i, seg in enumerate(segments):
        key = f"segment[{i}]"
        if not isinstance(seg, Mapping):
            raise ConfigError("expected a table", file=file, key=key)
        kind = seg.get("kind")
        if kind not in SEGMENT_KINDS:
            raise ConfigError(
                f"expected kind one of {', '.join(SEGMENT_KINDS)}, found {kind!r}", file=file, key=f"{key}.kind"
            )
        _only(seg, _SEGMENT_KEYS["common"] | _SEGMENT_KEYS[kind], key, file)
        repeat = seg.get("repeat", 1)
        if not isinstance(repeat, int) or isinstance(repeat, bool) or repeat < 1:
            raise ConfigError(f"expected a positive integer, found {repeat!r}", file=file, key=f"{key}.repeat")
        for _ in range(repeat):
            start = b.t
            length = _segment(b, seg, kind, limits, key, file)
            b.t = start + length
            check("duration", b.t, file=file, key=f"{key}.duration", shown=f"{b.t:g} s of motion up to {key}")
            infos.append(
                SegmentInfo(
                    index=len(infos),
                    kind=kind,
                    start_s=start,
                    end_s=b.t,
                    gnss=_flag(seg.get("gnss", gnss0), GNSS_FLAGS, f"{key}.gnss", file),
                    surface=_flag(seg.get("surface", surface0), SURFACES, f"{key}.surface", file),
                    label=str(seg.get("label", "")),
                    params={k: v for k, v in seg.items() if k not in ("kind", "label")},
                )
            )
    points = math.ceil(b.t * internal_rate_hz) + 1  # the position grid, 48 bytes each
    check("points", points, file=file, key="segment", shown=f"{points} ({b.t:g} s at {internal_rate_hz:g} Hz)")
    return ProfileTrajectory(
        lat0=lat0,
        lon0=lon0,
        h0=h0,
        speed0=speed0,
        heading0=heading0,
        accel=b.accel,
        heading_rate=b.rate,
        pitch=b.pitch,
        roll=b.roll,
        duration_s=b.t,
        segments=infos,
        internal_rate_hz=internal_rate_hz,
    )


def _segment(b: _Builder, seg: Mapping[str, Any], kind: str, limits: Limits, key: str, file: str | None) -> float:
    """Add one segment's manoeuvre at ``b.t``; return the segment length, s."""
    lim = _limits(seg, limits, key, file)
    duration = _opt(seg, "duration", "time", "s", key, file)
    if duration is not None and duration <= 0.0:
        raise ConfigError(f"expected a positive duration, found {seg['duration']!r}", file=file, key=f"{key}.duration")
    t0 = b.t
    need = 0.0
    if kind in ("static", "uniform"):
        if duration is None:
            raise ConfigError(
                "missing field (a static or uniform segment needs a duration)", file=file, key=f"{key}.duration"
            )
        if kind == "static" and abs(b.speed) > 1e-9:
            raise ConfigError(
                f"a static segment needs the vehicle at rest, but it moves at {b.speed:.3f} m/s "
                "(use 'stop' to brake first)",
                file=file,
                key=f"{key}.kind",
            )
    elif kind == "stop":
        need = b.speed_change(t0, 0.0, lim.accel, lim.jerk)
    elif kind in ("accelerate", "decelerate"):
        target = _opt(seg, "speed", "velocity", "m/s", key, file)
        if target is None:
            if duration is None or "accel" not in seg:
                raise ConfigError(
                    "expected a target 'speed', or 'accel' with 'duration'", file=file, key=f"{key}.speed"
                )
            t_ramp = SMOOTHSTEP_PEAK_SLOPE * lim.accel / lim.jerk
            if duration < 2.0 * t_ramp:
                raise ConfigError(
                    f"duration {duration:g} s is shorter than the two jerk-limited ramps ({2 * t_ramp:g} s)",
                    file=file,
                    key=f"{key}.duration",
                )
            dv = lim.accel * (duration - t_ramp)
            target = b.speed + (dv if kind == "accelerate" else -dv)
        if kind == "accelerate" and target <= b.speed:
            raise ConfigError(
                f"accelerate needs a speed above the current {b.speed:.3f} m/s, found {target:.3f}",
                file=file,
                key=f"{key}.speed",
            )
        if kind == "decelerate" and target >= b.speed:
            raise ConfigError(
                f"decelerate needs a speed below the current {b.speed:.3f} m/s, found {target:.3f}",
                file=file,
                key=f"{key}.speed",
            )
        need = b.speed_change(t0, target, lim.accel, lim.jerk)
    elif kind in ("turn", "coordinated_turn"):
        need = _turn(b, seg, kind, lim, key, file)
    elif kind in ("climb", "descend"):
        need = _hill(b, seg, kind, lim, duration, key, file)
    if duration is None:
        return need
    if need > duration + 1e-9:
        raise ConfigError(
            f"the {kind} manoeuvre needs {need:.3f} s within its limits, longer than the duration {duration:g} s",
            file=file,
            key=f"{key}.duration",
        )
    return duration


def _turn(b: _Builder, seg: Mapping[str, Any], kind: str, lim: Limits, key: str, file: str | None) -> float:
    angle = _opt(seg, "angle", "angle", "deg", key, file)
    if angle is None or angle <= 0.0:
        raise ConfigError("expected a positive heading change such as '90 deg'", file=file, key=f"{key}.angle")
    direction = seg.get("direction")
    if direction not in ("left", "right"):
        raise ConfigError(f"expected 'left' or 'right', found {direction!r}", file=file, key=f"{key}.direction")
    rate = _opt(seg, "rate", "angular_rate", "deg/s", key, file)
    radius = _opt(seg, "radius", "length", "m", key, file)
    if (rate is None) == (radius is None):
        raise ConfigError("give exactly one of 'rate' and 'radius'", file=file, key=f"{key}.rate")
    if radius is not None:
        if radius <= 0.0 or abs(b.speed) < 1e-6:
            raise ConfigError(
                f"a turn by radius needs a positive radius and a moving vehicle (speed {b.speed:.3f} m/s)",
                file=file,
                key=f"{key}.radius",
            )
        rate = abs(b.speed) / radius
    assert rate is not None
    if rate <= 0.0:
        raise ConfigError("expected a positive rate", file=file, key=f"{key}.rate")
    if rate > lim.max_rate + 1e-12:
        raise ConfigError(
            f"turn rate {math.degrees(rate):.3f} deg/s exceeds max_rate {math.degrees(lim.max_rate):.3f} deg/s",
            file=file,
            key=f"{key}.rate" if radius is None else f"{key}.radius",
        )
    dpsi = angle if direction == "right" else -angle
    roll_per_rate = b.speed / G0 if kind == "coordinated_turn" else None
    return b.heading_change(b.t, dpsi, rate, lim.angular_accel, roll_per_rate)


def _hill(
    b: _Builder, seg: Mapping[str, Any], kind: str, lim: Limits, duration: float | None, key: str, file: str | None
) -> float:
    angle = _opt(seg, "angle", "angle", "deg", key, file)
    if angle is None or not 0.0 < angle < math.radians(45.0):
        raise ConfigError("expected a grade angle between 0 and 45 deg", file=file, key=f"{key}.angle")
    if kind == "descend":
        angle = -angle
    t_ramp = SMOOTHSTEP_PEAK_SLOPE * abs(angle) / lim.pitch_rate
    height = _opt(seg, "height", "length", "m", key, file)
    if height is not None:
        if abs(b.speed) < 1e-6:
            raise ConfigError("a climb by height needs a moving vehicle", file=file, key=f"{key}.height")
        ramps = 2.0 * _ramp_height(b.speed, angle, t_ramp)
        dh = height if kind == "climb" else -height
        hold = (dh - ramps) / (b.speed * math.sin(angle))
        if hold < 0.0:
            raise ConfigError(
                f"height {height:g} m is less than the pitch ramps alone give ({abs(ramps):.2f} m)",
                file=file,
                key=f"{key}.height",
            )
    elif duration is not None:
        hold = duration - 2.0 * t_ramp
        if hold < 0.0:
            raise ConfigError(
                f"the pitch ramps need {2 * t_ramp:.3f} s, longer than the duration {duration:g} s",
                file=file,
                key=f"{key}.duration",
            )
    else:
        raise ConfigError("expected 'duration' or 'height'", file=file, key=f"{key}.duration")
    return b.pitch_hill(b.t, angle, lim.pitch_rate, hold)
