"""``seed003``: the SINS estimator of seed 003 that navigates in the geographic frame at low
latitude and in the polar grid frame at high latitude, and switches between them.

A 15-state closed-loop error-state Kalman filter (:mod:`bench.estimators.seed003_kernel`):

- mechanization and error model in the geographic frame g (ENU, seed eq. 9-13) or in the
  grid frame G with the ECEF position (eq. 18-22);
- the switch at ``switch_latitude`` (88 deg) with ``switch_hysteresis`` on the way back,
  or on BENCH_CMD (1 grid, 2 geographic; a command latches the frame, 3 restarts the
  filter's navigation covariance); the navigation parameters converted (eq. 23, 26-27) and
  the filter's covariance converted (eq. 28-38) with ``filter_conversion = true``, or
  restarted in the new frame from the initial sigmas with ``false`` (the paper's
  comparison; ``unconverted = "copy"`` keeps the matrix unconverted instead);
- aids, as SCENARIOS.md S003 has them: the BDS fix's position (for the paper's celestial
  position and barometric altitude, sigmas from GST), and the Doppler forward speed with
  the non-holonomic constraint as a body-frame velocity (for the paper's spectral
  red-shift velocity);
- start at rest (analytic coarse alignment, then the fine alignment, ``start = "rest"``) or
  moving, from a given state (``start = "moving"``: ``initial_velocity`` and
  ``initial_attitude``, as the paper's simulation starts); a moving start beyond the switch
  latitude starts in the grid frame.

The output is geographic whatever the frame (ICD 2.2), byte 44 giving the frame. Keys,
defaults and the variants: docs/estimators.md, ``seed003``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.config.table import check_keys
from bench.dut import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE, DutInputs, Estimator, EstimatorOutput
from bench.dut.estimator import CanView
from bench.errors import ConfigError
from bench.estimators import seed003_kernel as K  # noqa: N812 - the compiled step
from bench.estimators import seed003_state as L  # noqa: N812 - the layouts of its state
from bench.estimators.fixes import FIX_COLS, take_fixes
from bench.estimators.outblocks import OutputBlocks
from bench.estimators.rest_alignment import (
    AT_REST_KEYS,
    RestAlignment,
    core_covariance,
    standstill_parameters,
    standstill_switch,
)
from bench.estimators.settings import period_ns, surveyed_position, vectors
from bench.nav.ecef import from_geographic
from bench.nav.rotation import euler_to_quat
from bench.units import quantity

__all__ = ["Seed003", "CONFIG_KEYS", "VECTOR_KEYS"]

#: key -> (dimension, unit of a bare number, default)
CONFIG_KEYS: dict[str, tuple[str, str, float]] = {
    "gyro_bias": ("angular_rate", "deg/h", 0.01),
    "gyro_noise": ("angle_random_walk", "deg/sqrt(h)", 0.001),
    "accel_bias": ("acceleration", "ug", 100.0),
    "accel_noise": ("velocity_random_walk", "ug/sqrt(Hz)", 10.0),
    "gyro_bias_instability": ("angular_rate", "deg/h", 0.0),
    "accel_bias_instability": ("acceleration", "ug", 0.0),
    "bias_instability_tau": ("time", "s", 500.0),
    "alignment": ("time", "s", 25.0),
    "coarse_alignment": ("time", "s", 10.0),
    "time_update_period": ("time", "s", 0.1),
    "output_rate": ("frequency", "Hz", 100.0),
    "zupt_noise": ("velocity", "m/s", 0.001),
    "position_sigma": ("length", "m", 0.1),
    "switch_latitude": ("angle", "deg", 88.0),
    "switch_hysteresis": ("angle", "deg", 0.05),
    "geographic_limit": ("angle", "deg", 89.5),
    "doppler_noise": ("velocity", "m/s", 0.5),
    "nhc_noise": ("velocity", "m/s", 0.5),
    "velocity_update_period": ("time", "s", 1.0),
    "doppler_timeout": ("time", "s", 0.1),
    "position_gate": ("dimensionless", "1", 0.9999),
    "position_noise_floor": ("length", "m", 1.0),
    "aiding_timeout": ("time", "s", 2.0),
    "initial_level_sigma": ("angle", "arcmin", 1.0),
    "initial_heading_sigma": ("angle", "arcmin", 5.0),
    "initial_velocity_sigma": ("velocity", "m/s", 0.1),
    "initial_position_sigma": ("length", "m", 10.0),
    **AT_REST_KEYS,
}
#: key -> (dimension, unit of a bare number, default (3,))
VECTOR_KEYS: dict[str, tuple[str, str, tuple[float, float, float]]] = {
    "initial_velocity": ("velocity", "m/s", (0.0, 0.0, 0.0)),  # E, N, U
    "initial_attitude": ("angle", "deg", (0.0, 0.0, 0.0)),  # heading, pitch, roll
}
_SWITCHES = {"filter_conversion": True, "auto_switch": True, "velocity_aid": True, "log_diagnostics": False}
_CHOICES = {"start": ("rest", "moving"), "unconverted": ("restart", "copy")}
_OTHER_KEYS = ("initial_position", "standstill_zupt")
_EMPTY_I = np.zeros(0, np.int64)
_EMPTY_F = np.zeros(0)
_DOP_COLUMNS = ("rx_ns", "speed", "valid")


class Seed003(Estimator):
    """Geographic / grid-frame SINS of seed 003 (module docstring)."""

    name = "seed003"

    def __init__(self) -> None:
        self.cfg: dict[str, float] = {k: quantity(v, d, u) for k, (d, u, v) in CONFIG_KEYS.items()}
        self.switch = dict(_SWITCHES)
        self.choice = {k: v[0] for k, v in _CHOICES.items()}
        self.vec = {k: np.array(v[2], dtype=float) for k, v in VECTOR_KEYS.items()}
        self.position: tuple[float, float, float] | None = None
        self.st = np.zeros(L.ST_SIZE)
        self.P = np.zeros((L.N_STATES, L.N_STATES))
        self.prm = np.zeros(L.PRM_SIZE)
        self._fixes = np.zeros((0, FIX_COLS))
        self._cmd_t = _EMPTY_I
        self._cmd_code = _EMPTY_I
        self._rest = RestAlignment()
        self._started = False
        self._held: np.ndarray | None = None  # a moving start's first frame until a second one comes
        self._out_ns = 10_000_000
        self._standstill = True
        self._out = OutputBlocks()

    # -- configuration -------------------------------------------------------------------
    def configure(self, config: Mapping[str, Any]) -> None:
        check_keys(config, [*CONFIG_KEYS, *VECTOR_KEYS, *_SWITCHES, *_CHOICES, *_OTHER_KEYS], file=None,
                   key="dut.config")
        for k, (dim, unit, default) in CONFIG_KEYS.items():
            v = quantity(config.get(k, default), dim, unit, key=f"dut.config.{k}")
            if v < 0:
                raise ConfigError(f"expected a non-negative value, found {config[k]!r}", key=f"dut.config.{k}")
            self.cfg[k] = float(v)
        for k in _SWITCHES:
            v = config.get(k, _SWITCHES[k])
            if not isinstance(v, bool):
                raise ConfigError(f"expected true or false, found {v!r}", key=f"dut.config.{k}")
            self.switch[k] = v
        for k, allowed in _CHOICES.items():
            v = config.get(k, allowed[0])
            if v not in allowed:
                raise ConfigError(f"expected one of {', '.join(map(repr, allowed))}, found {v!r}",
                                  key=f"dut.config.{k}")
            self.choice[k] = v
        self.vec = vectors(config, VECTOR_KEYS)
        self.position = surveyed_position(config)
        c = self.cfg
        if c["coarse_alignment"] >= c["alignment"]:
            raise ConfigError("expected coarse_alignment shorter than alignment", key="dut.config.coarse_alignment")
        for k in ("output_rate", "time_update_period", "velocity_update_period", "doppler_noise", "nhc_noise"):
            if c[k] <= 0:
                raise ConfigError("expected a positive value", key=f"dut.config.{k}")
        if not math.radians(45.0) <= c["switch_latitude"] < math.radians(90.0):
            raise ConfigError("expected a switch latitude in [45, 90) deg", key="dut.config.switch_latitude")
        if not c["switch_latitude"] < c["geographic_limit"] <= math.radians(90.0):
            raise ConfigError("expected a geographic limit between the switch latitude and 90 deg",
                              key="dut.config.geographic_limit")
        if not 0.0 < c["position_gate"] <= 1.0:
            raise ConfigError(f"expected a probability in (0, 1], found {c['position_gate']!r}",
                              key="dut.config.position_gate")
        self._out_ns = period_ns(1.0 / c["output_rate"], "dut.config.output_rate")
        from scipy.stats import chi2

        p = self.prm
        p[L.P_NG], p[L.P_NA] = c["gyro_noise"], c["accel_noise"]
        tb = max(c["bias_instability_tau"], 1e-3)
        p[L.P_QG] = c["gyro_bias_instability"] * math.sqrt(2.0 / tb)
        p[L.P_QA] = c["accel_bias_instability"] * math.sqrt(2.0 / tb)
        p[L.P_TU], p[L.P_OUT], p[L.P_ZUPT], p[L.P_RP0] = c["time_update_period"], self._out_ns, c["zupt_noise"], \
            c["position_sigma"]
        p[L.P_SWLAT], p[L.P_HYST], p[L.P_GLIM] = c["switch_latitude"], c["switch_hysteresis"], c["geographic_limit"]
        p[L.P_AUTO] = 1.0 if self.switch["auto_switch"] else 0.0
        p[L.P_CONV] = 1.0 if self.switch["filter_conversion"] else (0.0 if self.choice["unconverted"] == "restart"
                                                                     else 2.0)
        p[L.P_RDOP], p[L.P_RNHC] = c["doppler_noise"], c["nhc_noise"]
        p[L.P_VELPER] = period_ns(c["velocity_update_period"], "dut.config.velocity_update_period")
        p[L.P_DOPTO] = c["doppler_timeout"] * 1e9
        p[L.P_GATE] = chi2.ppf(c["position_gate"], 3) if c["position_gate"] < 1.0 else 0.0
        p[L.P_AGE], p[L.P_RPOS] = c["aiding_timeout"] * 1e9, c["position_noise_floor"]
        lvl, hdg = c["initial_level_sigma"], c["initial_heading_sigma"]
        p[L.P_S0 : L.P_S0 + 9] = [lvl, lvl, hdg, *([c["initial_velocity_sigma"]] * 3),
                                  *([c["initial_position_sigma"]] * 3)]
        p[L.P_VEL] = 1.0 if self.switch["velocity_aid"] else 0.0
        self._standstill = standstill_switch(config)
        p[L.P_STILL : L.PRM_SIZE] = standstill_parameters(c, self._standstill)

    # -- what tests and scripts read -----------------------------------------------------------
    @property
    def frame(self) -> str:
        """The navigation frame in use: "geographic" or "grid"."""
        return "grid" if self.st[L.S_FRAME] == L.FRAME_GRID else "geographic"

    @property
    def covariance(self) -> np.ndarray:
        """The filter's covariance (15, 15) in the frame in use, a copy."""
        return self.P.copy()

    def diagnostics(self) -> dict[str, float]:
        """Counters beyond NAV_QUALITY."""
        st = self.st
        return {"frame": int(st[L.S_FRAME]), "switches": int(st[L.S_NSWITCH]),
                "switches_refused": int(st[L.S_NREFUSED]), "fixes_used": int(st[L.S_NBDS]),
                "fixes_gated": int(st[L.S_NREJ]), "velocity_updates": int(st[L.S_NVEL]),
                "last_position_nis": float(st[L.S_NIS])}

    def close(self) -> None:
        """With ``log_diagnostics``: one line on stderr (the DUT log through the harness)."""
        if self.switch["log_diagnostics"]:
            import json
            import sys

            print(f"seed003 diagnostics: {json.dumps(self.diagnostics())}", file=sys.stderr, flush=True)

    def warm_up(self) -> None:
        """Compile the step kernel for the argument types of a step, without running it."""
        from bench.estimators.jit import compile_for
        from bench.wire.imu import IMU_SAMPLE_DTYPE

        # two frames: field views as a multi-frame step's (not contiguous); one frame (or none): as a
        # step of an IMU at or below the step rate's (contiguous views, numba's other specialization)
        for n in (2, 1):
            imu = np.zeros(n, IMU_SAMPLE_DTYPE)
            compile_for(K.run_step, self.st, self.P, self.prm, imu["dtheta"], imu["dvel"], imu["t_ns"], _EMPTY_I,
                        _EMPTY_F, _EMPTY_I, _EMPTY_I, _EMPTY_I, self._fixes, np.zeros(2, NAV_SOLUTION_DTYPE),
                        np.zeros(2, NAV_QUALITY_DTYPE))

    # -- the step --------------------------------------------------------------------------
    def step(self, inputs: DutInputs) -> EstimatorOutput:
        if self.position is None:
            raise ConfigError("the seed003 estimator needs dut.config.initial_position", key="dut.config")
        self._fixes = take_fixes(self._fixes, inputs)
        self._take_commands(inputs)
        imu = inputs.imu
        if self.choice["start"] == "rest" and self._rest.coarse:
            self._rest.add(imu)
            out = self._rest.epochs(inputs.t_ns, self._out_ns, self.position, self.cfg["position_sigma"])
            if self._rest.done(self.cfg["coarse_alignment"], self.cfg, self.position[0]):
                self._start_fine(self._rest.last_ns)
            self._cmd_t, self._cmd_code = self._cmd_t[:0], self._cmd_code[:0]  # none applies while aligning
            return out
        if not self._started:
            if self._held is not None:  # the first frame(s) of a moving start, held for their interval
                imu = np.concatenate([self._held, imu])
            if len(imu) < 2:  # the IMU interval is measured from two frames' times, never assumed
                self._held = imu.copy() if len(imu) else None
                return EstimatorOutput()
            self._held = None
            self._start_moving(imu)
        can = inputs.can
        d = can.columns("DOPPLER", _DOP_COLUMNS) if type(can) is CanView else None
        if d is None:
            m = inputs.doppler
            d = (m["rx_ns"], m["speed"], m["valid"])
        d_t, d_v, d_ok = d
        if len(d_t):
            d_t, d_v, d_ok = d_t.astype(np.int64, copy=False), d_v.astype(float, copy=False), \
                d_ok.astype(np.int64, copy=False)
        else:
            d_t, d_v, d_ok = _EMPTY_I, _EMPTY_F, _EMPTY_I
        sol, qual = self._out.take(len(imu))
        k = K.run_step(self.st, self.P, self.prm, imu["dtheta"], imu["dvel"], imu["t_ns"], d_t, d_v, d_ok,
                       self._cmd_t, self._cmd_code, self._fixes, sol, qual)
        self._fixes = self._fixes[int(self.st[L.S_CONSUMED]) :]
        nc = int(self.st[L.S_CCONSUMED])
        self._cmd_t, self._cmd_code = self._cmd_t[nc:], self._cmd_code[nc:]
        if k == 0:
            return EstimatorOutput()
        return EstimatorOutput(sol[:k], qual[:k])

    def _take_commands(self, inputs: DutInputs) -> None:
        m = inputs.message("BENCH_CMD")
        if len(m["rx_ns"]):
            self._cmd_t = np.concatenate([self._cmd_t, m["rx_ns"].astype(np.int64)])
            self._cmd_code = np.concatenate([self._cmd_code, m["command"].astype(np.int64)])

    def _start_fine(self, t_ns: int) -> None:
        """Coarse attitude from the sums, then the fine alignment's state and covariance."""
        c = self.cfg
        lat, lon, h = self.position  # type: ignore[misc]
        st = self.st
        st[L.S_SINS : L.S_SINS + 3] = lat, lon, h
        st[L.S_SINS + 6 : L.S_SINS + 10] = self._rest.attitude(lat)
        st[L.S_PHASE], st[L.S_TLAST], st[L.S_NEXT_OUT] = 1.0, t_ns, self._rest.next_out_ns
        st[L.S_ALIGN_END] = round(c["alignment"] * 1e9)
        st[L.S_P0 : L.S_P0 + 3] = lat, lon, h
        st[L.S_TNOM] = self._rest.nominal_step_s()
        st[L.S_LAST_BDS] = st[L.S_LAST_VEL] = -1e18
        self.P[:, :] = core_covariance(L.N_STATES, c, t_ns * 1e-9, lat, self._rest.cov, self._rest.coarse_C_bn)
        self.prm[L.P_ZUPT] = self._rest.zupt_noise(c["zupt_noise"])
        self.prm[L.P_STILL : L.PRM_SIZE] = standstill_parameters(c, self._standstill, self._rest)
        self._rest.finish()
        self._started = True

    def _start_moving(self, imu: np.ndarray) -> None:
        """The given state at the first frame's start; the grid frame beyond the switch
        latitude. The covariance: the initial sigmas and the bias priors."""
        c = self.cfg
        lat, lon, h = self.position  # type: ignore[misc]
        t = imu["t_ns"].astype(np.int64)
        step = float(np.median(np.diff(t))) * 1e-9  # two frames at least (step)
        sg = np.zeros(20)
        sg[0:3] = lat, lon, h
        sg[3:6] = self.vec["initial_velocity"]
        sg[6:10] = euler_to_quat(*self.vec["initial_attitude"])
        st = self.st
        if abs(lat) >= c["switch_latitude"] and self.switch["auto_switch"]:
            from_geographic(sg, st[L.S_SINS : L.S_SINS + 20])
            st[L.S_FRAME] = L.FRAME_GRID
        else:
            st[L.S_SINS : L.S_SINS + 20] = sg
        st[L.S_PHASE], st[L.S_TNOM] = 2.0, step
        st[L.S_TLAST] = float(t[0]) - step * 1e9
        st[L.S_NEXT_OUT] = float(t[0])
        st[L.S_NEXT_VEL] = float(t[0]) + self.prm[L.P_VELPER]
        st[L.S_LAST_BDS] = st[L.S_LAST_VEL] = -1e18
        diag = np.zeros(L.N_STATES)
        diag[9:12] = c["gyro_bias"] ** 2
        diag[12:15] = c["accel_bias"] ** 2
        self.P[:, :] = np.diag(diag)
        K.restart_covariance(st, self.P, self.prm)
        self._started = True
