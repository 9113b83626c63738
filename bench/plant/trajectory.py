"""The truth of an FMU-driven drive: a :class:`~bench.scenario.trajectory.Trajectory`.

The runner's kept samples (position, heading, pitch, roll every ``decimate`` steps) are
interpolated by quintic splines (:class:`~bench.scenario.track.SampledTrajectory`), so
velocity, acceleration and the attitude rates are analytic derivatives of one smooth
curve and the exact IMU synthesis applies unchanged. On top of the kinematics the plant
tells what the odometer sees (:meth:`wheel_speed`: sprocket or wheel surface speed with
slip and idling) and what the driver commanded (:meth:`driver_input`).
"""

from __future__ import annotations

import numpy as np

from bench.nav import earth
from bench.plant.driver import DriverScript
from bench.plant.runner import PlantRun
from bench.scenario.track import SampledTrajectory, Track
from bench.scenario.trajectory import SegmentInfo

__all__ = ["FmuTrajectory"]


class FmuTrajectory(SampledTrajectory):
    """Trajectory of a vehicle FMU driven by a command script.

    Parameters
    ----------
    run:
        The plant run (samples at a uniform grid starting at 0).
    script:
        The driver commands that drove it.
    segments:
        Flags for stretches of the drive (default: one per command).
    """

    def __init__(self, run: PlantRun, script: DriverScript, segments: list[SegmentInfo] | None = None):
        s = run.samples
        xyz = earth.geodetic_to_ecef(s["lat"], s["lon"], s["h"])
        euler = np.column_stack([s["psi"], s["theta"], s["gamma"]])
        super().__init__(Track(s["t"], xyz, euler, str(run.description.path)), segments=segments or script.segments())
        self.run = run
        self.script = script
        self._t = s["t"]
        self._odo = s.get("odometer_speed")

    def knots(self) -> np.ndarray:
        """The samples' times: breakpoints of the interpolating splines."""
        return self._t[1:-1]

    def wheel_speed(self, t: np.ndarray) -> np.ndarray | None:
        """Odometer wheel or sprocket surface speed (m/s) from the FMU, None if unmapped."""
        if self._odo is None:
            return None
        t = np.asarray(t, dtype=float)
        self.check_times(t)
        return np.interp(t, self._t, self._odo)

    def driver_input(self, t: np.ndarray) -> dict[str, np.ndarray] | None:
        """The commands the FMU was given (held at the command rate): levers as 0/1/2,
        steering (rad, left positive), brake and throttle pedals (0..1), grade and bank (rad)."""
        t = np.asarray(t, dtype=float)
        self.check_times(t)
        out = {c: self.script.held(c, t) for c in ("left_lever", "right_lever", "steering", "brake", "throttle")}
        for c in ("left_lever", "right_lever"):
            out[c] = out[c].astype(np.int8)
        return out
