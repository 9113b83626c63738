"""Robust fitting of recorded tracks: glitch rejection, stationary holds and a fit report.

Real ground truth is not a smooth curve plus white noise: a reference receiver jumps by a
metre when it changes its solution, and at a standstill its positions wander by decimetres
from sample to sample. A least-squares spline follows both, and the yaw rate and forward
acceleration synthesized from it show tens of deg/s where the car did not turn. So:

* **Robust smoothing.** The positions are fitted by an iteratively reweighted quintic
  smoothing spline: a Huber weight on each sample's 3-D residual (full weight within
  ``huber`` x ``smoothing``, falling as 1/r beyond) lets a glitch pull the curve less
  than a good sample does; then samples whose residual still exceeds ``reject`` x
  ``smoothing`` are dropped, the worst of each neighbourhood (two samples either side)
  at a time, refitting in between. A clean
  track's residuals stay within a few ``smoothing``, so nothing is dropped from it.
* **Stationary holds.** Where the speed of the data (the least-squares slope of the
  positions over a window of ``stop_time``) stays below ``stop_speed`` for at least
  ``stop_time``, the vehicle is taken as stopped: the fitted spline is exactly constant
  there (at the median of the samples), so velocity and acceleration are zero and the
  heading is held; an IMU synthesized from it shows no rotation.
* **Turn limit.** A heading derived from the direction of travel changes by at most the
  distance travelled over ``turn_radius`` (:func:`limit_turn`): a road vehicle turns
  only as it moves, so the swings of a slow, noisy direction of travel are noise.
* **A report** (:class:`FitReport`) per fit: the RMS and largest residual, every rejected
  sample with its time and size, the stationary intervals with their spread.

All functions are pure: arrays in, arrays and records out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline, make_splrep

__all__ = [
    "TrackFit",
    "Rejected",
    "Stationary",
    "FitReport",
    "fit_spline",
    "stationary_intervals",
    "robust_position_fit",
    "hold",
    "hold_ramp",
    "limit_turn",
    "window_speed",
]


@dataclass(frozen=True)
class TrackFit:
    """Settings of a track's fit; the defaults are those of a ``[track]`` table, chosen on
    real drives (``benchmarks/track_berlin_fit.py``).

    Attributes
    ----------
    smoothing: 1-sigma position noise per axis, m (0: interpolate every sample exactly,
        with no reweighting, rejection or holds).
    attitude_smoothing: 1-sigma of given attitude, or of the derived heading, rad (0:
        given attitude interpolated, derived heading smoothed to 0.2 deg).
    min_speed: below this horizontal speed (m/s) the derived heading is held.
    huber: Huber threshold of the position reweighting, in units of ``smoothing`` (0: off).
    reject: residual beyond which a sample is rejected, in units of ``smoothing`` (0: off).
    stop_speed: the data's speed (m/s) below which the vehicle is stopped (0: no holds).
    stop_time: how long (s) it must stay below ``stop_speed``; also the window of the
        data's speed.
    turn_radius: the derived heading turns by at most 1 rad per this many metres
        travelled, m (5 m: tighter than a car turns; 0: no limit).
    """

    smoothing: float = 0.05
    attitude_smoothing: float = 0.0
    min_speed: float = 0.5
    huber: float = 4.0
    reject: float = 12.0
    stop_speed: float = 0.3
    stop_time: float = 1.0
    turn_radius: float = 5.0

    def kwargs(self) -> dict[str, float]:
        """The settings as keyword arguments of :class:`~bench.scenario.track.SampledTrajectory`."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class Rejected:
    """A sample left out of the fit: its time (s from the track's start) and its distance
    from the fitted curve, m."""

    t: float
    size_m: float


@dataclass(frozen=True)
class Stationary:
    """A stop (s from the track's start): ``start``-``end`` where the data's speed stays
    below the threshold; the fit stands exactly still over ``still_from``-``still_to``
    (joining the moving curve over the rest); ``spread_m`` is the largest distance of a
    sample in the stop from the fit."""

    start: float
    end: float
    still_from: float
    still_to: float
    spread_m: float


@dataclass(frozen=True)
class FitReport:
    """How a track's fit meets its samples (residuals are 3-D distances, m; rejected
    samples excluded from the RMS and maximum, which they would dominate)."""

    source: str
    samples: int
    smoothing_m: float
    rms_m: float
    max_m: float
    t_max: float
    rejected: tuple[Rejected, ...] = ()
    stationary: tuple[Stationary, ...] = ()

    def lines(self) -> list[str]:
        """The report as text lines, for a terminal."""
        out = [
            f"track fit {self.source or '(samples)'}: {self.samples} samples, smoothing "
            f"{self.smoothing_m * 100:g} cm; residual RMS {self.rms_m:.3f} m, max {self.max_m:.3f} m "
            f"at {self.t_max:.2f} s",
            f"  rejected {len(self.rejected)} sample(s)"
            + (": " + ", ".join(f"{r.t:.2f} s ({r.size_m:.2f} m)" for r in self.rejected) if self.rejected else ""),
            f"  stationary {len(self.stationary)} interval(s)"
            + (": " + ", ".join(f"{s.start:.2f}-{s.end:.2f} s (still {s.still_from:.2f}-{s.still_to:.2f} s, "
                                f"spread {s.spread_m:.2f} m)"
                                for s in self.stationary) if self.stationary else ""),
        ]
        return out

    def to_json(self) -> dict:
        """The report as plain JSON-able values."""
        return {
            "source": self.source,
            "samples": self.samples,
            "smoothing_m": self.smoothing_m,
            "rms_m": self.rms_m,
            "max_m": self.max_m,
            "t_max": self.t_max,
            "rejected": [{"t": r.t, "size_m": r.size_m} for r in self.rejected],
            "stationary": [{"start": s.start, "end": s.end, "still_from": s.still_from, "still_to": s.still_to,
                            "spread_m": s.spread_m} for s in self.stationary],
        }


def fit_spline(t: np.ndarray, y: np.ndarray, sigma: float, w: np.ndarray | None = None) -> BSpline:
    """Quintic spline through (t, y) (N,), smoothing to residual ``sigma`` (0 interpolates);
    ``w`` (N,) scales each residual (weight 1: the sample's noise is ``sigma``)."""
    if sigma <= 0.0:
        return make_interp_spline(t, y, k=5)
    return make_splrep(t, y, w=w, k=5, s=len(t) * sigma**2)


def window_speed(t: np.ndarray, xyz: np.ndarray, window: float) -> np.ndarray:
    """(N,) speed of the data, m/s: the least-squares slope of the positions ``xyz`` (N, 3)
    over the samples within ``window`` / 2 of each sample's time ``t`` (N,)."""
    half = window / 2.0 + 1e-9
    lo = np.searchsorted(t, t - half, side="left")
    hi = np.searchsorted(t, t + half, side="right")
    c = np.concatenate([[0.0], np.cumsum(t)])
    c2 = np.concatenate([[0.0], np.cumsum(t * t)])
    cp = np.vstack([np.zeros(3), np.cumsum(xyz, axis=0)])
    ctp = np.vstack([np.zeros(3), np.cumsum(t[:, None] * xyz, axis=0)])
    n = (hi - lo).astype(float)
    st, stt = c[hi] - c[lo], c2[hi] - c2[lo]
    sp, stp = cp[hi] - cp[lo], ctp[hi] - ctp[lo]
    den = stt - st * st / n
    slope = (stp - st[:, None] * sp / n[:, None]) / np.where(den > 0.0, den, np.inf)[:, None]
    return np.linalg.norm(slope, axis=1)


def stationary_intervals(t: np.ndarray, xyz: np.ndarray, stop_speed: float, stop_time: float) -> list[tuple[int, int]]:
    """Runs of samples ``[i, j]`` (inclusive indices) where the data's speed over a window
    of ``stop_time`` stays below ``stop_speed`` (m/s) for at least ``stop_time`` (s)."""
    if stop_speed <= 0.0 or stop_time <= 0.0 or len(t) < 3:
        return []
    slow = window_speed(t, xyz, stop_time) < stop_speed
    runs: list[tuple[int, int]] = []
    i = 0
    while i < len(t):
        if not slow[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(t) and slow[j + 1]:
            j += 1
        if t[j] - t[i] >= stop_time:
            runs.append((i, j))
        i = j + 1
    return runs


def limit_turn(t: np.ndarray, psi: np.ndarray, speed: np.ndarray, radius: float) -> np.ndarray:
    """(N,) the heading ``psi`` (N, rad, unwrapped) at times ``t`` (N,) with each step's
    change limited to the distance travelled over ``radius`` (m) (``speed`` (N,),
    m/s): a road vehicle turns only as it moves, and no tighter than its minimum radius, so
    the swings of a direction of travel derived from a slow, noisy track are noise. The
    mean of a forward and a backward pass (each limited, so their mean is too; no lag)."""
    step = 0.5 / radius * (speed[1:] + speed[:-1]) * np.diff(t)

    def one_way(p: np.ndarray, s: np.ndarray) -> np.ndarray:
        out = p.copy()
        for i in range(1, len(p)):
            out[i] = out[i - 1] + np.clip(p[i] - out[i - 1], -s[i - 1], s[i - 1])
        return out

    return 0.5 * (one_way(psi, step) + one_way(psi[::-1], step[::-1])[::-1])


def hold(spline: BSpline, start: float, end: float, value: float, ramp: float) -> BSpline:
    """The spline made exactly ``value`` on ``[start + ramp, end - ramp]`` and unchanged
    outside ``[start, end]``. Knots are inserted (which changes nothing) every ``ramp`` / k
    over the first and last ``ramp`` of the interval; then every coefficient whose basis
    function reaches into the inner interval (its support lies within ``[start, end]``)
    is set to ``value``. The result is a spline of the same degree, as smooth as before,
    that joins the original over the ramps."""
    k = spline.k
    lo, hi = spline.t[k], spline.t[-k - 1]
    for x in sorted({*(start + ramp * i / k for i in range(k + 1)), *(end - ramp * i / k for i in range(k + 1))}):
        if lo < x < hi and not np.any(np.isclose(spline.t, x, rtol=0.0, atol=1e-9)):
            spline = spline.insert_knot(x)
    tk = spline.t
    c = spline.c.copy()
    j = np.arange(len(c))
    c[(tk[j + k + 1] > start + ramp) & (tk[j] < end - ramp)] = value
    return BSpline(tk, c, k, extrapolate=spline.extrapolate)


def hold_ramp(start: float, end: float) -> float:
    """How long a hold on ``[start, end]`` takes to join the curve at either end, s: a
    quarter of the interval, at most 0.5 s."""
    return min(0.25 * (end - start), 0.5)


def robust_position_fit(
    t: np.ndarray,
    xyz: np.ndarray,
    sigma: float,
    *,
    huber: float,
    reject: float,
    stops: list[tuple[int, int]],
    max_iter: int = 8,
) -> tuple[list[BSpline], np.ndarray]:
    """Splines (one per axis) fitted robustly to positions ``xyz`` (N, 3) at times ``t``
    (N,), held constant over the stationary runs ``stops``; and the mask (N,) of the
    samples rejected. ``huber`` and ``reject`` are in units of ``sigma`` (0 switches the
    reweighting, or the rejection, off)."""
    y = xyz.copy()
    for i, j in stops:
        y[i : j + 1] = np.median(xyz[i : j + 1], axis=0)
    keep = np.ones(len(t), dtype=bool)
    h = np.ones(len(t))
    base = np.ones(len(t))
    for i, j in stops:  # held samples: the curve passes them within a tenth of sigma
        base[i : j + 1] = 10.0

    def fit() -> list[BSpline]:
        return [fit_spline(t[keep], y[keep, a], sigma, base[keep] * np.sqrt(h[keep])) for a in range(3)]

    def residual(splines: list[BSpline]) -> np.ndarray:
        return np.linalg.norm(np.stack([s(t) for s in splines], axis=-1) - y, axis=1)

    splines = fit()
    for _ in range(max_iter if huber > 0.0 else 0):
        r = residual(splines)
        h_new = np.where(r <= huber * sigma, 1.0, huber * sigma / np.maximum(r, 1e-300))
        if np.allclose(h_new, h, rtol=0.0, atol=1e-3):
            break
        h = h_new
        splines = fit()
    if reject > 0.0:
        while keep.sum() > 6:
            r = np.where(keep, residual(splines), 0.0)
            # the worst of each neighbourhood (two samples either side): a glitch pulls the
            # curve off its neighbours too, so they wait for the refit without it
            pad = np.pad(r, 2)
            peak = r >= np.max(np.lib.stride_tricks.sliding_window_view(pad, 5), axis=1)
            out = keep & peak & (r > reject * sigma)
            if not out.any() or keep.sum() - out.sum() < 6:
                break
            keep &= ~out
            splines = fit()
    for i, j in stops:
        splines = [hold(s, t[i], t[j], float(y[i, a]), hold_ramp(t[i], t[j])) for a, s in enumerate(splines)]
    return splines, ~keep
