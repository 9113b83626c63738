"""Two small in-process DUTs that ship with the bench.

``decode_only``
    Decodes everything and navigates nothing: one NAV_SOLUTION (mode "aligning", not
    valid) per output period. It measures what the bench itself costs.

``dead_reckoning``
    The laser-gyro / Doppler-radar dead-reckoning system of seed 000: coarse alignment
    at rest from the first seconds of IMU data, then the attitude from the gyro
    increments (rotation vector with the coning correction and the navigation-frame
    rotation), the velocity as the Doppler ground speed (odometer speed when there is no
    radar) along the body's forward axis, and the position integrated on the ellipsoid.
    Unaided, so its errors grow with distance; it is the minimal real DUT of the bench's
    own tests and a baseline for the seed 000 estimators.

    Configuration (``[dut] config``): ``initial_position = [lat_deg, lon_deg, h_m]``
    (required: a surveyed start point), ``alignment = "60 s"`` (time at rest used for
    the coarse alignment), ``output_rate = "100 Hz"``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.dut import MODE_ALIGNING, MODE_DOPPLER, MODE_ODOMETER, SOLUTION_VALID
from bench.dut.estimator import DutInputs, Estimator, EstimatorOutput
from bench.errors import ConfigError
from bench.estimators._dr_kernel import propagate
from bench.estimators.settings import period_ns, surveyed_position
from bench.nav.alignment import coarse_align
from bench.nav.rotation import dcm_to_quat, quat_to_euler
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from bench.units import quantity

__all__ = ["DecodeOnly", "DeadReckoning"]

def _output_period(config: Mapping[str, Any]) -> int:
    rate = quantity(config.get("output_rate", 100.0), "frequency", "Hz", key="dut.config.output_rate")
    if not rate > 0:
        raise ConfigError(f"expected a positive output rate, found {rate:g} Hz", key="dut.config.output_rate")
    return period_ns(1.0 / rate, "dut.config.output_rate")


def _first_grid(inputs: DutInputs, period_ns: int) -> int:
    """The first output time of a DUT at its first step: the first grid time from the
    step's time or its first IMU frame's, whichever is earlier (a replay from a seek gets no
    epochs from before it)."""
    t = inputs.t_ns
    if len(inputs.imu):
        t = min(t, int(inputs.imu["t_ns"][0]))
    return -(-t // period_ns) * period_ns


class DecodeOnly(Estimator):
    """Reads everything, navigates nothing (see the module docstring)."""

    name = "decode_only"

    def __init__(self) -> None:
        self.period_ns = 10_000_000
        self.next_ns: int | None = None  # the first step's time: no epoch before it (a replay's seek)
        self.received = 0

    def configure(self, config: Mapping[str, Any]) -> None:
        self.period_ns = _output_period(config)

    def step(self, inputs: DutInputs) -> EstimatorOutput:
        self.received += inputs.count()
        if self.next_ns is None:
            self.next_ns = _first_grid(inputs, self.period_ns)
        if inputs.t_ns < self.next_ns:
            return EstimatorOutput()
        if inputs.t_ns < self.next_ns + self.period_ns:  # one epoch (the usual step): no arrays to build
            sol = np.zeros(1, NAV_SOLUTION_DTYPE)
            sol["t_ns"], sol["mode"] = self.next_ns, MODE_ALIGNING
            self.next_ns += self.period_ns
            return EstimatorOutput(sol)
        times = np.arange(self.next_ns, inputs.t_ns + 1, self.period_ns, dtype=np.int64)
        self.next_ns = int(times[-1]) + self.period_ns
        sol = np.zeros(len(times), NAV_SOLUTION_DTYPE)
        sol["t_ns"] = times
        sol["mode"] = MODE_ALIGNING
        return EstimatorOutput(sol)


class DeadReckoning(Estimator):
    """Gyro attitude plus Doppler (or odometer) speed (see the module docstring)."""

    name = "dead_reckoning"

    def __init__(self) -> None:
        self.period_ns = 10_000_000
        self.alignment_ns = 60_000_000_000
        self.position: tuple[float, float, float] | None = None
        self._sum_th = np.zeros(3)
        self._sum_dv = np.zeros(3)
        self._sum_t = 0.0
        self._last_imu_ns = 0
        self._state: np.ndarray | None = None  # lat, lon, h, q0..q3, prev dtheta (3), speed, distance
        self._speed = 0.0
        self._source = MODE_DOPPLER
        self._next_out: int | None = None  # the first step's time: no epoch before it (a replay's seek)

    def configure(self, config: Mapping[str, Any]) -> None:
        self.period_ns = _output_period(config)
        self.alignment_ns = round(
            quantity(config.get("alignment", 60.0), "time", "s", key="dut.config.alignment") * 1e9
        )
        self.position = surveyed_position(config)

    # -- speed aid ---------------------------------------------------------------------
    def _speed_samples(self, inputs: DutInputs) -> tuple[np.ndarray, np.ndarray]:
        """(times, speeds) of the aiding speed that arrived this step."""
        d = inputs.doppler
        if len(d.get("rx_ns", ())):
            ok = d["valid"] > 0
            self._source = MODE_DOPPLER
            return d["rx_ns"][ok], d["speed"][ok]
        o = inputs.odometer
        if len(o.get("rx_ns", ())):
            ok = o["valid"] > 0
            self._source = MODE_ODOMETER
            return o["rx_ns"][ok], o["speed"][ok]
        return np.zeros(0, np.int64), np.zeros(0)

    def step(self, inputs: DutInputs) -> EstimatorOutput:
        imu = inputs.imu
        t_sp, sp = self._speed_samples(inputs)
        if self._state is None:
            return self._align(inputs, imu)
        if len(imu) == 0:
            return EstimatorOutput()
        # zero-order hold of the latest aiding speed at each IMU frame's time
        speed = np.full(len(imu), self._speed)
        if len(sp):
            idx = np.searchsorted(t_sp, imu["t_ns"], side="right") - 1
            speed = np.where(idx >= 0, sp[np.clip(idx, 0, None)], self._speed)
            self._speed = float(sp[-1])
        dt = np.diff(np.concatenate([[self._last_imu_ns], imu["t_ns"]])) * 1e-9
        self._last_imu_ns = int(imu["t_ns"][-1])
        out = np.empty((len(imu), 8))
        propagate(self._state, np.ascontiguousarray(imu["dtheta"], dtype=float), dt, speed, out)
        return self._outputs(imu["t_ns"], out)

    def _align(self, inputs: DutInputs, imu: np.ndarray) -> EstimatorOutput:
        if self.position is None:
            raise ConfigError("the dead-reckoning DUT needs dut.config.initial_position", key="dut.config")
        if len(imu):
            self._sum_th += imu["dtheta"].sum(axis=0)
            self._sum_dv += imu["dvel"].sum(axis=0)
            self._sum_t += float((imu["t_ns"][-1] - self._last_imu_ns) * 1e-9)
            self._last_imu_ns = int(imu["t_ns"][-1])
        out = self._aligning_epochs(inputs)
        if self._last_imu_ns >= self.alignment_ns and self._sum_t > 0:
            lat, lon, h = self.position
            C = coarse_align(self._sum_dv / self._sum_t, self._sum_th / self._sum_t, lat)
            q = dcm_to_quat(C)
            self._state = np.array([lat, lon, h, *q, 0.0, 0.0, 0.0, 0.0, 0.0])
        return out

    def _aligning_epochs(self, inputs: DutInputs) -> EstimatorOutput:
        t_ns = inputs.t_ns
        if self._next_out is None:
            self._next_out = _first_grid(inputs, self.period_ns)
        if t_ns < self._next_out or self.position is None:
            return EstimatorOutput()
        times = np.arange(self._next_out, t_ns + 1, self.period_ns, dtype=np.int64)
        self._next_out = int(times[-1]) + self.period_ns
        sol = np.zeros(len(times), NAV_SOLUTION_DTYPE)
        sol["t_ns"] = times
        sol["lat"], sol["lon"], sol["h"] = self.position
        sol["mode"] = MODE_ALIGNING
        return EstimatorOutput(sol)

    def _outputs(self, t_ns: np.ndarray, states: np.ndarray) -> EstimatorOutput:
        """Epochs on the output grid, each from the IMU frame at that time."""
        pick = (t_ns >= (self._next_out or 0)) & (t_ns % self.period_ns == 0)
        if not pick.any():
            return EstimatorOutput()
        t = t_ns[pick]
        s = states[pick]
        self._next_out = int(t[-1]) + self.period_ns
        n = len(t)
        sol = np.zeros(n, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = t
        sol["lat"], sol["lon"], sol["h"] = s[:, 0], s[:, 1], s[:, 2]
        q = s[:, 3:7]
        psi, theta, gamma = quat_to_euler(q)
        sol["heading"], sol["pitch"], sol["roll"] = psi, theta, gamma
        sol["vel_n"] = s[:, 7:8] * np.stack(
            [np.sin(psi) * np.cos(theta), np.cos(psi) * np.cos(theta), np.sin(theta)], axis=-1
        )
        sol["mode"] = self._source
        sol["valid"] = SOLUTION_VALID
        qual = np.zeros(n, NAV_QUALITY_DTYPE)
        qual["t_ns"] = t
        dist = self._state[11] if self._state is not None else 0.0
        qual["sigma_pos"] = np.array([1.0, 1.0, 2.0]) + 2e-3 * dist  # 0.2 % of distance travelled
        qual["sigma_vel"] = 0.05
        qual["sigma_att"] = np.radians([1.0, 0.5, 0.5]) / 60.0
        return EstimatorOutput(sol, qual)
