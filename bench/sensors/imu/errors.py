"""The IMU error model: exact increments in, the increments a real unit would output.

Per interval of length T, for each triad (gyro on angle increments, accelerometer on
velocity increments), in this order:

1. saturation: the mean input over the interval is clipped to the range; status bit 7;
2. gain: ``x + k x + M x`` with k the scale-factor error (asymmetric by the sign of the
   input) and M the misalignment matrix;
3. biases times T: constant (fixed or drawn per run), first-order Gauss-Markov bias
   instability, bias random walk, and for gyros the g-sensitivity on the true specific
   force;
4. white noise with variance ``N^2 T`` (angle or velocity random walk N);
5. pulse quantization with the residual carried to the next interval.

All random terms come from named streams of the run seed (:func:`bench.rng.stream`),
so the output is the same however the run is split into blocks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.rng import stream
from bench.sensors.imu.grade import ImuGrade, TriadErrors
from bench.sensors.imu.ideal import ImuBlock
from bench.sensors.processes import gauss_markov_filter

__all__ = ["ImuErrorModel", "gauss_markov_sigma", "ALLAN_FLOOR_FACTOR"]

#: Allan deviation of flicker (bias-instability) noise is sqrt(2 ln 2 / pi) B = 0.664 B.
ALLAN_FLOOR_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)


def _gm_adev_peak_factor() -> float:
    """Peak over T of the Allan deviation of a unit-variance first-order Gauss-Markov
    process, relative to its sigma (about 0.6175 at T = 1.89 tau)."""
    x = np.linspace(0.5, 6.0, 20001)  # T / tau
    avar = (2.0 / x) * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))
    return float(np.sqrt(avar.max()))


_GM_PEAK = _gm_adev_peak_factor()


def gauss_markov_sigma(bias_instability: np.ndarray | float) -> np.ndarray:
    """Sigma of the Gauss-Markov process whose Allan-deviation peak is 0.664 B."""
    return np.asarray(bias_instability) * ALLAN_FLOOR_FACTOR / _GM_PEAK


@dataclass
class _TriadState:
    bias: np.ndarray  # realised constant bias
    M: np.ndarray  # realised misalignment
    gm: np.ndarray  # Gauss-Markov state
    rw: np.ndarray  # random-walk state
    residual: np.ndarray  # quantization residual


class ImuErrorModel:
    """Apply an :class:`ImuGrade` to ideal increments, block by block.

    Parameters
    ----------
    grade:
        The error parameters.
    seed:
        Run seed; the streams are ``(name, "gyro"|"accel", term)``.
    rate_hz:
        IMU rate (the interval T of every block).
    name:
        Stream name of this IMU (two IMUs in one run need two names).
    """

    def __init__(self, grade: ImuGrade, seed: int, rate_hz: float, name: str = "imu"):
        self.grade = grade
        self.T = 1.0 / rate_hz
        self._rng = {
            (triad, term): stream(seed, name, triad, term)
            for triad in ("gyro", "accel")
            for term in ("noise", "gm", "rw")
        }
        draws = {triad: stream(seed, name, triad, "turn-on") for triad in ("gyro", "accel")}
        self._state = {
            "gyro": self._init_state(grade.gyro, draws["gyro"], "gyro"),
            "accel": self._init_state(grade.accel, draws["accel"], "accel"),
        }

    def _init_state(self, e: TriadErrors, rng: np.random.Generator, triad: str) -> _TriadState:
        bias = e.bias * rng.standard_normal(3) if e.bias_draw == "random" else e.bias.copy()
        if e.misalignment_draw == "random":
            M = e.misalignment * rng.standard_normal((3, 3))
            np.fill_diagonal(M, 0.0)
        else:
            M = e.misalignment.copy()
        gm0 = gauss_markov_sigma(e.bias_instability) * self._rng[(triad, "gm")].standard_normal(3)
        return _TriadState(bias, M, gm0, np.zeros(3), np.zeros(3))

    @property
    def realised(self) -> dict[str, dict[str, np.ndarray]]:
        """The per-run draws (constant biases, misalignment matrices), for the record."""
        return {k: {"bias": s.bias.copy(), "misalignment": s.M.copy()} for k, s in self._state.items()}

    def apply(self, block: ImuBlock) -> ImuBlock:
        """Erroneous copy of an ideal block (the block itself is not changed)."""
        g, a = self.grade.gyro, self.grade.accel
        status = block.status.copy()
        dvel_true = block.dvel
        dth, sat_g = self._triad(block.dtheta, g, self._state["gyro"], "gyro", extra=self._gsens(g, dvel_true))
        dv, sat_a = self._triad(dvel_true, a, self._state["accel"], "accel", extra=None)
        status[sat_g | sat_a] |= 0x80
        return ImuBlock(block.t_ns.copy(), dth, dv, status)

    def _gsens(self, g: TriadErrors, dvel_true: np.ndarray) -> np.ndarray | None:
        if not np.any(g.g_sensitivity):
            return None
        return dvel_true @ g.g_sensitivity.T  # (rad/s per m/s^2) * (m/s) = rad per interval

    def _triad(
        self, x: np.ndarray, e: TriadErrors, st: _TriadState, triad: str, extra: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        T = self.T
        n = len(x)
        sat = np.zeros(n, dtype=bool)
        if e.range > 0.0:
            lim = e.range * T
            over = np.abs(x) > lim
            sat = over.any(axis=1)
            x = np.clip(x, -lim, lim)
        out = x.copy()
        if np.any(e.scale_factor) or np.any(e.scale_factor_asymmetry):
            k = e.scale_factor + np.where(x >= 0.0, 1.0, -1.0) * e.scale_factor_asymmetry
            out += k * x
        if np.any(st.M):
            out += x @ st.M.T
        if np.any(st.bias):
            out += st.bias * T
        if extra is not None:
            out += extra
        if np.any(e.bias_instability):
            sigma = gauss_markov_sigma(e.bias_instability)
            phi = np.exp(-T / e.bias_instability_tau)
            w = self._rng[(triad, "gm")].standard_normal((n, 3))
            gm = np.empty((n, 3))
            for i in range(3):
                gm[:, i], st.gm[i] = gauss_markov_filter(
                    w[:, i], phi[i], sigma[i] * math.sqrt(1.0 - phi[i] ** 2), st.gm[i]
                )
            out += gm * T
        if np.any(e.bias_random_walk):
            steps = self._rng[(triad, "rw")].standard_normal((n, 3)) * (e.bias_random_walk * math.sqrt(T))
            rw = st.rw + np.cumsum(steps, axis=0)
            st.rw = rw[-1].copy()
            out += rw * T
        if np.any(e.noise):
            out += self._rng[(triad, "noise")].standard_normal((n, 3)) * (e.noise * math.sqrt(T))
        if e.quantization > 0.0:
            q = e.quantization
            cum = st.residual + np.cumsum(out, axis=0)
            counts = np.floor(cum / q)
            out = np.diff(counts, axis=0, prepend=np.zeros((1, 3))) * q
            st.residual = cum[-1] - counts[-1] * q
        return out, sat
