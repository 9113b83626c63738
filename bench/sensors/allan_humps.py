"""Humps of an Allan deviation that no sum of the IEEE noise terms makes.

Every term's Allan variance is a power of the averaging time except the Gauss-Markov
bias instability, whose peak is broad: half a decade from its top its ADEV keeps 0.81
of it, and no admixture of the other terms brings that below 0.69; and no term but the
rate ramp (which never turns over) rises faster than slope +1/2. A peak narrower or
steeper than that is vibration or periodic motion (a sinusoid rises at +1 and falls at
-1), and fitting noise terms through it reads it as a bias instability.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.sensors.allan import AllanResult

__all__ = ["Hump", "find_humps"]

#: A peak whose ADEV falls below this fraction of its top half a decade away is a hump.
_HUMP_DROP = 0.6
#: An ADEV slope into a peak steeper than this is a hump.
_HUMP_RISE = 0.6


@dataclass(frozen=True)
class Hump:
    """A peak of the Allan deviation that no noise term makes.

    ``tau_peak`` and ``adev_peak`` locate its top, ``tau_range`` the stretch of the
    curve it raises (left out of the fit), ``drop`` the smallest ratio of the ADEV half a
    decade away to the top (a noise term keeps at least 0.69).
    """

    tau_peak: float
    adev_peak: float
    tau_range: tuple[float, float]
    drop: float


def find_humps(result: AllanResult, *, resolution: float | None = None, min_clusters: int = 30) -> list[Hump]:
    """Peaks that no sum of the noise terms makes: vibration or periodic motion.

    A local maximum is a hump when the ADEV half a decade away on either side is below
    0.6 of its top, or when the curve rises into it faster than slope +0.6 over at least
    0.3 decade (no term but the rate ramp rises faster than +1/2, and a rate ramp never
    turns over), each by three sigma of the points.

    Parameters
    ----------
    result:
        The Allan deviation of one axis.
    resolution:
        Output pulse size (rad or m/s) when the data are quantized: the pulse pattern of
        a near-constant input makes wiggles below ``resolution / T``, which are not
        counted.
    min_clusters:
        Only points with at least this many clusters are examined.
    """
    ok = result.clusters >= min_clusters
    T, y, s = result.tau[ok], result.adev[ok], result.rel_sigma[ok]
    if len(T) < 3:
        return []
    lt, ly = np.log10(T), np.log10(np.maximum(y, np.finfo(float).tiny))
    found: list[Hump] = []
    for i in range(1, len(T) - 1):
        if not (y[i] >= y[i - 1] and y[i] >= y[i + 1]):
            continue
        if resolution is not None and y[i] <= resolution / T[i]:
            continue
        steep = _narrowness(lt, ly, s, i)
        if steep is None:
            continue
        lo = i
        while lo > 0 and y[lo - 1] < y[lo] and T[lo - 1] > T[i] / 10.0:
            lo -= 1
        hi = i
        while hi < len(T) - 1 and y[hi + 1] < y[hi] and T[hi + 1] < T[i] * 10.0:
            hi += 1
        hump = Hump(float(T[i]), float(y[i]), (float(T[lo]), float(T[hi])), steep)
        if found and hump.tau_range[0] <= found[-1].tau_range[1]:
            prev = found[-1]
            top = prev if prev.adev_peak >= hump.adev_peak else hump
            span = (prev.tau_range[0], max(prev.tau_range[1], hump.tau_range[1]))
            found[-1] = Hump(top.tau_peak, top.adev_peak, span, min(prev.drop, hump.drop))
        else:
            found.append(hump)
    return found


def _narrowness(lt: np.ndarray, ly: np.ndarray, s: np.ndarray, i: int) -> float | None:
    """The smallest ADEV ratio half a decade from peak ``i`` when the peak is narrower or
    steeper than noise terms make (see :func:`find_humps`), else None."""
    ratios = []
    narrow = steep = False
    for side in (-0.5, 0.5):
        x = lt[i] + side
        if lt[0] <= x <= lt[-1]:
            j = int(np.argmin(np.abs(lt - x)))
            ratio = 10 ** (float(np.interp(x, lt, ly)) - ly[i])
            ratios.append(ratio)
            narrow |= ratio * (1.0 + 3.0 * math.hypot(s[i], s[j])) < _HUMP_DROP
    start = i
    while start > 0 and ly[start - 1] <= ly[start] and lt[i] - lt[start - 1] <= 1.0:
        start -= 1
    for j in range(start, i):
        for k in range(j + 1, i + 1):
            span = lt[k] - lt[j]
            if span >= 0.3:
                slope_sd = 3.0 * math.hypot(s[k], s[j]) / (math.log(10.0) * span)
                steep |= (ly[k] - ly[j]) / span - slope_sd > _HUMP_RISE
    if not (narrow or steep):
        return None
    return float(min(ratios)) if ratios else 1.0
