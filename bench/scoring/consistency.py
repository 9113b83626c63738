"""Consistency: are the DUT's own sigmas (NAV_QUALITY) honest about its errors?

At each epoch with both a solution and a quality record (same time of validity), the
normalised estimation error squared (NEES) of

* ``position``: sum over E, N, U of (error / sigma)^2, 3 degrees of freedom;
* ``velocity``: the same with the velocity sigmas, 3 degrees of freedom;
* ``heading``: (heading error / heading sigma)^2, 1 degree of freedom

(the sigmas are taken as uncorrelated, as the ICD carries no correlations). For a
consistent estimator NEES follows a chi-square law with those degrees of freedom.
Statistics over a window:

* ``nees`` -- mean NEES divided by the degrees of freedom (1 when consistent);
* ``within`` -- fraction of epochs inside the two-sided chi-square interval of
  probability ``confidence`` (ideally ``confidence``);
* ``above`` -- fraction above its upper bound (the DUT is over-confident);
* ``below`` -- fraction below its lower bound (the DUT is pessimistic).

A zero sigma with a non-zero error is an infinite NEES (counted above the bound).

For a criterion judged over the Monte Carlo runs (``monte_carlo = { anees = ... }``,
:mod:`bench.acceptance.anees`) the details also carry ``nees_grid``: the NEES per degree of
freedom *sampled* on a fixed grid of bench time (:func:`nees_grid`, 1 s), the epoch at or
just after each grid time inside the window -- sampled, not averaged, so that each sample
keeps its chi-square law; the grid is the same in every run, so the runs line up.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.stats import chi2

from bench.scoring.accuracy import select
from bench.scoring.align import NavErrors
from bench.scoring.data import NoDataError
from bench.scoring.windows import Window

__all__ = [
    "CONSISTENCY_QUANTITIES", "CONSISTENCY_STATS", "nees_series", "nees_grid", "consistency_value", "chi2_bounds",
    "GRID_NS",
]

#: quantity -> degrees of freedom
CONSISTENCY_QUANTITIES = {"position": 3, "velocity": 3, "heading": 1}
CONSISTENCY_STATS = ("nees", "within", "above", "below")
#: The grid of the sampled NEES series (bench time), ns.
GRID_NS = 1_000_000_000


def chi2_bounds(dof: int, confidence: float) -> tuple[float, float]:
    """Two-sided interval of a chi-square variable with ``dof`` degrees of freedom."""
    a = (1.0 - confidence) / 2.0
    return float(chi2.ppf(a, dof)), float(chi2.ppf(1.0 - a, dof))


def _ratio_sq(err: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(sigma > 0, err / np.where(sigma > 0, sigma, 1.0), np.where(err == 0, 0.0, np.inf))
    return r * r


def nees_series(errors: NavErrors, quality: np.ndarray | None, quantity: str) -> tuple[np.ndarray, np.ndarray]:
    """``(has_quality, nees)`` per epoch of ``errors`` (nees NaN where no quality record)."""
    if quality is None or len(quality) == 0:
        raise NoDataError("the recording holds no DUT quality output (/dut/nav_quality)")
    qt = quality["t_ns"]
    order = np.argsort(qt, kind="stable")
    pos = np.searchsorted(qt[order], errors.t_ns)
    pos = np.clip(pos, 0, len(qt) - 1)
    match = qt[order][pos] == errors.t_ns
    q = quality[order][pos]
    if quantity == "position":
        nees = np.sum(_ratio_sq(errors.pos, q["sigma_pos"]), axis=1)
    elif quantity == "velocity":
        nees = np.sum(_ratio_sq(errors.vel, q["sigma_vel"]), axis=1)
    else:
        nees = _ratio_sq(errors.att[:, 0], q["sigma_att"][:, 0])
    return match, np.where(match, nees, np.nan)


def _sig(x: float) -> float:
    """``x`` to 6 significant digits (what a record keeps of a sample; inf stays inf)."""
    return float(f"{x:.6g}") if np.isfinite(x) else float(x)


def nees_grid(t_ns: np.ndarray, nees_per_dof: np.ndarray, step_ns: int = GRID_NS) -> dict[str, Any]:
    """The NEES per degree of freedom of the selected epochs ``t_ns`` (sorted) sampled on
    the grid ``k * step_ns`` of bench time: at each grid time from the first epoch's to
    the last's, the first epoch in ``[t_k, t_k + step)``, or None where the window has
    none (a gap, an epoch outside the window). ``{"start_s", "step_s", "values"}``: the
    grid time of ``values[0]`` and the step, s; an infinite sample (a zero sigma) stays
    infinite."""
    if len(t_ns) == 0:
        return {"start_s": 0.0, "step_s": step_ns * 1e-9, "values": []}
    k0 = -(-int(t_ns[0]) // step_ns)  # ceil: the first grid time at or after the first epoch
    k1 = int(t_ns[-1]) // step_ns
    grid = np.arange(k0, k1 + 1, dtype=np.int64) * step_ns
    j = np.searchsorted(t_ns, grid, side="left")
    ok = j < len(t_ns)
    ok[ok] &= t_ns[j[ok]] < grid[ok] + step_ns
    values: list[float | None] = [None] * len(grid)
    for i in np.flatnonzero(ok):
        values[i] = _sig(float(nees_per_dof[j[i]]))
    return {"start_s": k0 * step_ns * 1e-9, "step_s": step_ns * 1e-9, "values": values}


def consistency_value(
    quantity: str,
    stat: str,
    errors: NavErrors,
    quality: np.ndarray | None,
    window: Window,
    confidence: float,
    grid_ns: int | None = None,
) -> tuple[float, dict[str, Any]]:
    """Value of ``consistency.<quantity>.<stat>`` over ``window``; with ``grid_ns`` the
    details carry the sampled series ``nees_grid`` (:func:`nees_grid`)."""
    idx = select(errors, window)
    match, nees = nees_series(errors, quality, quantity)
    idx = idx[match[idx]]
    if len(idx) == 0:
        raise NoDataError(f"no DUT epoch in window {window.text()} has a matching NAV_QUALITY record")
    v = nees[idx]
    dof = CONSISTENCY_QUANTITIES[quantity]
    lo, hi = chi2_bounds(dof, confidence)
    details: dict[str, Any] = {"epochs": len(idx), "dof": dof, "confidence": confidence, "lower": lo, "upper": hi}
    if grid_ns is not None:
        details["nees_grid"] = nees_grid(errors.t_ns[idx], v / dof, grid_ns)
    if stat == "nees":
        return float(np.mean(v)) / dof, details
    if stat == "within":
        return float(np.mean((v >= lo) & (v <= hi))), details
    if stat == "above":
        return float(np.mean(v > hi)), details
    if stat == "below":
        return float(np.mean(v < lo)), details
    raise KeyError(stat)
