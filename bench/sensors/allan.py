"""Allan deviation of IMU data, and the IEEE noise terms fitted to it.

The overlapping Allan deviation of a rate signal sampled at interval ``tau0`` from its
integral (angle or velocity): ``AVAR(m tau0) = sum (th[k+2m] - 2 th[k+m] + th[k])^2 /
(2 (m tau0)^2 (N - 2m))``. Cross-checked against allantools in the tests.

:func:`fit_noise_terms` fits the terms of IEEE Std 952/1554 to the Allan variance, each
as its own power of the averaging time T:

============================  ===================  =====================
term                          Allan variance       ADEV slope
============================  ===================  =====================
quantization Q                ``3 Q^2 / T^2``      -1
angle/velocity random walk N  ``N^2 / T``          -1/2
bias instability B            ``0.664^2 B^2``      0 (flicker floor)
rate random walk K            ``K^2 T / 3``        +1/2
rate ramp R                   ``R^2 T^2 / 2``      +1
============================  ===================  =====================

The bias instability is either the flicker floor above or, as the bench's IMU model
realises it, a first-order Gauss-Markov process of correlation time ``tau_c`` whose
Allan-deviation peak (at about 1.89 ``tau_c``) is ``0.664 B``; the fit tries both and
keeps the better. The variance is linear in the squared coefficients, so each candidate
is a non-negative weighted least-squares fit; a point's weight is the inverse of its
relative uncertainty, from the number of independent clusters ``N / m`` behind it.

A term is *resolved* when it dominates the fitted curve (the largest share of the
variance) over at least half a decade (a factor 3) of well-determined averaging times (at
least ``min_clusters`` clusters; a flicker floor: a decade, less is only the bend between
two slopes); its ``tau_range`` is where it does. A rise (rate random walk, rate ramp) that
runs to the end of the log counts only after a resolved bias instability: before one, it
may be the rising side of a bias instability beyond the log. An unresolved term gets
an upper bound instead: no term can exceed the measured curve (plus two sigma) at any
averaging time. A Gauss-Markov bias instability counts only when the curve shows its
peak; on its tails it is indistinguishable from random walks.

:func:`bench.sensors.allan_humps.find_humps` finds what no sum of these terms makes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "AllanResult",
    "allan_deviation",
    "TERMS",
    "TermFit",
    "NoiseFit",
    "fit_noise_terms",
    "read_noise_terms",
]

_FLOOR = float(np.sqrt(2.0 * np.log(2.0) / np.pi))  # 0.664

#: The IEEE terms in order of their slope, with that ADEV slope.
TERMS: dict[str, float] = {
    "quantization": -1.0,
    "random_walk": -0.5,
    "bias_instability": 0.0,
    "rate_random_walk": 0.5,
    "rate_ramp": 1.0,
}
_B = 2  # index of the bias instability
_MIN_SPAN = 3.0  # a term dominating over less than half a decade of averaging time is not resolved
_FIRM_CLUSTERS = 50  # clusters of the points that must show a Gauss-Markov peak's fall
_MIN_SPAN_FLOOR = 10.0  # a flicker floor over less than a decade is the bend between two slopes
_MODEL_FLOOR = 0.02  # relative variance misfit tolerated at every point (model error)


@dataclass
class AllanResult:
    """Averaging times (s), Allan deviations (rate units) and the number of terms behind
    each (N - 2m), from which confidence intervals follow."""

    tau: np.ndarray
    adev: np.ndarray
    n_terms: np.ndarray

    @property
    def clusters(self) -> np.ndarray:
        """Independent (non-overlapping) clusters behind each point, ``N // m``."""
        m = np.maximum(np.round(self.tau / self.tau[0]), 1.0)
        return (self.n_terms + 2 * m) // m

    @property
    def rel_sigma(self) -> np.ndarray:
        """Relative 1-sigma uncertainty of each ADEV point, ``1 / sqrt(2 (K - 1))``."""
        return 1.0 / np.sqrt(2.0 * np.maximum(self.clusters - 1, 1))


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
    buf = np.empty(len(theta))
    for i, m in enumerate(ms):
        k = len(theta) - 2 * m
        d = buf[:k]
        np.subtract(theta[2 * m :], theta[m:-m], out=d)
        np.subtract(d, theta[m:-m], out=d)
        np.add(d, theta[:k], out=d)
        np.square(d, out=d)  # not np.dot: a threaded BLAS call stalls on a busy machine
        adev[i] = math.sqrt(float(d.sum()) / k / (2.0 * (m * tau0) ** 2))
        terms[i] = k
    return AllanResult(tau, adev, terms)


def _gm_avar(T: np.ndarray, tau_c: float) -> np.ndarray:
    """Allan variance of a unit-variance first-order Gauss-Markov process."""
    x = np.asarray(T, dtype=float) / tau_c
    return (2.0 / x) * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))


_GM_PEAK = float(np.sqrt(_gm_avar(np.linspace(0.5, 6.0, 20001), 1.0).max()))  # 0.6175 at T = 1.89 tau_c
_GM_PEAK_AT = 1.8926


def _basis(T: np.ndarray, tau_c: float | None) -> np.ndarray:
    """(len(T), 5) Allan variance of each term with a unit coefficient."""
    b = np.full_like(T, _FLOOR**2) if tau_c is None else (_FLOOR / _GM_PEAK) ** 2 * _gm_avar(T, tau_c)
    return np.column_stack([3.0 / T**2, 1.0 / T, b, T / 3.0, T**2 / 2.0])


@dataclass(frozen=True)
class TermFit:
    """One fitted term.

    ``value`` is the coefficient in the signal's units (quantization: rad or m/s;
    random walk: per sqrt(s); bias instability: rate; rate random walk: rate per
    sqrt(s); rate ramp: rate per s). ``resolved`` says whether the curve shows it;
    ``tau_range`` is where it dominates the fit, ``bound`` the largest value the curve
    allows (the figure to quote when it is not resolved), ``why`` what keeps a term that
    dominates somewhere from counting as resolved.
    """

    name: str
    value: float
    resolved: bool
    tau_range: tuple[float, float] | None
    bound: float
    why: str = ""


@dataclass
class NoiseFit:
    """The fitted terms of one axis and how well they fit.

    Attributes
    ----------
    terms: name -> :class:`TermFit`, in the order of :data:`TERMS`.
    tau_c: correlation time of a Gauss-Markov bias instability (None: flicker floor).
    rms_log10: RMS of ``log10(measured / fitted ADEV)`` over the points used.
    tau_used: shortest and longest averaging time used by the fit, s.
    tau_well: the same for the well-determined points (resolution and ranges).
    excluded: averaging-time ranges left out of the fit (humps).
    """

    terms: dict[str, TermFit]
    tau_c: float | None
    rms_log10: float
    tau_used: tuple[float, float]
    tau_well: tuple[float, float]
    excluded: list[tuple[float, float]] = field(default_factory=list)
    coefficients: np.ndarray = field(default_factory=lambda: np.zeros(5))

    def adev(self, tau: np.ndarray) -> np.ndarray:
        """The fitted Allan deviation at ``tau``."""
        tau = np.asarray(tau, dtype=float)
        return np.sqrt(_basis(tau, self.tau_c) @ self.coefficients)


def _nnls_pass(F: np.ndarray, a: np.ndarray, sig: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Non-negative coefficients minimising ``sum(((F c - a) / (sig ref))^2)``."""
    from scipy.optimize import nnls

    A = F / (sig * ref)[:, None]
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0.0] = 1.0
    c, _ = nnls(A / scale, a / (sig * ref))
    return c / scale


def _solve(T: np.ndarray, a: np.ndarray, sig: np.ndarray, tau_c: float | None) -> tuple[float, np.ndarray]:
    """The five coefficients for one bias-instability shape, and their misfit score.

    Two reweighted least-squares fits: residuals relative to the model (the unbiased
    choice for scattered variances) and relative to the geometric mean of model and
    measurement (the linearised log misfit, which cannot trade a large overshoot at some
    points for a better fit at others). The first is kept unless its log misfit is much
    worse, which happens only when the curve is not a sum of the terms. The score is
    ``sum((ln(model / measured) / sigma)^2)``.
    """
    F = _basis(T, tau_c)
    tiny = np.finfo(float).tiny

    def run(kind: str) -> tuple[float, np.ndarray]:
        ref = a
        for _ in range(3):
            c = _nnls_pass(F, a, sig, ref)
            m = np.maximum(F @ c, tiny)
            ref = m if kind == "model" else np.sqrt(a * m)
        return float(np.sum((np.log(m / a) / sig) ** 2)), c

    unbiased, robust = run("model"), run("log")
    return unbiased if unbiased[0] <= 1.5 * robust[0] + 0.01 * len(T) else robust


def _gm_shows(tau_c: float | None, c: np.ndarray, firm: np.ndarray, exclude: Sequence[tuple[float, float]]) -> bool:
    """A Gauss-Markov bias instability counts only where the curve shows its peak: fitted
    points a factor 3 to 6 away on both sides of it (where its ADEV has fallen to 0.8-0.6
    of the peak) with enough clusters to see that fall (``firm``: 50, a 10 % ADEV
    uncertainty), nothing left out within a factor 6, and the process the largest term
    at the point nearest to it."""
    if tau_c is None or c[_B] == 0.0:
        return True
    tp = _GM_PEAK_AT * tau_c
    if any(lo <= 6.0 * tp and hi >= tp / 6.0 for lo, hi in exclude):
        return False
    if not np.any((firm >= tp / 6.0) & (firm <= tp / 3.0)) or not np.any((firm >= 3.0 * tp) & (firm <= 6.0 * tp)):
        return False
    near = firm[int(np.argmin(np.abs(np.log(firm / tp))))]
    return int(np.argmax(_basis(np.array([near]), tau_c)[0] * c)) == _B


def fit_noise_terms(
    result: AllanResult,
    *,
    tau_c: float | None = None,
    exclude: Sequence[tuple[float, float]] = (),
    min_clusters: int = 10,
) -> NoiseFit:
    """Fit quantization, random walk, bias instability, rate random walk and rate ramp.

    Parameters
    ----------
    result:
        The Allan deviation of one axis.
    tau_c:
        Correlation time of the bias instability when known; otherwise the fit tries a
        flicker floor and Gauss-Markov processes over the whole averaging-time range.
    exclude:
        Averaging-time ranges (s) to leave out (humps that no term makes).
    min_clusters:
        Points with fewer independent clusters count as fitted but not as evidence
        that a term dominates.
    """
    from scipy.optimize import minimize_scalar

    clusters = result.clusters
    use = clusters >= 3
    for lo, hi in exclude:
        use &= (result.tau < lo) | (result.tau > hi)
    T, a, clusters = result.tau[use], result.adev[use] ** 2, clusters[use]
    names = list(TERMS)
    if len(T) < 3:
        empty = {n: TermFit(n, 0.0, False, None, math.inf) for n in names}
        span = (float(T[0]), float(T[-1])) if len(T) else (math.nan, math.nan)
        return NoiseFit(empty, None, math.nan, span, span, list(exclude))
    sig = np.sqrt(2.0 / np.maximum(clusters - 1, 1) + _MODEL_FLOOR**2)
    well_mask = clusters >= min_clusters
    well = T[well_mask]
    firm = T[clusters >= _FIRM_CLUSTERS]

    def chi2_of(tc: float | None) -> float:
        chi2, c = _solve(T, a, sig, tc)
        return chi2 if _gm_shows(tc, c, firm, exclude) else 1e300

    if tau_c is not None:
        best_tc: float | None = float(tau_c)
    else:
        grid = np.linspace(np.log10(T[0]), np.log10(T[-1]) + 0.5, 41)
        scores = [(chi2_of(None), None)] + [(chi2_of(10**g), float(10**g)) for g in grid]
        best_chi2, best_tc = min(scores, key=lambda s: s[0])  # the flicker floor is always valid
        if best_tc is not None:
            step = grid[1] - grid[0]
            lg = math.log10(best_tc)
            r = minimize_scalar(
                lambda x: chi2_of(10**x), bounds=(lg - step, lg + step), method="bounded", options={"xatol": 1e-3}
            )
            if r.fun <= best_chi2:
                best_tc = float(10**r.x)
    _, c = _solve(T, a, sig, best_tc)
    F = _basis(T, best_tc)
    model = np.maximum(F @ c, np.finfo(float).tiny)
    share = F * c / model[:, None]
    top = np.argmax(share, axis=1)
    # no term alone may exceed the measured variance (plus two sigma) anywhere
    pts = well_mask if well_mask.any() else np.ones(len(T), dtype=bool)
    bounds = np.min((a * (1.0 + 2.0 * sig))[pts][:, None] / _basis(T[pts], None), axis=0)
    terms = {}
    for j, n in enumerate(names):
        sel = (top == j) & well_mask & (c[j] > 0.0)
        rng = (float(T[sel].min()), float(T[sel].max())) if sel.any() else None
        span = _MIN_SPAN_FLOOR if (n == "bias_instability" and best_tc is None) else _MIN_SPAN
        why = ""
        if rng is not None and rng[1] < span * rng[0]:
            why = f"dominates only over {rng[0]:.3g}-{rng[1]:.3g} s"
        elif rng is not None and n in ("rate_random_walk", "rate_ramp") and rng[1] >= well[-1] \
                and not terms["bias_instability"].resolved:
            why = (f"the rise from {rng[0]:.3g} s to the end of the log could also be the onset of a bias "
                   "instability beyond it (no floor or peak before it)")
        resolved = rng is not None and not why
        terms[n] = TermFit(n, float(math.sqrt(c[j])), resolved, rng if resolved else None, float(math.sqrt(bounds[j])),
                           why)
    pts = well_mask if well_mask.any() else np.ones(len(T), dtype=bool)
    rms = float(np.sqrt(np.mean((0.5 * np.log10(a[pts] / model[pts])) ** 2)))
    span_well = (float(well[0]), float(well[-1])) if len(well) else (math.nan, math.nan)
    return NoiseFit(terms, best_tc, rms, (float(T[0]), float(T[-1])), span_well, list(exclude), c)


def read_noise_terms(result: AllanResult, tau_c: float | None = None) -> dict[str, float]:
    """The fitted coefficients as a dict (``random_walk``, ``bias_instability``,
    ``gm_sigma``, ``tau_c``, ``rate_random_walk``, ``quantization``, ``rate_ramp``),
    whether resolved or not; see :func:`fit_noise_terms`."""
    fit = fit_noise_terms(result, tau_c=tau_c)
    out = {n: t.value for n, t in fit.terms.items()}
    out["tau_c"] = float(fit.tau_c) if fit.tau_c is not None else math.inf
    out["gm_sigma"] = out["bias_instability"] * _FLOOR / _GM_PEAK if fit.tau_c is not None else 0.0
    return out
