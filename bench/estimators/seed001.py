"""``seed001``: the BDS / SINS loose-integration estimator of seed 001 (transport vehicle).

A 20-state closed-loop error-state Kalman filter on the bench's SINS (the core 15 states,
an odometer scale factor, the receiver's time offset and, optionally, three first-order
Markov states of the receiver's correlated position error; the layout in
:mod:`bench.estimators.seed001_meas`):

- BDS position and horizontal velocity (seed eq. 14) from the NMEA epochs, compared with
  the INS at the fix's measurement time (its UTC via BENCH_EPOCH, minus the estimated
  time offset; the INS kept in a 2 s history), the antenna lever arm compensated in
  position and velocity (eq. 1-6) and the time offset in the measurement matrix (eq.
  7-10); R from the GST sigmas minus the modelled Markov part; chi-square gating (fixes
  gated out: NAV_QUALITY fault detected and excluded, bit 2; no-fix epochs: excluded);
- the odometer speed with the non-holonomic constraint (eq. 20, body velocity (0, (1-k)
  v_odo, 0)) at ``odometer_rate``; a zero-velocity update instead when the odometer has
  read zero for ``zupt_time`` and the IMU is still;
- alignment at rest: analytic coarse alignment, then the fine alignment (zero velocity and
  the surveyed position) until ``alignment``;
- optionally the output position put on the road network by the HMM map matcher
  (``map_matching = true``, :mod:`bench.estimators.mapmatch`).

Configuration keys, defaults and the variants: docs/estimators.md, ``seed001``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from bench.config.table import check_keys
from bench.dut import MODE_ALIGNING, NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE, DutInputs, Estimator, EstimatorOutput
from bench.dut.estimator import CanView
from bench.errors import ConfigError
from bench.estimators import seed001_kernel as K  # noqa: N812 - the kernel layout constants
from bench.estimators.fixes import take_fixes
from bench.estimators.outblocks import OutputBlocks
from bench.estimators.rest_alignment import (
    AT_REST_KEYS,
    RestAlignment,
    core_covariance,
    standstill_parameters,
    standstill_switch,
)
from bench.estimators.seed001_meas import DDT, DK, MK
from bench.estimators.settings import period_ns, surveyed_position, vectors
from bench.units import quantity

__all__ = ["Seed001", "CONFIG_KEYS", "VECTOR_KEYS"]

#: key -> (dimension, unit of a bare number, default)
CONFIG_KEYS: dict[str, tuple[str, str, float]] = {
    "gyro_bias": ("angular_rate", "deg/h", 0.01),
    "gyro_noise": ("angle_random_walk", "deg/sqrt(h)", 0.001),
    "accel_bias": ("acceleration", "ug", 100.0),
    "accel_noise": ("velocity_random_walk", "ug/sqrt(Hz)", 10.0),
    "gyro_bias_instability": ("angular_rate", "deg/h", 0.003),
    "accel_bias_instability": ("acceleration", "ug", 10.0),
    "bias_instability_tau": ("time", "s", 500.0),
    "alignment": ("time", "s", 55.0),
    "coarse_alignment": ("time", "s", 10.0),
    "time_update_period": ("time", "s", 0.1),
    "output_rate": ("frequency", "Hz", 100.0),
    "zupt_noise": ("velocity", "m/s", 0.001),
    "position_sigma": ("length", "m", 0.1),
    "time_offset": ("time", "s", 0.0),
    "time_offset_sigma": ("time", "s", 0.1),
    "bds_markov_tau": ("time", "s", 45.0),
    "bds_white_floor": ("dimensionless", "1", 0.2),
    "bds_velocity_sigma": ("velocity", "m/s", 0.1),
    "bds_gate": ("dimensionless", "1", 0.9999),
    "bds_aiding_timeout": ("time", "s", 2.0),
    "odometer_rate": ("frequency", "Hz", 10.0),
    "odometer_scale_sigma": ("dimensionless", "%", 0.5),
    "odometer_timeout": ("time", "s", 0.1),
    "zupt_time": ("time", "s", 1.0),
    "zupt_speed": ("velocity", "m/s", 0.02),
    "zupt_accel_std": ("acceleration", "m/s^2", 0.05),
    "zupt_rate": ("angular_rate", "deg/s", 1.0),
    "stop_zupt_noise": ("velocity", "m/s", 0.01),
    **AT_REST_KEYS,
}
#: key -> (dimension, unit of a bare number, default (3,)); body RFU for the lever arms
VECTOR_KEYS: dict[str, tuple[str, str, tuple[float, float, float]]] = {
    "lever_arm": ("length", "m", (0.0, 0.0, 0.0)),
    "odometer_lever_arm": ("length", "m", (0.0, 0.0, 0.0)),
    "nhc_lever_arm": ("length", "m", (0.0, 0.0, 0.0)),
    "bds_markov_sigma": ("length", "m", (0.57, 2.53, 2.22)),
    "odometer_noise": ("velocity", "m/s", (0.1, 0.05, 0.1)),
}
_SWITCHES = {
    "lever_arm_compensation": True,
    "time_offset_estimation": True,
    "odometer": True,
    "map_matching": False,
    "log_diagnostics": False,
}
_OTHER_KEYS = ("initial_position", "road_network", "standstill_zupt")
_EMPTY_I = np.zeros(0, np.int64)
_EMPTY_F = np.zeros(0)
_ODO_COLUMNS = ("rx_ns", "speed", "valid")


class Seed001(Estimator):
    """BDS / SINS loose integration of seed 001 (module docstring)."""

    name = "seed001"

    def __init__(self) -> None:
        self.cfg: dict[str, float] = {k: quantity(v, d, u) for k, (d, u, v) in CONFIG_KEYS.items()}
        self.switch = dict(_SWITCHES)
        self.position: tuple[float, float, float] | None = None
        self.st = np.zeros(K.ST_SIZE)
        self.P = np.zeros((K.N_STATES, K.N_STATES))
        self.prm = np.zeros(K.PRM_SIZE)
        self.xm = np.zeros(3)
        self.hist = np.zeros((K.HIST_LEN, 14))
        self._pending = np.zeros((0, K.FIX_COLS))
        self._rest = RestAlignment()
        self._out_ns = 10_000_000
        self._standstill = True
        self._matcher: Any = None
        self._mm_sent: dict[int, tuple[float, float]] = {}
        self._mm_offset = (0.0, 0.0)
        self._out = OutputBlocks()

    # -- configuration -------------------------------------------------------------------
    def configure(self, config: Mapping[str, Any]) -> None:
        check_keys(config, [*CONFIG_KEYS, *VECTOR_KEYS, *_SWITCHES, *_OTHER_KEYS], file=None, key="dut.config")
        for k, (dim, unit, default) in CONFIG_KEYS.items():
            v = quantity(config.get(k, default), dim, unit, key=f"dut.config.{k}")
            if v < 0 and k != "time_offset":
                raise ConfigError(f"expected a non-negative value, found {config[k]!r}", key=f"dut.config.{k}")
            self.cfg[k] = float(v)
        for k in _SWITCHES:
            v = config.get(k, _SWITCHES[k])
            if not isinstance(v, bool):
                raise ConfigError(f"expected true or false, found {v!r}", key=f"dut.config.{k}")
            self.switch[k] = v
        vec = vectors(config, VECTOR_KEYS, "right, forward, up / E, N, U")
        self.position = surveyed_position(config)
        c = self.cfg
        if c["coarse_alignment"] >= c["alignment"]:
            raise ConfigError("expected coarse_alignment shorter than alignment", key="dut.config.coarse_alignment")
        for k in ("output_rate", "odometer_rate", "bds_markov_tau", "time_update_period", "odometer_timeout"):
            if c[k] <= 0:
                raise ConfigError("expected a positive value", key=f"dut.config.{k}")
        if not 0.0 < c["bds_gate"] < 1.0:
            raise ConfigError(f"expected a probability in (0, 1), found {c['bds_gate']!r}", key="dut.config.bds_gate")
        self._out_ns = period_ns(1.0 / c["output_rate"], "dut.config.output_rate")
        from scipy.stats import chi2

        p = self.prm
        p[K.P_NG], p[K.P_NA], p[K.P_GB], p[K.P_AB] = c["gyro_noise"], c["accel_noise"], c["gyro_bias"], c["accel_bias"]
        # bias instability as a random walk of the bias states: sigma^2 growth 2 sigma^2 / tau per s
        tb = max(c["bias_instability_tau"], 1e-3)
        p[K.P_QG] = c["gyro_bias_instability"] * math.sqrt(2.0 / tb)
        p[K.P_QA] = c["accel_bias_instability"] * math.sqrt(2.0 / tb)
        p[K.P_TU], p[K.P_OUT], p[K.P_ZUPT], p[K.P_RP0] = c["time_update_period"], self._out_ns, c["zupt_noise"], \
            c["position_sigma"]
        p[K.P_LA : K.P_LA + 3] = vec["lever_arm"] if self.switch["lever_arm_compensation"] else 0.0
        p[K.P_TOE] = 1.0 if self.switch["time_offset_estimation"] else 0.0
        p[K.P_DTS], p[K.P_DTQ] = c["time_offset_sigma"], 0.0
        p[K.P_MS : K.P_MS + 3] = vec["bds_markov_sigma"]
        p[K.P_MTAU], p[K.P_RVEL], p[K.P_FLOOR] = c["bds_markov_tau"], c["bds_velocity_sigma"], c["bds_white_floor"]
        p[K.P_GATE3], p[K.P_GATE5] = chi2.ppf(c["bds_gate"], 3), chi2.ppf(c["bds_gate"], 5)
        p[K.P_ODO] = 1.0 if self.switch["odometer"] else 0.0
        p[K.P_ODOPER] = period_ns(1.0 / c["odometer_rate"], "dut.config.odometer_rate")
        p[K.P_ODOR : K.P_ODOR + 3] = vec["odometer_noise"]
        p[K.P_OL : K.P_OL + 3] = vec["odometer_lever_arm"]
        p[K.P_NL : K.P_NL + 3] = vec["nhc_lever_arm"]
        p[K.P_KS] = c["odometer_scale_sigma"]
        p[K.P_KQ] = c["odometer_scale_sigma"] / math.sqrt(3600.0)  # grows by its prior sigma in an hour
        p[K.P_ZT], p[K.P_ZA], p[K.P_ZW] = c["zupt_time"], c["zupt_accel_std"], c["zupt_rate"]
        p[K.P_ZS], p[K.P_ZN] = c["zupt_speed"], c["stop_zupt_noise"]
        p[K.P_BDSAGE], p[K.P_ODOTO] = c["bds_aiding_timeout"] * 1e9, c["odometer_timeout"] * 1e9
        self.st[K.S_DT] = c["time_offset"]
        self._standstill = standstill_switch(config)
        p[K.P_STILL : K.PRM_SIZE] = standstill_parameters(c, self._standstill)
        if self.switch["map_matching"]:
            self._matcher = _matcher(config.get("road_network"))

    # -- what the MC scripts read ------------------------------------------------------------
    @property
    def time_offset(self) -> tuple[float, float]:
        """(estimate, 1-sigma) of the receiver's time offset (sentence time minus true
        measurement time), s."""
        return float(self.st[K.S_DT]), math.sqrt(max(self.P[DDT, DDT], 0.0))

    @property
    def odometer_scale(self) -> tuple[float, float]:
        """(estimate, 1-sigma) of the odometer scale-factor error compensated."""
        return float(self.st[K.S_K]), math.sqrt(max(self.P[DK, DK], 0.0))

    def diagnostics(self) -> dict[str, float]:
        """Counters and estimates beyond NAV_QUALITY."""
        st = self.st
        dt, sdt = self.time_offset
        return {"time_offset_s": dt, "time_offset_sigma_s": sdt, "odometer_scale": float(st[K.S_K]),
                "fixes_used": int(st[K.S_NBDS]), "fixes_gated": int(st[K.S_NREJ]),
                "fixes_without_position": int(st[K.S_NSKIP]), "last_nis": float(st[K.S_NIS])}

    def close(self) -> None:
        """With ``log_diagnostics``: one line on stderr (the DUT log through the harness)."""
        if self.switch["log_diagnostics"]:
            import json
            import sys

            print(f"seed001 diagnostics: {json.dumps(self.diagnostics())}", file=sys.stderr, flush=True)

    @property
    def covariance(self) -> np.ndarray:
        """The filter's covariance (20, 20), a copy."""
        return self.P.copy()

    def warm_up(self) -> None:
        """Compile the step kernel for the argument types of a step, without running it."""
        from bench.estimators.jit import compile_for
        from bench.wire.imu import IMU_SAMPLE_DTYPE

        # two frames: field views as a multi-frame step's (not contiguous); one frame (or none): as a
        # step of an IMU at or below the step rate's (contiguous views, numba's other specialization)
        for n in (2, 1):
            imu = np.zeros(n, IMU_SAMPLE_DTYPE)
            compile_for(K.run_step, self.st, self.P, self.prm, self.xm, self.hist, imu["dtheta"], imu["dvel"],
                        imu["t_ns"], _EMPTY_I, _EMPTY_F, _EMPTY_I, self._pending, np.zeros(2, NAV_SOLUTION_DTYPE),
                        np.zeros(2, NAV_QUALITY_DTYPE))

    # -- the step --------------------------------------------------------------------------
    def step(self, inputs: DutInputs) -> EstimatorOutput:
        if self.position is None:
            raise ConfigError("the seed001 estimator needs dut.config.initial_position", key="dut.config")
        self._pending = take_fixes(self._pending, inputs)
        imu = inputs.imu
        if self._rest.coarse:
            return self._coarse_step(inputs, imu)
        can = inputs.can
        if type(can) is CanView:  # the bench's: the three columns, without the message's dict
            o = can.columns("ODOMETER", _ODO_COLUMNS)
            o_t, o_v, o_ok = o if o is not None else (_EMPTY_I, _EMPTY_F, _EMPTY_I)
        else:
            odo = inputs.odometer
            o_t, o_v, o_ok = (odo[key] for key in _ODO_COLUMNS)
        if len(o_t):
            o_t, o_v, o_ok = o_t.astype(np.int64, copy=False), o_v.astype(float, copy=False), \
                o_ok.astype(np.int64, copy=False)
        else:
            o_t, o_v, o_ok = _EMPTY_I, _EMPTY_F, _EMPTY_I
        sol, qual = self._out.take(len(imu))
        k = K.run_step(self.st, self.P, self.prm, self.xm, self.hist, imu["dtheta"], imu["dvel"], imu["t_ns"],
                       o_t, o_v, o_ok, self._pending, sol, qual)
        self._pending = self._pending[int(self.st[K.S_CONSUMED]) :]
        if k == 0:
            return EstimatorOutput()
        sol, qual = sol[:k], qual[:k]
        if self._matcher is not None:
            self._map_match(sol)
        return EstimatorOutput(sol, qual)


    def _coarse_step(self, inputs: DutInputs, imu: np.ndarray) -> EstimatorOutput:
        """Sum the increments at rest; output "aligning" epochs at the surveyed position."""
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
        st[K.S_STILL] = -1.0
        st[K.S_LAST_BDS] = st[K.S_LAST_ODO] = -1e18
        st[K.S_TNOM] = self._rest.nominal_step_s()
        # the INS history holds 2 s at the measured rate (HIST_LEN: 2 s at 200 Hz, the least kept)
        self.hist = np.zeros((max(K.HIST_LEN, math.ceil(2.0 / st[K.S_TNOM] - 1e-9)), 14))
        P = core_covariance(K.N_STATES, c, t_ns * 1e-9, lat, self._rest.cov, self._rest.coarse_C_bn)
        P[DK, DK] = c["odometer_scale_sigma"] ** 2
        P[DDT, DDT] = c["time_offset_sigma"] ** 2 if self.switch["time_offset_estimation"] else 0.0
        for i in range(3):
            P[MK + i, MK + i] = self.prm[K.P_MS + i] ** 2
        self.P[:, :] = P
        self.prm[K.P_ZUPT] = self._rest.zupt_noise(c["zupt_noise"])
        self.prm[K.P_STILL : K.PRM_SIZE] = standstill_parameters(c, self._standstill, self._rest)
        self._rest.finish()

    # -- map matching ----------------------------------------------------------------------
    def _map_match(self, sol: np.ndarray) -> None:
        """Output positions on the road: the matcher at each 10 Hz epoch, its offset from the
        filter applied to the epochs between."""
        lat, lon = sol["lat"], sol["lon"]
        times = sol["t_ns"].tolist()
        for i, ok in enumerate(sol["valid"].tolist()):  # (plain ints: a record's fields are slow to read)
            if ok and times[i] % 100_000_000 == 0:
                r = sol[i]
                v = r["vel_n"]
                t = times[i]
                self._mm_sent[t] = (float(r["lat"]), float(r["lon"]))
                m = self._matcher.update(t, float(r["lat"]), float(r["lon"]), float(r["heading"]),
                                         float(math.hypot(v[0], v[1])))
                # the matcher decides `lag` epochs back: the offset is the matched position
                # minus the filter's position at that epoch, carried to the epochs after
                if m is not None and m.t_ns in self._mm_sent:
                    lat0, lon0 = self._mm_sent[m.t_ns]
                    self._mm_offset = (m.lat - lat0, m.lon - lon0) if m.matched else (0.0, 0.0)
                    for k in [k for k in self._mm_sent if k <= m.t_ns]:
                        del self._mm_sent[k]
            if ok:
                lat[i] += self._mm_offset[0]
                lon[i] += self._mm_offset[1]


def _matcher(path: Any) -> Any:
    """The online HMM map matcher on the road network ``path`` (imported only when used)."""
    key = "dut.config.road_network"
    if not isinstance(path, str) or not path:
        raise ConfigError("map_matching = true needs the road network: a GeoJSON file path", key=key)
    if not Path(path).is_file():
        raise ConfigError(f"no road network file {path!r}", key=key)
    from bench.estimators.mapmatch import OnlineMatcher, RoadNetwork

    return OnlineMatcher(RoadNetwork.from_geojson(path))
