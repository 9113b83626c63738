"""The Monte Carlo consistency test over the runs: ANEES against the chi-square band of N runs.

A criterion ``consistency.<quantity>.within`` (``above``, ``below``) with
``monte_carlo = { anees = c }`` is judged here, over the N runs of a variant, from the NEES
each run's details carry sampled on a 1 s grid of bench time
(:func:`bench.scoring.consistency.nees_grid`; per degree of freedom, the epoch at or just
after each grid time inside the criterion's window).

At each grid time covered by every run, the average of the runs' NEES per degree of
freedom (ANEES) is compared with the two-sided interval of probability ``c`` of the mean of
N independent draws (Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to
Tracking and Navigation*, 5.4). The runs are independent, so at each grid time this law
holds whatever the correlation of a run's errors in time: an error dominated by one slowly
varying draw per run, which a per-run band judges unfairly (a consistent filter spends
whole runs outside it), is judged fairly across the runs. The criterion's value is the
share of the grid times whose ANEES lies in (above, below) the band. N = 1 is the per-run
test on the sampled series.

The band is chi-square(N) / N, one degree of freedom per run whatever the quantity's
``dof``. A run's position or velocity NEES sums three squared normalised errors whose
correlation the ICD does not carry (NAV_QUALITY has one sigma per axis): a heading error
moves east and north together (over the 20 runs of S002 the runs' east and north position
errors correlate at 0.88 in magnitude), and such a sum is not chi-square(3): its law lies
between chi-square(3) / 3 (independent axes) and chi-square(1) (one error on every axis).
Over N runs the mean per degree of freedom is a weighted sum of N x dof squared normal
draws whose weights add up to 1 per run; its widest law, at both tails, is chi-square(N) /
N, so the band holds (a consistent DUT leaves it at most ``1 - c`` of the time) whatever the
correlation between the axes. With 3 independent axes the band of N x dof would be
narrower, but with the east and north errors correlated at 0.9 a consistent DUT would
leave its 95 % band 11 % of the time (tests/acceptance/test_anees.py).

Fewer than :data:`MIN_GRID_TIMES` grid times covered by every run is an error (the
statistic would mean nothing); a run without the sampled series (a record of an older
bench) is an error, never a verdict on fewer runs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import chi2

__all__ = ["MIN_GRID_TIMES", "AneesError", "AneesResult", "anees_band", "anees_test", "series_of"]

#: Fewest grid times covered by every run for the share in band to be judged.
MIN_GRID_TIMES = 10


class AneesError(ValueError):
    """The runs cannot be judged by ANEES (why in the message): the criterion is ERROR."""


@dataclass
class AneesResult:
    """The ANEES of N runs over the grid times every run covers."""

    runs: int
    dof: int
    confidence: float
    band: tuple[float, float]  # per degree of freedom
    step_s: float
    t_s: np.ndarray  # the grid times judged, s
    anees: np.ndarray  # per degree of freedom, at each of t_s
    left_out: int  # grid times of some run that not every run covers
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def within(self) -> float:
        lo, hi = self.band
        return float(np.mean((self.anees >= lo) & (self.anees <= hi)))

    @property
    def above(self) -> float:
        return float(np.mean(self.anees > self.band[1]))

    @property
    def below(self) -> float:
        return float(np.mean(self.anees < self.band[0]))

    @property
    def mean(self) -> float:
        return float(np.mean(self.anees))

    def share(self, stat: str) -> float:
        """The value of ``consistency.<q>.<stat>`` judged over the runs."""
        return {"within": self.within, "above": self.above, "below": self.below}[stat]

    def text(self, window: str = "") -> str:
        lo, hi = self.band
        n, k = self.runs, len(self.t_s)
        where = f" of window {window}" if window else ""
        pct = lambda x: f"{100 * x:.3g} %"  # noqa: E731
        out = (f"ANEES of {n} run{'s' if n != 1 else ''} at {k} grid times ({self.step_s:g} s){where}: "
               f"{pct(self.within)} in its {100 * self.confidence:g} % band [{lo:.3g}, {hi:.3g}] "
               f"(chi-square({n}) / {n}), {pct(self.above)} above, "
               f"{pct(self.below)} below; mean ANEES {self.mean:.3g} (1 when consistent)")
        if n == 1:
            out += "; one run: the per-run test"
        if self.left_out:
            out += f"; {self.left_out} grid times not covered by every run left out"
        return out

    def as_dict(self) -> dict[str, Any]:
        """What results.json and campaign.json keep of it (per degree of freedom; the figure
        of the campaign report draws ``t_s`` against ``anees`` and the band)."""
        return {
            "runs": self.runs, "dof": self.dof, "confidence": self.confidence, "band": list(self.band),
            "grid_times": len(self.t_s), "step_s": self.step_s, "left_out": self.left_out,
            "within": self.within, "above": self.above, "below": self.below, "mean": _sig(self.mean),
            "t_s": [float(f"{t:.9g}") for t in self.t_s], "anees": [_sig(a) for a in self.anees],
        }


def _sig(x: float) -> float | str:
    """For JSON: 6 significant digits; an infinity as the string ``"inf"`` (a zero sigma)."""
    return float(f"{x:.6g}") if math.isfinite(x) else "inf"


def anees_band(runs: int, confidence: float) -> tuple[float, float]:
    """Two-sided interval of probability ``confidence`` of the ANEES of ``runs`` runs:
    chi-square(runs) / runs, the widest law of the mean over independent runs of a NEES per
    degree of freedom whatever the correlation between its axes (module docstring)."""
    a = (1.0 - confidence) / 2.0
    return float(chi2.ppf(a, runs)) / runs, float(chi2.ppf(1.0 - a, runs)) / runs


def _number(x: Any) -> float:
    """A sample as stored: a float, None (no sample), or an infinity as JSON spells it."""
    if x is None:
        return math.nan
    if isinstance(x, str) and x in ("inf", "Infinity"):
        return math.inf
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise AneesError(f"a NEES sample that is not a number: {x!r}")
    return float(x)


def series_of(details: Mapping[str, Any], seed: int) -> tuple[int, float, float, np.ndarray]:
    """``(dof, start_s, step_s, values)`` of a run's sampled NEES (:class:`AneesError`
    without one)."""
    grid = details.get("nees_grid") if isinstance(details, Mapping) else None
    dof = details.get("dof") if isinstance(details, Mapping) else None
    if not isinstance(grid, Mapping) or not isinstance(dof, int) or isinstance(dof, bool) or dof < 1:
        raise AneesError(f"the run of seed {seed} carries no sampled NEES series (nees_grid): judged by another "
                         "version of the bench; judge its recording again")
    try:
        start, step = float(grid["start_s"]), float(grid["step_s"])
        values = np.asarray([_number(v) for v in grid["values"]], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise AneesError(f"the sampled NEES series of the run of seed {seed} is malformed: {exc}") from None
    if not (math.isfinite(start) and math.isfinite(step) and step > 0):
        raise AneesError(f"the sampled NEES series of the run of seed {seed} has no valid grid")
    if np.any(values < 0):
        raise AneesError(f"the sampled NEES series of the run of seed {seed} holds a negative NEES")
    return dof, start, step, values


def anees_test(series: Sequence[tuple[int, float, float, np.ndarray]], confidence: float) -> AneesResult:
    """The ANEES of the runs' sampled series (:func:`series_of`, one per run) over the grid
    times every run covers, against the band of ``len(series)`` runs at ``confidence``."""
    if not series:
        raise AneesError("no run to judge")
    dofs = {s[0] for s in series}
    steps = {round(s[2], 9) for s in series}
    if len(dofs) != 1 or len(steps) != 1:
        raise AneesError(f"the runs' NEES series differ in degrees of freedom ({sorted(dofs)}) or grid "
                         f"({sorted(steps)} s)")
    dof, step = series[0][0], series[0][2]
    first = [round(s[1] / step) for s in series]
    k0 = min(first)
    k1 = max(f + len(s[3]) for f, s in zip(first, series, strict=True))
    grid = np.full((len(series), max(k1 - k0, 0)), np.nan)
    for i, (f, s) in enumerate(zip(first, series, strict=True)):
        grid[i, f - k0:f - k0 + len(s[3])] = s[3]
    sampled = ~np.isnan(grid)
    every = np.all(sampled, axis=0)
    some = np.any(sampled, axis=0)
    n, k = len(series), int(np.sum(every))
    if k < MIN_GRID_TIMES:
        raise AneesError(
            f"only {k} grid times ({step:g} s) of the window are covered by all {n} runs; at least "
            f"{MIN_GRID_TIMES} are needed to judge the ANEES ({int(np.sum(some))} are covered by some run)")
    with np.errstate(invalid="ignore"):
        anees = np.mean(grid[:, every], axis=0)
    t = (k0 + np.flatnonzero(every)) * step
    return AneesResult(n, dof, confidence, anees_band(n, confidence), step, t, anees,
                       int(np.sum(some & ~every)))
