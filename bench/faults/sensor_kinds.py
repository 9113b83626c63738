"""Sensor-level fault kinds: their registration (layer ``"sensor"``) and their table.

Importing this module registers the kinds with :func:`bench.faults.schedule.register_kind`;
:mod:`bench.faults.sensor` applies them to the samples of each window.
"""

from __future__ import annotations

from bench.faults.schedule import ParamSpec, register_kind, registered_kinds

__all__ = [
    "ODOMETER_KINDS",
    "DOPPLER_KINDS",
    "BDS_KINDS",
    "IMU_KINDS",
    "MOTION_KINDS",
    "OUTAGE_STYLES",
    "register_sensor_kinds",
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
