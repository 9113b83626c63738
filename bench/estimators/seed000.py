"""``seed000``: the SINS / Doppler-radar integrated position and orientation estimator of
seed 000, in its two integration modes.

The laser gyros serve two navigators: the SINS (the bench's strapdown mechanization) and
a dead-reckoning system (DRS: attitude from the same gyro increments by the rotation
vector, velocity as the Doppler forward speed along the direction of motion, position on
the ellipsoid; seed eq. 1-19). A 24-state error-state Kalman filter (the core 15 SINS
states, the DRS attitude and position errors, the Doppler scale factor as a first-order
Markov state and the two angles of the direction of motion in the body frame) compares
them once per ``update_period``:

``mode = "attitude_position"`` (default)
    SINS minus DRS attitude (the rotation vector of C_D C_S', equivalent to the heading,
    pitch and roll differences of eq. 44-51) and position.
``mode = "velocity_position"``
    SINS minus DRS velocity and position (eq. 52-55).

Every estimate is fed back (SINS attitude, velocity, position; DRS attitude and position;
gyro and accelerometer biases; Doppler scale factor; direction of motion) and the state
reset. Before navigating the estimator aligns at rest: an analytic coarse alignment over
``coarse_alignment``, then a Kalman fine alignment with zero-velocity and surveyed-position
measurements until ``alignment`` (300 s), whose heading converges to the gyrocompassing
limit (east gyro bias / (Earth rate cos latitude)). The Doppler ``valid`` bit is honoured:
without a valid sample for ``doppler_timeout`` the DRS is suspended (mode "inertial only",
NAV_QUALITY Doppler excluded) and restarted from the SINS when the radar returns; a
``low_signal`` sample counts with ``low_signal_noise_factor`` times the noise.

See docs/estimators.md for the configuration keys, the tuning and the error budget.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.config.table import check_keys
from bench.dut import MODE_ALIGNING, NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE, DutInputs, Estimator, EstimatorOutput
from bench.errors import ConfigError
from bench.estimators import seed000_kernel as K  # noqa: N812 - the kernel layout constants
from bench.estimators.rest_alignment import (
    AT_REST_KEYS,
    RestAlignment,
    core_covariance,
    standstill_parameters,
    standstill_switch,
)
from bench.estimators.settings import period_ns, surveyed_position
from bench.units import quantity

__all__ = ["Seed000", "CONFIG_KEYS"]

#: key -> (dimension, unit of a bare number, default); the defaults are the seed-000
#: sensors (SCENARIOS.md S000) and the filter settings of docs/estimators.md
CONFIG_KEYS: dict[str, tuple[str, str, float]] = {
    "gyro_bias": ("angular_rate", "deg/h", 0.01),
    "gyro_noise": ("angle_random_walk", "deg/sqrt(h)", 0.001),
    "accel_bias": ("acceleration", "ug", 100.0),
    "accel_noise": ("velocity_random_walk", "ug/sqrt(Hz)", 10.0),
    "doppler_noise": ("velocity", "m/s", 0.02),
    "doppler_rate": ("frequency", "Hz", 50.0),
    "doppler_scale_sigma": ("dimensionless", "%", 0.1),
    "doppler_scale_tau": ("time", "s", 300.0),
    "mounting_sigma": ("angle", "arcmin", 1.0),
    "low_signal_noise_factor": ("dimensionless", "1", 3.0),
    "doppler_timeout": ("time", "s", 0.1),
    "alignment": ("time", "s", 300.0),
    "coarse_alignment": ("time", "s", 10.0),
    "time_update_period": ("time", "s", 0.1),
    "update_period": ("time", "s", 1.0),
    "attitude_noise": ("angle", "arcsec", 2.0),
    "position_noise": ("length", "m", 0.05),
    "velocity_noise": ("velocity", "m/s", 0.005),
    "zupt_noise": ("velocity", "m/s", 0.001),
    "position_sigma": ("length", "m", 0.1),
    "output_rate": ("frequency", "Hz", 100.0),
    "gyro_bias_instability": ("angular_rate", "deg/h", 0.0),  # the coarse alignment's accuracy only
    "accel_bias_instability": ("acceleration", "ug", 0.0),
    **AT_REST_KEYS,
}
_OTHER_KEYS = ("initial_position", "mode", "gyro_noise_model", "standstill_zupt")
NOISE_MODELS = ("shared", "independent")
MODES = ("attitude_position", "velocity_position")
_EMPTY_I = np.zeros(0, np.int64)
_EMPTY_F = np.zeros(0)


class Seed000(Estimator):
    """SINS / Doppler-radar integrated estimator of seed 000 (module docstring)."""

    name = "seed000"

    def __init__(self) -> None:
        self.cfg: dict[str, float] = {k: quantity(v, d, u) for k, (d, u, v) in CONFIG_KEYS.items()}
        self.mode = 0
        self.position: tuple[float, float, float] | None = None
        self.st = np.zeros(K.ST_SIZE)
        self.P = np.zeros((K.N_STATES, K.N_STATES))
        self.prm = np.zeros(K.PRM_SIZE)
        self._rest = RestAlignment()
        self._out_ns = 10_000_000
        self._standstill = True

    # -- configuration -------------------------------------------------------------------
    def configure(self, config: Mapping[str, Any]) -> None:
        check_keys(config, [*CONFIG_KEYS, *_OTHER_KEYS], file=None, key="dut.config")
        for k, (dim, unit, default) in CONFIG_KEYS.items():
            v = quantity(config.get(k, default), dim, unit, key=f"dut.config.{k}")
            if v < 0:
                raise ConfigError(f"expected a non-negative value, found {config[k]!r}", key=f"dut.config.{k}")
            self.cfg[k] = float(v)
        mode = config.get("mode", MODES[0])
        if mode not in MODES:
            raise ConfigError(f"expected one of {MODES}, found {mode!r}", key="dut.config.mode")
        self.mode = MODES.index(mode)
        noise_model = config.get("gyro_noise_model", NOISE_MODELS[0])
        if noise_model not in NOISE_MODELS:
            raise ConfigError(
                f"expected one of {NOISE_MODELS}, found {noise_model!r}", key="dut.config.gyro_noise_model"
            )
        self.prm[K.P_SHARED] = 1.0 if noise_model == "shared" else 0.0
        self._standstill = standstill_switch(config)
        self.position = surveyed_position(config)
        c = self.cfg
        if c["coarse_alignment"] >= c["alignment"]:
            raise ConfigError("expected coarse_alignment shorter than alignment", key="dut.config.coarse_alignment")
        for k in ("doppler_rate", "doppler_scale_tau", "output_rate"):
            if c[k] <= 0:
                raise ConfigError("expected a positive value", key=f"dut.config.{k}")
        self._out_ns = period_ns(1.0 / c["output_rate"], "dut.config.output_rate")
        prm = self.prm
        prm[K.P_NG], prm[K.P_NA] = c["gyro_noise"], c["accel_noise"]
        prm[K.P_SD], prm[K.P_DRATE] = c["doppler_noise"], c["doppler_rate"]
        prm[K.P_SK], prm[K.P_TK] = c["doppler_scale_sigma"], c["doppler_scale_tau"]
        prm[K.P_TU] = c["time_update_period"]
        prm[K.P_MU] = period_ns(c["update_period"], "dut.config.update_period")
        prm[K.P_MODE] = self.mode
        prm[K.P_RATT], prm[K.P_RPOS], prm[K.P_RVEL] = c["attitude_noise"], c["position_noise"], c["velocity_noise"]
        prm[K.P_ZUPT], prm[K.P_RP0] = c["zupt_noise"], c["position_sigma"]
        prm[K.P_OUT] = self._out_ns
        prm[K.P_LOWF] = c["low_signal_noise_factor"]
        prm[K.P_DTIMEOUT] = c["doppler_timeout"] * 1e9
        prm[K.P_SMOUNT] = c["mounting_sigma"]
        prm[K.P_GB], prm[K.P_AB] = c["gyro_bias"], c["accel_bias"]
        prm[K.P_STILL : K.PRM_SIZE] = standstill_parameters(c, self._standstill)

    def warm_up(self) -> None:
        """Compile the step kernel for the argument types of a step (the decoder's DOPPLER
        columns, a multi-frame IMU slice), without running it."""
        from bench.estimators.jit import compile_for
        from bench.wire.imu import IMU_SAMPLE_DTYPE

        # two frames: field views as a multi-frame step's (not contiguous); one frame (or none): as a
        # step of an IMU at or below the step rate's (contiguous views, numba's other specialization)
        sol, qual = np.zeros(2, NAV_SOLUTION_DTYPE), np.zeros(2, NAV_QUALITY_DTYPE)
        for n in (2, 1):
            imu = np.zeros(n, IMU_SAMPLE_DTYPE)
            compile_for(K.run_step, self.st, self.P, self.prm, imu["dtheta"], imu["dvel"], imu["t_ns"], _EMPTY_I,
                        _EMPTY_F, _EMPTY_I, _EMPTY_I, sol, qual)

    # -- the step --------------------------------------------------------------------------
    def step(self, inputs: DutInputs) -> EstimatorOutput:
        imu = inputs.imu
        if self.position is None:
            raise ConfigError("the seed000 estimator needs dut.config.initial_position", key="dut.config")
        if self._rest.coarse:
            return self._coarse_step(inputs, imu)
        n = len(imu)
        d = inputs.doppler
        if len(d["rx_ns"]):
            d_t, d_v, d_ok, d_low = d["rx_ns"], d["speed"], d["valid"], d["low_signal"]
        else:
            d_t, d_v, d_ok, d_low = _EMPTY_I, _EMPTY_F, _EMPTY_I, _EMPTY_I
        sol = np.zeros(n, NAV_SOLUTION_DTYPE)
        qual = np.zeros(n, NAV_QUALITY_DTYPE)
        k = K.run_step(
            self.st, self.P, self.prm, imu["dtheta"], imu["dvel"], imu["t_ns"], d_t, d_v, d_ok, d_low, sol, qual
        )
        if k == 0:
            return EstimatorOutput()
        return EstimatorOutput(sol[:k], qual[:k])

    def _coarse_step(self, inputs: DutInputs, imu: np.ndarray) -> EstimatorOutput:
        """Sum the increments at rest; output "aligning" epochs at the surveyed position."""
        self._rest.add(imu)
        out = self._rest.epochs(inputs.t_ns, self._out_ns, self.position, self.cfg["position_sigma"])
        if self._rest.done(self.cfg["coarse_alignment"], self.cfg, self.position[0]):  # type: ignore[index]
            self._start_fine(self._rest.last_ns)
        return out

    def _start_fine(self, t_ns: int) -> None:
        """Coarse attitude from the sums, then the fine alignment's state and covariance."""
        c = self.cfg
        lat, lon, h = self.position  # type: ignore[misc]
        st = self.st
        st[K.S_SINS : K.S_SINS + 3] = lat, lon, h
        st[K.S_SINS + 6 : K.S_SINS + 10] = self._rest.attitude(lat)
        st[K.S_PHASE] = 1.0
        st[K.S_TLAST] = t_ns
        st[K.S_NEXT_OUT] = self._rest.next_out_ns
        st[K.S_ALIGN_END] = round(c["alignment"] * 1e9)
        st[K.S_P0 : K.S_P0 + 3] = lat, lon, h
        st[K.S_MODE] = MODE_ALIGNING
        st[K.S_TNOM] = self._rest.nominal_step_s()
        self.P[:, :] = core_covariance(K.N_STATES, c, t_ns * 1e-9, lat, self._rest.cov, self._rest.coarse_C_bn)
        self.prm[K.P_ZUPT] = self._rest.zupt_noise(c["zupt_noise"])
        self.prm[K.P_STILL : K.PRM_SIZE] = standstill_parameters(c, self._standstill, self._rest)
        self._rest.finish()

    @property
    def covariance(self) -> np.ndarray:
        """The filter's covariance (24, 24), a copy (states in bench.estimators.seed000_kernel)."""
        return self.P.copy()
