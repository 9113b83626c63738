"""The SI quantities each ICD CAN message carries, and the DBC signals that carry them.

The codecs of :mod:`bench.wire.can` take and give these names; docs/wire.md lists them
with units. Kept apart from the codec machinery so the table reads at a glance.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Quantity", "QUANTITIES"]


@dataclass(frozen=True)
class Quantity:
    """An SI quantity of a message and the DBC signal(s) that carry it.

    ``kind``: ``"time_us"``/``"time_ms"`` (integer ns <-> integer us/ms, rounded to nearest),
    ``"float"`` (SI float, DBC unit converted: deg and arcmin to rad), ``"angle_wrap"``
    (float wrapped into [0, 360) deg before rounding), ``"int"`` (the raw integer),
    ``"int_wrap"`` (an integer taken modulo the field range: rolling counts), ``"bits"``
    (an integer bit mask spread over 1-bit signals, bit i to ``signals[i]``). A quantity
    with three ``float`` signals is a 3-vector, shape (N, 3).
    """

    name: str
    signals: tuple[str, ...]
    kind: str = "float"


def _q(name: str, *signals: str, kind: str = "float") -> Quantity:
    return Quantity(name, tuple(signals), kind)


#: The SI quantities of every message, by message name.
QUANTITIES: dict[str, tuple[Quantity, ...]] = {
    "BENCH_TIME": (
        _q("time_ns", "BenchTime", kind="time_us"),
        _q("lockstep", "Lockstep", kind="int"),
        _q("alive", "AliveCounter", kind="int"),
    ),
    "BENCH_EPOCH": (_q("epoch_utc_ns", "EpochUtc", kind="time_ms"), _q("alive", "AliveCounter", kind="int")),
    "BENCH_CMD": (_q("command", "Command", kind="int"), _q("alive", "AliveCounter", kind="int")),
    "ODOMETER": (
        _q("pulse_count", "PulseCount", kind="int_wrap"),
        _q("speed", "Speed"),
        _q("reverse", "Reverse", kind="int"),
        _q("valid", "Valid", kind="int"),
        _q("alive", "AliveCounter", kind="int"),
    ),
    "DRIVER_INPUT": (
        _q("left_lever", "LeftLever", kind="int"),
        _q("right_lever", "RightLever", kind="int"),
        _q("steering", "SteeringAngle"),
        _q("brake", "Brake", kind="int"),
        _q("alive", "AliveCounter", kind="int"),
    ),
    "DOPPLER": (
        _q("speed", "ForwardSpeed"),
        _q("quality", "SignalQuality", kind="int"),
        _q("valid", "Valid", kind="int"),
        _q("low_signal", "LowSignal", kind="int"),
        _q("alive", "AliveCounter", kind="int"),
    ),
    "NAV_SOLUTION": (
        _q("t_ns", "TimeOfValidity", kind="time_us"),
        _q("lat", "Latitude"),
        _q("lon", "Longitude"),
        _q("h", "Height"),
        _q("vel_n", "VelEast", "VelNorth", "VelUp"),
        _q("heading", "Heading", kind="angle_wrap"),
        _q("pitch", "Pitch"),
        _q("roll", "Roll"),
        _q("frame", "NavFrame", kind="int"),
        _q("mode", "Mode", kind="int"),
        _q("valid", "SolutionValid", kind="int"),
        _q("epoch", "EpochCounter", kind="int"),
    ),
    "NAV_QUALITY": (
        _q("t_ns", "TimeOfValidity", kind="time_us"),
        _q("sigma_pos", "SigmaPosEast", "SigmaPosNorth", "SigmaPosUp"),
        _q("sigma_vel", "SigmaVelEast", "SigmaVelNorth", "SigmaVelUp"),
        _q("sigma_att", "SigmaHeading", "SigmaPitch", "SigmaRoll"),
        _q("fault_detected", "FaultOdometer", "FaultDoppler", "FaultBds", "FaultImu", kind="bits"),
        _q("excluded", "ExcludedOdometer", "ExcludedDoppler", "ExcludedBds", "ExcludedImu", kind="bits"),
        _q("odo_fault_class", "OdoFaultClass", kind="int"),
        _q("epoch", "EpochCounter", kind="int"),
    ),
    "DUT_READY": (_q("time_ns", "ProcessedUpTo", kind="time_us"), _q("alive", "AliveCounter", kind="int")),
}
