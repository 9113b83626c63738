"""Noise processes shared by the sensor models, and the estimators that check them.

* :class:`WhiteNoise`: independent Gaussian samples of standard deviation ``sigma``.
* :class:`GaussMarkov`: first-order Gauss-Markov process ``dx/dt = -x/tau + w`` sampled at
  a fixed interval ``dt`` with its exact discretisation
  ``x_k = phi x_k-1 + sigma sqrt(1 - phi^2) w_k``, ``phi = exp(-dt/tau)``, so its
  stationary standard deviation is ``sigma`` and its autocorrelation ``exp(-|lag|/tau)``
  whatever ``dt`` is. It starts from its stationary distribution unless told otherwise.
* :class:`RandomWalk`: ``x_k = x_k-1 + q sqrt(dt) w_k`` (``q`` per square-root second).

Every process draws from the :class:`numpy.random.Generator` it is given (one named
stream per process, :func:`bench.rng.stream`) and carries its state between calls, so
``draw(n1)`` then ``draw(n2)`` returns exactly ``draw(n1 + n2)``: a sensor's output does
not depend on how the run is cut into windows.

Shapes: a process of dimension ``d`` (``sigma`` an array of shape (d,)) returns (n, d)
arrays; a scalar process returns (n,).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

__all__ = [
    "gauss_markov_filter",
    "WhiteNoise",
    "GaussMarkov",
    "RandomWalk",
    "sample_times",
    "period_ns",
    "autocovariance",
    "fit_markov",
]


def gauss_markov_filter(w: np.ndarray, phi: float, drive: float, x_prev: float) -> tuple[np.ndarray, float]:
    """``y_k = phi y_k-1 + drive w_k`` over one column ``w`` (n,), with ``y_-1 = x_prev``.

    Returns the filtered samples and the last state (``x_prev`` when ``w`` is empty).
    """
    if len(w) == 0:
        return np.empty(0), float(x_prev)
    y, _ = lfilter([drive], [1.0, -phi], w, zi=[phi * x_prev])
    return y, float(y[-1])


def _as_sigma(sigma: float | np.ndarray) -> tuple[np.ndarray, bool]:
    arr = np.atleast_1d(np.asarray(sigma, dtype=float))
    if np.any(arr < 0.0) or not np.all(np.isfinite(arr)):
        raise ValueError(f"a standard deviation must be finite and non-negative, found {sigma!r}")
    return arr, np.ndim(sigma) == 0


class WhiteNoise:
    """Independent N(0, sigma^2) samples.

    Parameters
    ----------
    sigma:
        Standard deviation, scalar or (d,).
    rng:
        The process's own generator.
    """

    def __init__(self, sigma: float | np.ndarray, rng: np.random.Generator):
        self.sigma, self._scalar = _as_sigma(sigma)
        self.rng = rng

    def draw(self, n: int) -> np.ndarray:
        """The next ``n`` samples, (n,) or (n, d)."""
        d = len(self.sigma)
        x = self.rng.standard_normal((n, d)) * self.sigma
        return x[:, 0] if self._scalar else x


class GaussMarkov:
    """First-order Gauss-Markov process at a fixed interval, exact discretisation.

    Parameters
    ----------
    sigma:
        Stationary standard deviation, scalar or (d,).
    tau:
        Correlation time, s (scalar or (d,)), positive.
    dt:
        Sample interval, s.
    rng:
        The process's own generator.
    x0:
        Initial state (before the first sample); drawn from N(0, sigma^2) when None.
    """

    def __init__(
        self,
        sigma: float | np.ndarray,
        tau: float | np.ndarray,
        dt: float,
        rng: np.random.Generator,
        x0: float | np.ndarray | None = None,
    ):
        self.sigma, self._scalar = _as_sigma(sigma)
        d = len(self.sigma)
        self.tau = np.broadcast_to(np.asarray(tau, dtype=float), (d,)).copy()
        if np.any(self.tau <= 0.0) or dt <= 0.0:
            raise ValueError(f"correlation time and interval must be positive, found tau {tau!r}, dt {dt!r}")
        self.dt = float(dt)
        self.rng = rng
        self.phi = np.exp(-self.dt / self.tau)
        self.drive = self.sigma * np.sqrt(1.0 - self.phi**2)
        if x0 is None:
            self.state = self.sigma * rng.standard_normal(d)
        else:
            self.state = np.broadcast_to(np.asarray(x0, dtype=float), (d,)).copy()

    def draw(self, n: int) -> np.ndarray:
        """The next ``n`` samples, (n,) or (n, d)."""
        d = len(self.sigma)
        w = self.rng.standard_normal((n, d))
        out = np.empty((n, d))
        for i in range(d):
            out[:, i], self.state[i] = gauss_markov_filter(w[:, i], self.phi[i], self.drive[i], self.state[i])
        return out[:, 0] if self._scalar else out


class RandomWalk:
    """``x_k = x_k-1 + q sqrt(dt) w_k``, starting at ``x0`` (0 by default).

    ``q`` is the random-walk coefficient in units per square-root second, scalar or (d,).
    """

    def __init__(self, q: float | np.ndarray, dt: float, rng: np.random.Generator, x0: float | np.ndarray = 0.0):
        self.q, self._scalar = _as_sigma(q)
        self.step = self.q * math.sqrt(dt)
        self.rng = rng
        self.state = np.broadcast_to(np.asarray(x0, dtype=float), (len(self.q),)).copy()

    def draw(self, n: int) -> np.ndarray:
        """The next ``n`` samples, (n,) or (n, d)."""
        steps = self.rng.standard_normal((n, len(self.q))) * self.step
        # summed on from the carried state, so any cut of the run adds in the same order
        x = np.cumsum(np.vstack([self.state[None, :], steps]), axis=0)[1:]
        if n:
            self.state = x[-1].copy()
        return x[:, 0] if self._scalar else x


# -- sample grids -------------------------------------------------------------------------
def period_ns(rate_hz: float) -> int:
    """Sample period in integer nanoseconds; the rate must divide a second into whole ns."""
    if not rate_hz > 0.0:
        raise ValueError(f"a rate must be positive, found {rate_hz}")
    period = 1e9 / rate_hz
    if abs(period - round(period)) > 1e-6:
        raise ValueError(f"rate {rate_hz:g} Hz does not give a whole number of nanoseconds per sample")
    return round(period)


def sample_times(period: int, t0_ns: int, t1_ns: int) -> np.ndarray:
    """Times ``k * period`` (int64 ns, k >= 1) within the window ``(t0_ns, t1_ns]``."""
    k0 = max(t0_ns // period + 1, 1)
    k1 = t1_ns // period
    return np.arange(k0, k1 + 1, dtype=np.int64) * period


# -- estimators (used by the statistical tests and by users checking a log) ----------------
def autocovariance(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Biased sample autocovariance of ``x`` (n,) at lags ``0..max_lag`` (FFT, mean removed)."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    n = len(x)
    size = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(x, size)
    acf = np.fft.irfft(f * np.conj(f), size)[: max_lag + 1]
    return acf / n


def fit_markov(x: np.ndarray, dt: float, max_lag: int | None = None) -> tuple[float, float, float]:
    """Split ``x`` (n,) into white noise plus a first-order Gauss-Markov process.

    The autocovariance of ``white + GM`` is ``s_w^2 + s_m^2`` at lag 0 and
    ``s_m^2 exp(-k dt / tau)`` at lags k >= 1; a straight-line fit of its logarithm over
    lags ``1..max_lag`` (default: where it first falls below a third of lag 1) gives
    ``s_m`` and ``tau``, and lag 0 gives ``s_w``.

    Returns
    -------
    (sigma_white, sigma_markov, tau):
        Standard deviations (units of ``x``) and the correlation time, s.
    """
    x = np.asarray(x, dtype=float)
    probe = max_lag or min(len(x) // 10, 100_000)
    c = autocovariance(x, probe)
    if max_lag is None:
        below = np.flatnonzero(c[1:] < c[1] / 3.0)
        max_lag = int(below[0]) + 1 if below.size else probe
        max_lag = max(max_lag, 2)
    lags = np.arange(1, max_lag + 1)
    vals = c[1 : max_lag + 1]
    ok = vals > 0.0
    if ok.sum() < 2:  # no correlated part to speak of: all white
        return math.sqrt(max(c[0], 0.0)), 0.0, math.nan
    slope, intercept = np.polyfit(lags[ok] * dt, np.log(vals[ok]), 1)
    tau = -1.0 / slope
    s_m2 = math.exp(intercept)
    s_w2 = max(c[0] - s_m2, 0.0)
    return math.sqrt(s_w2), math.sqrt(s_m2), tau
