"""``seed002``: the SINS/odometer fault-tolerant estimator of seed 002 (tracked vehicle).

An 18-state closed-loop error-state Kalman filter on the bench's SINS (the core 15 states
and the odometer's yaw mounting, scale factor and pitch mounting errors, seed eq. 10; the
kernel in :mod:`bench.estimators.seed002_kernel`):

- the displacement-increment measurement in the body frame (eq. 9-17): every
  ``odometer_period`` the SINS travel of the odometer point in the body frame minus the
  odometer's travel (its pulses) put into the body frame through the mounting angles;
- the tracked-vehicle constraints by the lever positions of DRIVER_INPUT (eq. 1-8):
  straight at high speed (the odometer reads the travel), straight at low speed (1.42:1),
  turning in place (the odometer abandoned: pure inertial until the turn ends), turning in
  curve (lateral travel ``L * integral(w_z)``, forward ``0.8521 s_D + 0.2048 integral(|w_z|)``),
  parked (no travel). For ``lever_settle`` after a lever moves (the steering mechanisms
  engage, the yaw and the skid follow) the odometer is not used;
- the two-layer residual chi-square test of section 5.3 before each update (eq. 18-20):
  the whole measurement; when it fails, the lateral and vertical rows alone (the
  kinematic constraint, the odometer's travel excluded: class 1, longitudinal); when
  that fails too, pure inertial (class 2 lateral or 3 vertical, by the larger normalised
  residual). Thresholds: chi-square quantiles at ``false_alarm`` probability;
- NAV_QUALITY bytes 26-28: odometer fault detected, odometer excluded, fault class;
- alignment at rest: analytic coarse alignment, then the fine alignment (zero velocity and
  the surveyed position) until ``alignment``.

Variants by configuration: ``detection = "two_layer"`` (default), ``"single_layer"``
(the whole-measurement test only: a failing period is pure inertial), ``"none"`` (every
measurement applied, the paper's red curve), ``constraints = false`` (the odometer read
as straight running at 1:1 whatever the levers). Keys and defaults: docs/estimators.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.config.table import check_keys
from bench.dut import MODE_ALIGNING, NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE, DutInputs, Estimator, EstimatorOutput
from bench.dut.estimator import CanView
from bench.errors import ConfigError
from bench.estimators import seed002_kernel as K  # noqa: N812 - the kernel layout constants
from bench.estimators.outblocks import OutputBlocks
from bench.estimators.rest_alignment import (
    AT_REST_KEYS,
    RestAlignment,
    core_covariance,
    standstill_parameters,
    standstill_switch,
)
from bench.estimators.settings import period_ns, surveyed_position, vectors
from bench.units import quantity

__all__ = ["Seed002", "CONFIG_KEYS", "VECTOR_KEYS", "DETECTION"]

#: key -> (dimension, unit of a bare number, default)
CONFIG_KEYS: dict[str, tuple[str, str, float]] = {
    "gyro_bias": ("angular_rate", "deg/h", 0.02),
    "gyro_noise": ("angle_random_walk", "deg/sqrt(h)", 0.02),
    "accel_bias": ("acceleration", "ug", 100.0),
    "accel_noise": ("velocity_random_walk", "ug/sqrt(Hz)", 50.0),
    "gyro_bias_instability": ("angular_rate", "deg/h", 0.0),
    "accel_bias_instability": ("acceleration", "ug", 0.0),
    "bias_instability_tau": ("time", "s", 500.0),
    "alignment": ("time", "s", 170.0),
    "coarse_alignment": ("time", "s", 10.0),
    "time_update_period": ("time", "s", 0.1),
    "output_rate": ("frequency", "Hz", 100.0),
    "zupt_noise": ("velocity", "m/s", 0.001),
    "position_sigma": ("length", "m", 0.1),
    "odometer_period": ("time", "s", 0.1),
    "pulse_equivalent": ("length", "m", 0.02),
    "odometer_latency": ("time", "s", 0.0),
    "false_alarm": ("dimensionless", "1", 1e-6),
    "low_speed_ratio": ("dimensionless", "1", 1.42),
    "curve_speed_gain": ("dimensionless", "1", 0.8521),
    "curve_rate_gain": ("length", "m", 0.2048),
    "lateral_length": ("length", "m", 0.5),
    "lever_settle": ("time", "s", 2.0),
    "curve_noise": ("velocity", "m/s", 0.05),
    "standing_travel": ("length", "m", 0.05),
    "scale_factor_sigma": ("dimensionless", "%", 3.0),
    "mounting_sigma": ("angle", "deg", 1.0),
    "scale_factor_walk": ("dimensionless", "1", 1e-6),
    "mounting_walk": ("angle", "deg", 1e-5),
    **AT_REST_KEYS,
}
#: key -> (dimension, unit of a bare number, default (3,)); body RFU
VECTOR_KEYS: dict[str, tuple[str, str, tuple[float, float, float]]] = {
    "odometer_lever_arm": ("length", "m", (0.0, 0.0, 0.0)),
    "odometer_noise": ("velocity", "m/s", (0.03, 0.02, 0.03)),
}
#: detection setting -> kernel code
DETECTION = {"none": 0.0, "single_layer": 1.0, "two_layer": 2.0}
_OTHER_KEYS = ("initial_position", "detection", "constraints", "log_diagnostics", "standstill_zupt")
_EMPTY_I = np.zeros(0, np.int64)
_NO_ODO = [_EMPTY_I, _EMPTY_I, _EMPTY_I, _EMPTY_I]
_NO_DRV = [_EMPTY_I, _EMPTY_I, _EMPTY_I]
_ODO_COLUMNS = ("rx_ns", "pulse_count", "reverse", "valid")
_DRV_COLUMNS = ("rx_ns", "left_lever", "right_lever")


def _int_columns(can: Mapping[str, Any], name: str, keys: tuple[str, ...]) -> list[np.ndarray] | None:
    """The columns ``keys`` of CAN message ``name`` in this step as contiguous int64 arrays
    (the bench's decoder gives them so: :meth:`Seed002.step` takes them from its
    :class:`CanView` as they are); None when none arrived."""
    msg = can.get(name)
    if msg is None or not len(msg[keys[0]]):
        return None
    return [np.ascontiguousarray(msg[k], dtype=np.int64) for k in keys]


class Seed002(Estimator):
    """SINS/odometer fault-tolerant navigation of seed 002 (module docstring)."""

    name = "seed002"

    def __init__(self) -> None:
        self.cfg: dict[str, float] = {k: quantity(v, d, u) for k, (d, u, v) in CONFIG_KEYS.items()}
        self.detection = "two_layer"
        self.constraints = True
        self.log_diagnostics = False
        self.position: tuple[float, float, float] | None = None
        self.st = np.zeros(K.ST_SIZE)
        self.P = np.zeros((K.N_STATES, K.N_STATES))
        self.prm = np.zeros(K.PRM_SIZE)
        self._rest = RestAlignment()
        self._out_ns = 10_000_000
        self._standstill = True
        self._odo = _NO_ODO  # samples waiting for the IMU: rx_ns, pulses, reverse, valid (int64 columns)
        self._out = OutputBlocks()
        self.st[K.S_PULSE] = -1.0
        self.st[K.S_LL] = self.st[K.S_LR] = -1.0
        self.st[K.S_PMODEL] = K.M_UNKNOWN

    # -- configuration -------------------------------------------------------------------
    def configure(self, config: Mapping[str, Any]) -> None:
        check_keys(config, [*CONFIG_KEYS, *VECTOR_KEYS, *_OTHER_KEYS], file=None, key="dut.config")
        for k, (dim, unit, default) in CONFIG_KEYS.items():
            v = quantity(config.get(k, default), dim, unit, key=f"dut.config.{k}")
            if v < 0:
                raise ConfigError(f"expected a non-negative value, found {config[k]!r}", key=f"dut.config.{k}")
            self.cfg[k] = float(v)
        det = config.get("detection", "two_layer")
        if det not in DETECTION:
            raise ConfigError(f"expected one of {', '.join(DETECTION)}, found {det!r}", key="dut.config.detection")
        self.detection = det
        for key in ("constraints", "log_diagnostics"):
            v = config.get(key, key == "constraints")
            if not isinstance(v, bool):
                raise ConfigError(f"expected true or false, found {v!r}", key=f"dut.config.{key}")
            setattr(self, key, v)
        vec = vectors(config, VECTOR_KEYS, "right, forward, up")
        self.position = surveyed_position(config)
        c = self.cfg
        if c["coarse_alignment"] >= c["alignment"]:
            raise ConfigError("expected coarse_alignment shorter than alignment", key="dut.config.coarse_alignment")
        for k in ("output_rate", "odometer_period", "time_update_period", "pulse_equivalent", "low_speed_ratio"):
            if c[k] <= 0:
                raise ConfigError("expected a positive value", key=f"dut.config.{k}")
        if not 0.0 < c["false_alarm"] < 1.0:
            raise ConfigError(f"expected a probability in (0, 1), found {c['false_alarm']!r}",
                              key="dut.config.false_alarm")
        self._out_ns = period_ns(1.0 / c["output_rate"], "dut.config.output_rate")
        from scipy.stats import chi2

        p = self.prm
        p[K.P_NG], p[K.P_NA], p[K.P_GB], p[K.P_AB] = c["gyro_noise"], c["accel_noise"], c["gyro_bias"], c["accel_bias"]
        tb = max(c["bias_instability_tau"], 1e-3)
        p[K.P_QG] = c["gyro_bias_instability"] * math.sqrt(2.0 / tb)
        p[K.P_QA] = c["accel_bias_instability"] * math.sqrt(2.0 / tb)
        p[K.P_TU], p[K.P_OUT], p[K.P_ZUPT], p[K.P_RP0] = c["time_update_period"], self._out_ns, c["zupt_noise"], \
            c["position_sigma"]
        p[K.P_PER] = period_ns(c["odometer_period"], "dut.config.odometer_period")
        p[K.P_PEQ] = c["pulse_equivalent"]
        p[K.P_DET] = DETECTION[self.detection]
        p[K.P_CON] = 1.0 if self.constraints else 0.0
        p[K.P_G3], p[K.P_G2] = chi2.isf(c["false_alarm"], 3), chi2.isf(c["false_alarm"], 2)
        p[K.P_RATIO], p[K.P_GV], p[K.P_GR] = c["low_speed_ratio"], c["curve_speed_gain"], c["curve_rate_gain"]
        p[K.P_LLAT], p[K.P_SETTLE], p[K.P_RCURVE] = c["lateral_length"], c["lever_settle"], c["curve_noise"]
        p[K.P_RN : K.P_RN + 3] = vec["odometer_noise"]
        p[K.P_OL : K.P_OL + 3] = vec["odometer_lever_arm"]
        p[K.P_KQ], p[K.P_AQ] = c["scale_factor_walk"], c["mounting_walk"]
        p[K.P_MOVE] = c["standing_travel"]
        p[K.P_OGAP] = 2.5e7  # 25 ms: more than one 10 ms sample missing
        p[K.P_LAT] = round(c["odometer_latency"] * 1e9)
        self._standstill = standstill_switch(config)
        p[K.P_STILL : K.PRM_SIZE] = standstill_parameters(c, self._standstill)

    # -- what the MC scripts read ------------------------------------------------------------
    @property
    def odometer_errors(self) -> tuple[np.ndarray, np.ndarray]:
        """(estimate, 1-sigma) of the odometer's yaw mounting (rad), scale factor and pitch
        mounting (rad) compensated."""
        d = np.sqrt(np.maximum(np.diag(self.P)[K.D_YAW : K.D_PITCH + 1], 0.0))
        return self.st[K.S_OD : K.S_OD + 3].copy(), d

    def diagnostics(self) -> dict[str, float]:
        """Counters and estimates beyond NAV_QUALITY."""
        st = self.st
        return {"odometer_yaw_deg": math.degrees(st[K.S_OD]), "odometer_scale": float(st[K.S_OD + 1]),
                "odometer_pitch_deg": math.degrees(st[K.S_OD + 2]), "updates": int(st[K.S_NUPD]),
                "layer1_rejected": int(st[K.S_NL1]), "layer2_rejected": int(st[K.S_NL2]),
                "turning_in_place": int(st[K.S_NPIV]), "last_statistic": float(st[K.S_NIS])}

    def close(self) -> None:
        """With ``log_diagnostics``: one line on stderr (the DUT log through the harness)."""
        if self.log_diagnostics:
            import json
            import sys

            print(f"seed002 diagnostics: {json.dumps(self.diagnostics())}", file=sys.stderr, flush=True)

    @property
    def covariance(self) -> np.ndarray:
        """The filter's covariance (18, 18), a copy."""
        return self.P.copy()

    def warm_up(self) -> None:
        """Compile the step kernel for the argument types of a step, without running it."""
        from bench.estimators.jit import compile_for
        from bench.wire.imu import IMU_SAMPLE_DTYPE

        # two frames: field views as a multi-frame step's (not contiguous); one frame (or none): as a
        # step of an IMU at or below the step rate's (contiguous views, numba's other specialization)
        for n in (2, 1):
            imu = np.zeros(n, IMU_SAMPLE_DTYPE)
            compile_for(K.run_step, self.st, self.P, self.prm, imu["dtheta"], imu["dvel"], imu["t_ns"],
                        _EMPTY_I, _EMPTY_I, _EMPTY_I, _EMPTY_I, _EMPTY_I, _EMPTY_I, _EMPTY_I,
                        np.zeros(2, NAV_SOLUTION_DTYPE), np.zeros(2, NAV_QUALITY_DTYPE))

    # -- the step --------------------------------------------------------------------------
    def step(self, inputs: DutInputs) -> EstimatorOutput:
        if self.position is None:
            raise ConfigError("the seed002 estimator needs dut.config.initial_position", key="dut.config")
        can = inputs.can
        if type(can) is CanView:  # the bench's: the columns as they are, without the message's dict
            new = can.columns("ODOMETER", _ODO_COLUMNS)
            drv = can.columns("DRIVER_INPUT", _DRV_COLUMNS)
            if new is not None and not len(new[0]):
                new = None
            if drv is None or not len(drv[0]):
                drv = _NO_DRV
        else:
            new = _int_columns(can, "ODOMETER", _ODO_COLUMNS)
            drv = _int_columns(can, "DRIVER_INPUT", _DRV_COLUMNS) or _NO_DRV
        if new is not None:
            old = self._odo
            self._odo = new if not len(old[0]) else [np.concatenate(ab) for ab in zip(old, new, strict=True)]
        d_t, d_l, d_r = drv
        imu = inputs.imu
        if self._rest.coarse:
            return self._coarse_step(inputs, imu, d_t, d_l, d_r)
        o_t, o_p, o_r, o_ok = odo = self._odo
        sol, qual = self._out.take(len(imu))
        k = K.run_step(self.st, self.P, self.prm, imu["dtheta"], imu["dvel"], imu["t_ns"], o_t, o_p, o_r, o_ok,
                       d_t, d_l, d_r, sol, qual)
        used = int(self.st[K.S_OCONS])
        if used:
            self._odo = _NO_ODO if used == len(o_t) else [c[used:] for c in odo]
        if k == 0:
            return EstimatorOutput()
        return EstimatorOutput(sol[:k], qual[:k])


    def _coarse_step(self, inputs: DutInputs, imu: np.ndarray, d_t: np.ndarray, d_l: np.ndarray,
                     d_r: np.ndarray) -> EstimatorOutput:
        """Sum the increments at rest; output "aligning" epochs at the surveyed position.
        The levers and the pulse count are followed meanwhile."""
        st = self.st
        for t, left, right in zip(d_t.tolist(), d_l.tolist(), d_r.tolist(), strict=True):
            if left != st[K.S_LL] or right != st[K.S_LR]:
                st[K.S_LL], st[K.S_LR], st[K.S_LT] = left, right, t
        if len(self._odo[0]):
            st[K.S_PULSE] = float(self._odo[1][-1])
            st[K.S_OT] = float(self._odo[0][-1])
            self._odo = _NO_ODO
        self._rest.add(imu)
        out = self._rest.epochs(inputs.t_ns, self._out_ns, self.position, self.cfg["position_sigma"])
        if self._rest.done(self.cfg["coarse_alignment"], self.cfg, self.position[0]):  # type: ignore[index]
            self._start_fine(self._rest.last_ns)
        return out

    def _start_fine(self, t_ns: int) -> None:
        c = self.cfg
        lat, lon, h = self.position  # type: ignore[misc]
        st = self.st
        st[K.S_SINS : K.S_SINS + 3] = lat, lon, h
        st[K.S_SINS + 6 : K.S_SINS + 10] = self._rest.attitude(lat)
        st[K.S_PHASE], st[K.S_TLAST], st[K.S_NEXT_OUT] = 1.0, t_ns, self._rest.next_out_ns
        st[K.S_ALIGN_END] = round(c["alignment"] * 1e9)
        st[K.S_P0 : K.S_P0 + 3] = lat, lon, h
        st[K.S_MODE] = MODE_ALIGNING
        st[K.S_LASTUPD] = -1e18
        st[K.S_TNOM] = self._rest.nominal_step_s()
        P = core_covariance(K.N_STATES, c, t_ns * 1e-9, lat, self._rest.cov, self._rest.coarse_C_bn)
        P[K.D_YAW, K.D_YAW] = P[K.D_PITCH, K.D_PITCH] = c["mounting_sigma"] ** 2
        P[K.D_K, K.D_K] = c["scale_factor_sigma"] ** 2
        self.P[:, :] = P
        self.prm[K.P_ZUPT] = self._rest.zupt_noise(c["zupt_noise"])
        self.prm[K.P_STILL : K.PRM_SIZE] = standstill_parameters(c, self._standstill, self._rest)
        self._rest.finish()
