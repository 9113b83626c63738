"""The at-rest start shared by the reference estimators: the coarse alignment, the
"aligning" epochs output meanwhile, and the covariance the fine alignment starts from.

An estimator keeps one :class:`RestAlignment`; while :attr:`RestAlignment.coarse` it feeds
each step's IMU increments to :meth:`RestAlignment.add` and returns
:meth:`RestAlignment.epochs`; once :meth:`RestAlignment.done` it takes the attitude from
:meth:`RestAlignment.attitude`, the core covariance from :func:`core_covariance` and the
zero-velocity noise from :meth:`RestAlignment.zupt_noise`, and starts its own fine
alignment (its kernel's state layout is its own).

The coarse alignment is the inertial-frame (anti-disturbance) one of
:class:`bench.nav.alignment.InertialAlignment` over the whole coarse period: the gyros take
the vehicle's rocking out, so a parked vehicle with its engine running and people aboard
aligns as a still one does, only slower. Its accuracy (:func:`coarse_covariance`) is the
fit's own (the measured disturbance) plus what the datasheet's errors do to it (east gyro
bias, accelerometer bias, angle random walk, bias instabilities) plus the fit's change
over the period's last quarter (a disturbance slower than the fit can tell from the
Earth's rotation shows as a heading that still moves). The coarse period runs at least
``coarse_alignment`` and on, while the heading sigma exceeds ``coarse_heading_sigma``, up
to half the alignment: the fine alignment (a linear filter) starts inside its linear
range, from a prior that covers the coarse error.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.dut import MODE_ALIGNING, NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE, EstimatorOutput
from bench.errors import ConfigError
from bench.nav.alignment import InertialAlignment, InertialFit, coarse_align
from bench.nav.rotation import dcm_to_quat

__all__ = ["RestAlignment", "core_covariance", "coarse_covariance", "AT_REST_KEYS", "standstill_switch",
           "standstill_parameters"]

#: the keys every reference estimator with a SINS takes for its start at rest and its
#: standstills: key -> (dimension, unit of a bare number, default); docs/estimators.md
AT_REST_KEYS: dict[str, tuple[str, str, float]] = {
    "coarse_heading_sigma": ("angle", "deg", 2.0),
    "standstill_time": ("time", "s", 1.0),
    "standstill_accel": ("acceleration", "m/s^2", 0.05),
    "standstill_rate": ("angular_rate", "deg/s", 0.5),
    "standstill_speed": ("velocity", "m/s", 0.1),
    "standstill_noise": ("velocity", "m/s", 0.01),
}

_EARTH_RATE = 7.292115e-5  # rad/s
_G = 9.80665
_FIT_EVERY_NS = 1_000_000_000  # the coarse fit is checked once a second of data
_SIGMA_POS_MAX = 655.35  # m, NAV_QUALITY's full scale (the aligning epochs are not valid anyway)


class RestAlignment:
    """The coarse alignment at rest over ``coarse_s`` seconds; aligning epochs every
    ``out_ns`` at the surveyed ``position`` (rad, rad, m) with sigma ``position_sigma``."""

    def __init__(self) -> None:
        self.coarse = True
        self.sum_th = np.zeros(3)
        self.sum_dv = np.zeros(3)
        self._gaps: list[np.ndarray] = []
        self.last_ns = 0
        self.next_out_ns: int | None = None  # set by the first step: no epoch before its data (a replay's seek)
        self.first_ns: int | None = None  # the first IMU frame's time
        self.inertial = InertialAlignment()
        self.fit: InertialFit | None = None
        self.cov: np.ndarray | None = None  # (3, 3) the coarse attitude's error covariance (ENU, rad^2)
        self._next_fit_ns = 0

    def add(self, imu: np.ndarray) -> None:
        """Sum one step's increments (IMU_SAMPLE_DTYPE rows); the gaps between consecutive
        frames' times of validity are kept, across steps too (a step may hold one frame, or
        none: 100 Hz at 10 ms steps, 1 Hz at any step)."""
        if len(imu):
            t = imu["t_ns"].astype(np.int64)
            if self.first_ns is None:
                self.first_ns = int(t[0])
                if len(t) > 1:
                    self._gaps.append(np.diff(t))
            else:
                self._gaps.append(np.diff(t, prepend=self.last_ns))
            self.sum_th += imu["dtheta"].sum(axis=0)
            self.sum_dv += imu["dvel"].sum(axis=0)
            self.last_ns = int(imu["t_ns"][-1])
            self.inertial.add(imu["dtheta"], imu["dvel"], imu["t_ns"])

    def done(self, coarse_s: float, cfg: dict[str, float] | None = None, lat: float | None = None) -> bool:
        """True once the increments span ``coarse_s`` and, with the configuration ``cfg``
        (SI: ``alignment``, ``coarse_heading_sigma``, the datasheet figures of
        :func:`coarse_covariance`) and the latitude ``lat``, the inertial-frame fit's heading
        sigma is within ``coarse_heading_sigma`` or the period has reached half the
        alignment. The fit and its covariance are then :attr:`fit` and :attr:`cov`."""
        if not (self.last_ns > 0 and self.last_ns >= coarse_s * 1e9):
            return False
        if cfg is None or lat is None:
            return True
        if self.last_ns < self._next_fit_ns:
            return False
        self._next_fit_ns = self.last_ns + _FIT_EVERY_NS
        an, gb = cfg.get("accel_noise", 0.0), cfg.get("gyro_bias", 0.0)
        fit = self.inertial.fit(lat, an, gyro_bias=gb)
        if fit is None:
            return self.last_ns >= 0.5 * cfg["alignment"] * 1e9
        self.fit = fit
        earlier = [self.inertial.fit(lat, an, until_s=0.75 * self.inertial.span_s, gyro_bias=gb)]
        self.cov = coarse_covariance(fit, [e for e in earlier if e is not None], cfg, lat)
        hdg = math.sqrt(max(float(self.cov[2, 2]), 0.0))
        return hdg <= cfg.get("coarse_heading_sigma", math.radians(2.0)) or self.last_ns >= 0.5 * cfg["alignment"] * 1e9

    def epochs(self, t_ns: int, out_ns: int, position: tuple[float, float, float] | None,
               position_sigma: float) -> EstimatorOutput:
        """The "aligning" (not valid) epochs on the ``out_ns`` grid up to ``t_ns``, from the
        first step's time or its first IMU frame's, whichever is earlier, on (a run that
        starts later than bench time 0, a replay from a seek, gets no epochs from before it:
        a DUT never answers for a time it saw nothing of)."""
        if self.next_out_ns is None:
            self.next_out_ns = min(t_ns, self.first_ns) if self.first_ns is not None else t_ns
        if t_ns < self.next_out_ns or position is None:
            return EstimatorOutput()
        first = -(-self.next_out_ns // out_ns) * out_ns
        times = np.arange(first, t_ns + 1, out_ns, dtype=np.int64)
        if not len(times):
            return EstimatorOutput()
        self.next_out_ns = int(times[-1]) + out_ns
        sol = np.zeros(len(times), NAV_SOLUTION_DTYPE)
        sol["t_ns"] = times
        sol["lat"], sol["lon"], sol["h"] = position
        sol["mode"] = MODE_ALIGNING
        qual = np.zeros(len(times), NAV_QUALITY_DTYPE)
        qual["t_ns"] = times
        qual["sigma_pos"] = min(position_sigma, _SIGMA_POS_MAX)  # NAV_QUALITY's full scale ("at least")
        return EstimatorOutput(sol, qual)

    def attitude(self, lat: float) -> np.ndarray:
        """q_bn (scalar first) at the last frame: the inertial-frame fit's (after
        :meth:`done` with a configuration), else the analytic coarse alignment over the sums
        at ``lat``."""
        if self.fit is not None:
            return dcm_to_quat(self.fit.C_bn)
        T = self.last_ns * 1e-9
        return dcm_to_quat(coarse_align(self.sum_dv / T, self.sum_th / T, lat))

    @property
    def coarse_C_bn(self) -> np.ndarray | None:
        """The inertial-frame fit's C_bn (body to ENU) at the last frame, None without one
        (the covariance's heading-bias correlation, :func:`core_covariance`)."""
        return None if self.fit is None else self.fit.C_bn

    def zupt_noise(self, configured: float) -> float:
        """The zero-velocity noise of the fine alignment (m/s): the configured one, or the
        velocity disturbance the coarse fit measured (rocking, vibration; its
        autocorrelation counted) when larger."""
        if self.fit is None:
            return configured
        return max(configured, self.fit.disturbance * math.sqrt(self.fit.inflation))

    def nominal_step_s(self) -> float:
        """The IMU interval measured over the coarse period: the median gap between
        consecutive frames' times of validity, s. Never assumed: fewer than two frames
        (a coarse period shorter than the IMU's interval) is a ConfigError naming
        ``dut.config.coarse_alignment``."""
        gaps = np.concatenate(self._gaps) if self._gaps else np.zeros(0, np.int64)
        gaps = gaps[gaps > 0]  # a repeated time of validity is no interval
        if not len(gaps):
            seen = "no IMU frame" if self.first_ns is None else "one IMU frame time"
            raise ConfigError(
                f"the coarse alignment saw {seen} up to bench time {self.last_ns / 1e9:g} s: the IMU interval "
                "cannot be measured; make the coarse alignment last at least two IMU intervals",
                key="dut.config.coarse_alignment",
            )
        return float(np.median(gaps)) * 1e-9

    def finish(self) -> None:
        self.coarse = False


def coarse_covariance(fit: InertialFit, earlier: list[InertialFit], cfg: dict[str, float], lat: float) -> np.ndarray:
    """(3, 3) covariance of the coarse attitude's error angles (ENU, rad^2): the fit's own
    (the measured disturbance), the datasheet errors' effects on an alignment at rest over
    ``fit.t_s`` -- level: accelerometer bias / g; heading: east gyro bias / horizontal Earth
    rate, the accelerometer bias through the latitude (tan), the angle random walk's slope
    over the period (sqrt(6/5) N / sqrt(T) / horizontal Earth rate), the bias
    instabilities (a gyro bias that moves by it; an accelerometer bias that moves by it
    within the period, which curves the velocity as the Earth's rotation does) -- and the
    squared changes of the attitude from the ``earlier`` fits (the same over the first
    three quarters of the period: how much the last quarter still moved it)."""
    T = max(fit.t_s, 1e-3)
    wh = _EARTH_RATE * max(math.cos(lat), 1e-3)
    g = fit.g if fit.g > 0.0 else _G
    ab, gb, arw = cfg.get("accel_bias", 0.0), cfg.get("gyro_bias", 0.0), cfg.get("gyro_noise", 0.0)
    abi, gbi = cfg.get("accel_bias_instability", 0.0), cfg.get("gyro_bias_instability", 0.0)
    lvl2 = (ab / g) ** 2
    hdg2 = (gb / wh) ** 2 + (ab * math.tan(min(abs(lat), math.radians(89.0))) / g) ** 2 \
        + 1.2 * arw**2 / T / wh**2 + (gbi / wh) ** 2 + (2.0 * abi / (g * wh * T)) ** 2
    cov = fit.cov + np.diag([lvl2, lvl2, hdg2])
    for e in earlier:
        E = fit.C_bn @ e.C_bn.T  # I + [d x]: what the rest of the period changed
        d = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
        cov = cov + np.diag(d**2)
    return 0.5 * (cov + cov.T)


def core_covariance(n: int, cfg: dict[str, float], coarse_s: float, lat: float,
                    attitude: np.ndarray | None = None, C_bn: np.ndarray | None = None) -> np.ndarray:
    """The (n, n) covariance the fine alignment starts from, the core 15 states filled
    (the rest zero): the attitude block from the coarse alignment's own accuracy
    (``attitude``, (3, 3), :attr:`RestAlignment.cov`; without it the former generous
    figures: level from the accelerometer bias, heading from the gyro noise over
    ``coarse_s``), 1 cm/s, the surveyed ``position_sigma``, the bias priors. ``cfg`` holds
    ``accel_bias``, ``gyro_noise``, ``gyro_bias`` and ``position_sigma`` in SI.

    With the coarse attitude ``C_bn`` (body to ENU) too, the heading error and the gyro
    bias states are correlated as the coarse alignment made them: at rest it finds the
    heading at which the east gyro bias balances the Earth rate, phi_U = -eps_E / (Omega
    cos lat) (phi as in C_true = (I + [phi x]) C), so cov(phi_U, eps_b) = -C_bn[0, :]
    sigma_b^2 / (Omega cos lat). Without it the fine alignment, which sees the same
    unobservable sum of heading and east bias, splits that sum by the prior's ratio and
    pulls the heading towards the coarse period's noise (S000: 5.5' after the alignment
    where the gyrocompassing limit is 3.8')."""
    P = np.zeros((n, n))
    if attitude is not None:
        P[0:3, 0:3] = attitude
    else:
        lvl = max(3.0 * cfg["accel_bias"] / 9.8, math.radians(0.05))
        hdg = max(10.0 * cfg["gyro_noise"] / math.sqrt(coarse_s) / (_EARTH_RATE * math.cos(lat)), math.radians(1.0))
        P[0, 0], P[1, 1], P[2, 2] = lvl**2, lvl**2, hdg**2
    for i in range(3):
        P[3 + i, 3 + i] = 0.01**2
        P[6 + i, 6 + i] = cfg["position_sigma"] ** 2
        P[9 + i, 9 + i] = cfg["gyro_bias"] ** 2
        P[12 + i, 12 + i] = cfg["accel_bias"] ** 2
    if attitude is not None and C_bn is not None:
        wn = _EARTH_RATE * max(math.cos(lat), 1e-3)
        cross = -np.asarray(C_bn, dtype=float)[0, :] * cfg["gyro_bias"] ** 2 / wn
        P[2, 9:12] = cross
        P[9:12, 2] = cross
    return P


def standstill_switch(config: Mapping[str, Any]) -> bool:
    """``dut.config.standstill_zupt`` (default true): zero-velocity updates at standstills
    while navigating."""
    v = config.get("standstill_zupt", True)
    if not isinstance(v, bool):
        raise ConfigError(f"expected true or false, found {v!r}", key="dut.config.standstill_zupt")
    return v


def standstill_parameters(cfg: dict[str, float], on: bool, rest: RestAlignment | None = None) -> np.ndarray:
    """The standstill detector's parameters (:data:`bench.estimators.sins_core.STILL_PRM`)
    from the configuration ``cfg`` (SI): on, time, horizontal specific force, rate, speed,
    and the zero-velocity noise -- the configured ``standstill_noise``, or the velocity
    disturbance the coarse alignment measured when larger (``rest``)."""
    noise = cfg["standstill_noise"] if rest is None else rest.zupt_noise(cfg["standstill_noise"])
    for k in ("standstill_time", "standstill_accel", "standstill_rate", "standstill_speed"):
        if not cfg[k] > 0.0:
            raise ConfigError("expected a positive value", key=f"dut.config.{k}")
    return np.array([1.0 if on else 0.0, cfg["standstill_time"], cfg["standstill_accel"], cfg["standstill_rate"],
                     cfg["standstill_speed"], noise])
