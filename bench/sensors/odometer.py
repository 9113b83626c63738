"""Odometer: pulses from the driven wheel or track sprocket (seed 002).

The odometer measures its wheel, not the body. The wheel surface speed is
``traj.wheel_speed(t)`` when the plant models it (slip, idling, locked wheels); otherwise
the wheel rolls with the body: the velocity of its mounting point (``lever_arm`` from the
IMU) projected on its forward axis (``mounting_yaw``, ``mounting_pitch``, seed 002 eq. 9).
Odometer faults (:mod:`bench.faults.sensor`) then act on the wheel: idling adds speed the
body does not have, sliding takes it away, a bump spikes it, no output stops the pulses;
a sideslip moves the body sideways, which the wheel does not see.

The sensor turns the wheel's travel into pulses of ``pulse_equivalent`` metres with a
scale-factor error ``(1 + k + m(t))`` (``k`` constant, ``m`` first-order Gauss-Markov):
the wheel's travel over each interval (trapezoid on the samples), in pulses, is added to
the travel carried from before, and its whole part is the pulse count, one per pulse
whatever the direction (ICD ODOMETER); the fraction of a pulse carries on. The speed is
the wheel speed through the same scale factor plus white noise, forward positive;
``reverse`` is set while the wheel turns backwards.

Topic ``/<name>`` (``/odometer``), one record per sample at ``rate`` (100 Hz).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bench.faults.schedule import FaultWindow
from bench.faults.sensor import odometer_silenced, odometer_wheel_speed
from bench.rng import stream
from bench.scenario.trajectory import Trajectory
from bench.sensors.base import SensorModel
from bench.sensors.geometry import body_velocity, forward_axis
from bench.sensors.params import Param, Resolved
from bench.sensors.processes import GaussMarkov, WhiteNoise, period_ns, sample_times
from bench.topics import TopicSpec

__all__ = ["ODOMETER_PARAMS", "ODOMETER_DTYPE", "Odometer"]

ODOMETER_PARAMS: dict[str, Param] = {
    "rate": Param("frequency", "Hz", 100.0, "output rate", lo=1.0, hi=1000.0),
    "pulse_equivalent": Param("length", "m", 0.01, "wheel travel per pulse", lo=1e-6),
    "scale_factor": Param("dimensionless", "1", 0.0, "constant scale-factor error (0.02 = 2 %)"),
    "scale_factor_markov": Param("dimensionless", "%", 0.0, "sigma of a Gauss-Markov scale-factor error", lo=0.0),
    "scale_factor_tau": Param("time", "s", 600.0, "its correlation time", lo=1e-3),
    "lever_arm": Param("length", "m", 0.0, "wheel (contact point) position from the IMU, body frame", n=3),
    "mounting_yaw": Param("angle", "deg", 0.0, "yaw of the odometer frame from the body frame, towards the right"),
    "mounting_pitch": Param("angle", "deg", 0.0, "pitch of the odometer frame from the body frame, nose up"),
    "speed_noise": Param("velocity", "m/s", 0.0, "1-sigma white noise on the speed output", lo=0.0),
}

ODOMETER_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),
        ("pulses", "<i8"),
        ("speed", "<f8"),
        ("reverse", "u1"),
        ("valid", "u1"),
        ("wheel_speed", "<f8"),
        ("distance", "<f8"),
    ]
)
_UNITS = {
    "t_ns": "ns (time of validity)",
    "pulses": "cumulative pulse count (the wire wraps it to uint16)",
    "speed": "m/s, forward positive, as output",
    "reverse": "0/1",
    "valid": "0/1",
    "wheel_speed": "m/s, true wheel surface speed including slip faults (diagnostic)",
    "distance": "m, cumulative travel of the wheel surface |ds| (diagnostic)",
}


class Odometer(SensorModel):
    """Wheel or sprocket pulse odometer.

    Parameters
    ----------
    params:
        Resolved :data:`ODOMETER_PARAMS` (SI).
    seed:
        Run seed; streams ``(name, "scale_factor")`` and ``(name, "noise")``.
    name:
        Instance name (topic ``/<name>``).
    faults:
        Sensor-layer windows aimed at this odometer.
    """

    def __init__(self, params: Resolved, seed: int, name: str = "odometer", faults: Sequence[FaultWindow] = ()):
        self.name = name
        self.p = params
        self.period = period_ns(params["rate"])
        dt = self.period * 1e-9
        self.axis = forward_axis(params["mounting_yaw"], params["mounting_pitch"])
        self.lever = np.asarray(params["lever_arm"], dtype=float)
        self.q = float(params["pulse_equivalent"])
        self._sf = GaussMarkov(
            params["scale_factor_markov"], params["scale_factor_tau"], dt, stream(seed, name, "scale_factor")
        )
        self._noise = WhiteNoise(params["speed_noise"], stream(seed, name, "noise"))
        self.faults = list(faults)
        # carried state
        self._prev: tuple[int, float, float] | None = None  # t_ns, wheel speed, measured wheel speed
        self._travel = 0.0  # measured travel in pulses: its whole part is the count, the rest carries
        self._distance = 0.0

    def topics(self) -> list[TopicSpec]:
        return [
            TopicSpec(
                f"/{self.name}",
                "bench.Odometer",
                ODOMETER_DTYPE,
                f"odometer pulses and speed ({self.p.model_name}), ICD ODOMETER fields in SI",
                _UNITS,
            )
        ]

    def wheel_speed(self, traj: Trajectory, t_ns: np.ndarray) -> np.ndarray:
        """Wheel surface speed (m/s) before faults: the plant's, or the body's at the wheel."""
        v = traj.wheel_speed(t_ns * 1e-9)
        if v is not None:
            return np.asarray(v, dtype=float)
        return body_velocity(traj, t_ns, self.lever) @ self.axis

    def run(self, traj: Trajectory, t0_ns: int, t1_ns: int) -> dict[str, np.ndarray]:
        t = sample_times(self.period, t0_ns, min(t1_ns, traj.duration_ns))
        n = len(t)
        if n == 0:
            return {}
        if self._prev is None:
            t_start = np.array([0], dtype=np.int64)
            v_start = odometer_wheel_speed(self.faults, t_start, self.wheel_speed(traj, t_start))
            silent0, _ = odometer_silenced(self.faults, t_start)
            meas0 = 0.0 if silent0[0] else float(v_start[0])
            self._prev = (0, float(v_start[0]), meas0)
        wheel = odometer_wheel_speed(self.faults, t, self.wheel_speed(traj, t))
        silent, invalid = odometer_silenced(self.faults, t)
        sf = 1.0 + self.p["scale_factor"] + self._sf.draw(n)
        noise = self._noise.draw(n)
        measured = np.where(silent, 0.0, wheel)  # the wheel speed the pulse train follows
        t_prev, w_prev, m_prev = self._prev
        tt = np.concatenate([[t_prev], t]) * 1e-9
        dt = np.diff(tt)
        ww = np.concatenate([[w_prev], wheel])
        mm = np.concatenate([[m_prev], measured])
        ds_wheel = 0.5 * (ww[1:] + ww[:-1]) * dt
        ds_meas = 0.5 * (mm[1:] + mm[:-1]) * dt * sf
        # running sums continued from the carried totals, so that any cut of the run adds in
        # the same order; the pulse count is the whole part of the travel in pulses
        distance = np.cumsum(np.concatenate([[self._distance], np.abs(ds_wheel)]))[1:]
        cum = np.cumsum(np.concatenate([[self._travel], np.abs(ds_meas) / self.q]))[1:]
        pulses = np.floor(cum + 1e-9).astype(np.int64)  # exactly n pulses of travel count n
        self._travel = float(cum[-1])
        self._distance = float(distance[-1])
        self._prev = (int(t[-1]), float(wheel[-1]), float(measured[-1]))
        speed = np.where(silent, 0.0, sf * wheel + noise)
        rec = np.empty(n, dtype=ODOMETER_DTYPE)
        rec["t_ns"] = t
        rec["pulses"] = pulses
        rec["speed"] = speed
        rec["reverse"] = (measured < 0.0).astype(np.uint8)
        rec["valid"] = (~invalid).astype(np.uint8)
        rec["wheel_speed"] = wheel
        rec["distance"] = distance
        return {f"/{self.name}": rec}
