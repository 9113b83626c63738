"""Allan deviation of IMU data, and the noise terms read off it.

The overlapping Allan deviation of a rate signal sampled at interval ``tau0`` from its
integral (angle or velocity): ``AVAR(m tau0) = sum (th[k+2m] - 2 th[k+m] + th[k])^2 /
(2 (m tau0)^2 (N - 2m))``. Cross-checked against allantools in the tests.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["AllanResult", "allan_deviation", "read_noise_terms"]

_FLOOR = float(np.sqrt(2.0 * np.log(2.0) / np.pi))  # 0.664


@dataclass
class AllanResult:
    """Averaging times (s), Allan deviations (rate units) and the number of terms behind
    each (N - 2m), from which confidence intervals follow."""

    tau: np.ndarray
    adev: np.ndarray
    n_terms: np.ndarray


def allan_deviation(
    increments: np.ndarray, tau0: float, *, points_per_decade: int = 10, min_terms: int = 10
) -> AllanResult:
    """Overlapping Allan deviation of one axis from its increments.

    Parameters
    ----------
    increments:
        (N,) angle (rad) or velocity (m/s) increments of consecutive intervals.
    tau0:
        Interval length, s.
    points_per_decade:
        Density of the log-spaced averaging times.
    min_terms:
        Averaging times leaving fewer terms than this are not computed.
    """
    x = np.asarray(increments, dtype=float)
    theta = np.concatenate([[0.0], np.cumsum(x)])
    n = len(x)
    m_max = max(1, (n - min_terms) // 2)
    ms = np.unique(np.round(np.logspace(0, np.log10(m_max), int(np.log10(m_max) * points_per_decade) + 1)))
    ms = ms.astype(np.int64)
    tau = ms * tau0
    adev = np.empty(len(ms))
    terms = np.empty(len(ms), dtype=np.int64)
    for i, m in enumerate(ms):
        d = theta[2 * m :] - 2.0 * theta[m:-m] + theta[: -2 * m]
        adev[i] = np.sqrt(np.mean(d * d) / (2.0 * (m * tau0) ** 2))
        terms[i] = len(d)
    return AllanResult(tau, adev, terms)


def _gm_avar(T: np.ndarray, tau_c: float) -> np.ndarray:
    """Allan variance of a unit-variance first-order Gauss-Markov process."""
    x = T / tau_c
    return (2.0 / x) * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))


def read_noise_terms(result: AllanResult, tau_c: float | None = None) -> dict[str, float]:
    """Fit white noise N, Gauss-Markov bias instability and rate random walk K to an
    Allan deviation curve.

    The Allan variance is linear in the squared coefficients,
    ``AVAR(T) = N^2 / T + sigma^2 g(T / tau_c) + K^2 T / 3``, so for each correlation time
    (given, or searched on a log grid) a non-negative weighted least-squares fit gives
    them; each point is weighted by its expected relative uncertainty, ``sqrt(terms/m)``.

    Returns
    -------
    dict with ``random_walk`` (N, units per sqrt(s)), ``bias_instability`` (B, the
    Allan-floor convention: 0.664 B is the Gauss-Markov peak), ``gm_sigma``, ``tau_c``
    and ``rate_random_walk`` (K).
    """
    from scipy.optimize import nnls

    T = result.tau
    avar = result.adev**2
    m = np.maximum(T / T[0], 1.0)
    w = np.sqrt(result.n_terms / m) / avar
    grid = [tau_c] if tau_c is not None else list(np.logspace(np.log10(T[0]) + 0.3, np.log10(T[-1]), 40))
    best: tuple[float, np.ndarray, float] | None = None
    for tc in grid:
        A = np.column_stack([1.0 / T, _gm_avar(T, tc), T / 3.0]) * w[:, None]
        coef, rnorm = nnls(A, avar * w)
        if best is None or rnorm < best[0]:
            best = (rnorm, coef, tc)
    assert best is not None
    _, coef, tc = best
    sigma = float(np.sqrt(coef[1]))
    peak = float(np.sqrt(_gm_avar(np.linspace(0.5, 6.0, 20001) * tc, tc).max()))
    return {
        "random_walk": float(np.sqrt(coef[0])),
        "gm_sigma": sigma,
        "tau_c": float(tc),
        "bias_instability": sigma * peak / _FLOOR,
        "rate_random_walk": float(np.sqrt(coef[2])),
    }
