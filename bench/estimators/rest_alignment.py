"""The at-rest start shared by the reference estimators: the coarse alignment's sums, the
"aligning" epochs output meanwhile, and the covariance the fine alignment starts from.

An estimator keeps one :class:`RestAlignment`; while :attr:`RestAlignment.coarse` it feeds
each step's IMU increments to :meth:`RestAlignment.add` and returns
:meth:`RestAlignment.epochs`; once :meth:`RestAlignment.done` it takes the attitude from
:meth:`RestAlignment.attitude` and the core covariance from :func:`core_covariance` and
starts its own fine alignment (its kernel's state layout is its own).
"""

from __future__ import annotations

import math

import numpy as np

from bench.dut import MODE_ALIGNING, NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE, EstimatorOutput
from bench.errors import ConfigError
from bench.nav.alignment import coarse_align
from bench.nav.rotation import dcm_to_quat

__all__ = ["RestAlignment", "core_covariance"]

_EARTH_RATE = 7.292115e-5  # rad/s


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

    def done(self, coarse_s: float) -> bool:
        """True once the increments span ``coarse_s``."""
        return self.last_ns > 0 and self.last_ns >= coarse_s * 1e9

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
        qual["sigma_pos"] = position_sigma
        return EstimatorOutput(sol, qual)

    def attitude(self, lat: float) -> np.ndarray:
        """q_bn (scalar first) of the analytic coarse alignment over the sums at ``lat``."""
        T = self.last_ns * 1e-9
        return dcm_to_quat(coarse_align(self.sum_dv / T, self.sum_th / T, lat))

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


def core_covariance(n: int, cfg: dict[str, float], coarse_s: float, lat: float) -> np.ndarray:
    """The (n,) diagonal of the covariance the fine alignment starts from, the core 15
    states filled (the rest zero): level from the accelerometer bias, heading from the gyro
    noise over ``coarse_s`` (generous; the fine alignment shrinks them), 1 cm/s, the
    surveyed ``position_sigma``, the bias priors. ``cfg`` holds ``accel_bias``,
    ``gyro_noise``, ``gyro_bias`` and ``position_sigma`` in SI."""
    lvl = max(3.0 * cfg["accel_bias"] / 9.8, math.radians(0.05))
    hdg = max(10.0 * cfg["gyro_noise"] / math.sqrt(coarse_s) / (_EARTH_RATE * math.cos(lat)), math.radians(1.0))
    diag = np.zeros(n)
    diag[0:3] = lvl**2, lvl**2, hdg**2
    diag[3:6] = 0.01**2
    diag[6:9] = cfg["position_sigma"] ** 2
    diag[9:12] = cfg["gyro_bias"] ** 2
    diag[12:15] = cfg["accel_bias"] ** 2
    return diag
