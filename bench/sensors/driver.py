"""Driver input stream: what the DUT sees of the driver on the bus (ICD DRIVER_INPUT).

When the plant is driven by commands (FMU runs), ``traj.driver_input(t)`` gives them and
they are passed through. For scripted motion the commands are derived from the
kinematics, as a driver would have set them:

* wheeled vehicles: the steering angle of a bicycle model with wheelbase ``L`` on the
  path curvature, ``delta = atan(L kappa)``, ``kappa = -psi_dot / v`` (left positive),
  times ``steering_ratio``, clipped to ``max_steering`` and held below
  ``steer_min_speed``;
* tracked vehicles (seed 002): both levers most former (0) driving straight; turning with
  a radius below ``pivot_radius`` (turning in place, radius B/2), the inner lever in
  position II (2, locked); turning in a curve (radius 2.88 B), the inner lever in
  position I (1);
* both: the brake (0/1) when the vehicle must slow down harder than coasting does
  (``coast_decel``: rolling resistance and engine braking), counting the slope
  (``a + g sin(pitch)`` along the motion), and at rest.

Topic ``/<name>`` (``/driver``), one record per sample at ``rate`` (50 Hz).
"""

from __future__ import annotations

import numpy as np

from bench.nav.rotation import euler_to_dcm
from bench.scenario.trajectory import Trajectory
from bench.sensors.base import SensorModel
from bench.sensors.params import Param, Resolved
from bench.sensors.processes import period_ns, sample_times
from bench.topics import TopicSpec
from bench.units import G0

__all__ = ["DRIVER_PARAMS", "DRIVER_DTYPE", "DriverInput", "LEVER_MOST_FORMER", "LEVER_I", "LEVER_II"]

LEVER_MOST_FORMER, LEVER_I, LEVER_II = 0, 1, 2

DRIVER_PARAMS: dict[str, Param] = {
    "vehicle": Param("text", "", "wheeled", "vehicle type", choices=("wheeled", "tracked")),
    "rate": Param("frequency", "Hz", 50.0, "output rate", lo=1.0, hi=1000.0),
    "wheelbase": Param("length", "m", 3.0, "wheeled: wheelbase of the bicycle model", lo=0.1),
    "steering_ratio": Param("number", "", 1.0, "wheeled: output angle over road-wheel angle", lo=0.01),
    "max_steering": Param("angle", "deg", 35.0, "wheeled: largest road-wheel angle", lo=0.0),
    "steer_min_speed": Param("velocity", "m/s", 0.5, "wheeled: below this speed the steering is held", lo=0.0),
    "track_width": Param("length", "m", 2.8, "tracked: distance B between the track centres", lo=0.1),
    "turn_rate_threshold": Param("angular_rate", "deg/s", 1.0, "tracked: slower turns count as straight", lo=0.0),
    "pivot_radius": Param("length", "m", 0.0, "tracked: below this radius position II (0: 1.69 B)", lo=0.0),
    "coast_decel": Param("acceleration", "m/s^2", 0.3, "deceleration without the brake", lo=0.0),
    "rest_speed": Param("velocity", "m/s", 0.05, "below this speed (and not turning) the brake is held", lo=0.0),
}

DRIVER_DTYPE = np.dtype(
    [("t_ns", "<i8"), ("left_lever", "u1"), ("right_lever", "u1"), ("steering", "<f8"), ("brake", "u1")]
)
_UNITS = {
    "t_ns": "ns",
    "left_lever": "0 most former, 1 position I, 2 position II",
    "right_lever": "0 most former, 1 position I, 2 position II",
    "steering": "rad, left positive",
    "brake": "0/1",
}


class DriverInput(SensorModel):
    """Driver commands, from the plant or derived from the kinematics.

    Parameters
    ----------
    params:
        Resolved :data:`DRIVER_PARAMS` (SI).
    name:
        Instance name (topic ``/<name>``).
    """

    def __init__(self, params: Resolved, name: str = "driver"):
        self.name = name
        self.p = params
        self.period = period_ns(params["rate"])
        B = params["track_width"]
        self.pivot_radius = params["pivot_radius"] or 0.5 * (0.5 * B + 2.88 * B)
        self._last_steer = 0.0

    def topics(self) -> list[TopicSpec]:
        return [
            TopicSpec(
                f"/{self.name}",
                "bench.DriverInput",
                DRIVER_DTYPE,
                f"driver input ({self.p['vehicle']} vehicle), ICD DRIVER_INPUT fields in SI",
                _UNITS,
            )
        ]

    def run(self, traj: Trajectory, t0_ns: int, t1_ns: int) -> dict[str, np.ndarray]:
        t = sample_times(self.period, t0_ns, min(t1_ns, traj.duration_ns))
        n = len(t)
        if n == 0:
            return {}
        rec = np.zeros(n, dtype=DRIVER_DTYPE)
        rec["t_ns"] = t
        given = traj.driver_input(t * 1e-9)
        if given is not None:
            for key in ("left_lever", "right_lever", "steering", "brake"):
                if key in given:
                    rec[key] = given[key]
            return {f"/{self.name}": rec}
        p = self.p
        k = traj.kinematics(t * 1e-9)
        C = euler_to_dcm(k.euler[:, 0], k.euler[:, 1], k.euler[:, 2])
        v = np.einsum("ni,ni->n", C[:, :, 1], k.vel_n)  # forward speed
        a = np.einsum("ni,ni->n", C[:, :, 1], k.acc_n)  # forward acceleration
        r = k.euler_rate[:, 0]  # heading rate, right turn positive
        moving = np.abs(v) >= p["rest_speed"]
        turning = np.abs(r) >= p["turn_rate_threshold"]
        direction = np.where(v < 0.0, -1.0, 1.0)
        traction = direction * (a + G0 * np.sin(k.euler[:, 1]))
        rec["brake"] = ((moving & (traction < -p["coast_decel"])) | (~moving & ~turning)).astype(np.uint8)
        if p["vehicle"] == "wheeled":
            rec["steering"] = self._steering(v, r)
        else:
            radius = np.abs(v) / np.maximum(np.abs(r), 1e-12)
            inner = np.where(turning, np.where(radius < self.pivot_radius, LEVER_II, LEVER_I), LEVER_MOST_FORMER)
            right = r > 0.0
            rec["right_lever"] = np.where(right, inner, LEVER_MOST_FORMER)
            rec["left_lever"] = np.where(right, LEVER_MOST_FORMER, inner)
        return {f"/{self.name}": rec}

    def _steering(self, v: np.ndarray, r: np.ndarray) -> np.ndarray:
        p = self.p
        ok = np.abs(v) >= max(p["steer_min_speed"], 1e-6)
        kappa = np.where(ok, -r / np.where(ok, v, 1.0), 0.0)
        delta = np.clip(np.arctan(p["wheelbase"] * kappa), -p["max_steering"], p["max_steering"])
        delta = delta * p["steering_ratio"]
        # hold the last angle while too slow to steer by curvature
        idx = np.where(ok, np.arange(len(v)), -1)
        np.maximum.accumulate(idx, out=idx)
        held = np.where(idx >= 0, delta[np.maximum(idx, 0)], self._last_steer)
        self._last_steer = float(held[-1])
        return held
