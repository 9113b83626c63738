"""Two sets of runs judged against each other: the tests ``bench compare`` applies when A
and B ran a criterion on different seeds, several runs on each side (docs/compare.md).

* :func:`mann_whitney_greater` -- the one-sided Mann-Whitney (Wilcoxon rank-sum) test that
  B's values tend to be larger than A's: exact (the distribution of B's rank sum over all
  ``C(n+m, m)`` equally likely assignments of the ranks, ties given their mid-rank) up to
  :data:`EXACT_MAX` runs in all, the normal approximation with tie and continuity
  corrections beyond;
* :func:`fisher_greater` -- Fisher's exact one-sided test that B's proportion of runs not
  PASS is larger than A's (the hypergeometric tail).

Pure Python (``math`` only): no library is needed for runs counted in tens.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["EXACT_MAX", "mann_whitney_greater", "fisher_greater", "median"]

#: The Mann-Whitney test is exact for at most this many runs (A's and B's together).
EXACT_MAX = 30


def median(xs: Sequence[float]) -> float:
    s = sorted(xs)
    n = len(s)
    if not n:
        raise ValueError("the median of no value")
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def _ranks(values: Sequence[float]) -> list[float]:
    """Mid-ranks (1-based) of ``values``, ties sharing the mean of their ranks."""
    order = sorted(range(len(values)), key=lambda i: values[i])
    ranks = [0.0] * len(values)
    i = 0
    while i < len(order):
        j = i
        while j + 1 < len(order) and values[order[j + 1]] == values[order[i]]:
            j += 1
        for k in range(i, j + 1):
            ranks[order[k]] = 0.5 * (i + j) + 1.0
        i = j + 1
    return ranks


def mann_whitney_greater(a: Sequence[float], b: Sequence[float]) -> float:
    """The p-value of the one-sided Mann-Whitney test that ``b`` is stochastically larger
    than ``a`` (1.0 when a side is empty or every value ties)."""
    n, m = len(a), len(b)
    if not n or not m:
        return 1.0
    ranks = _ranks([*a, *b])
    rb = sum(ranks[n:])  # rank sum of B: large when B is larger
    if n + m <= EXACT_MAX:
        # ways[k][s]: subsets of k ranks whose doubled sum (an integer: mid-ranks are halves) is s
        ways: list[dict[int, int]] = [{0: 1}] + [{} for _ in range(m)]
        for r in ranks:
            r2 = round(2 * r)
            for k in range(m, 0, -1):
                for s, w in ways[k - 1].items():
                    ways[k][s + r2] = ways[k].get(s + r2, 0) + w
        target = round(2 * rb)
        return sum(w for s, w in ways[m].items() if s >= target) / math.comb(n + m, m)
    u = rb - m * (m + 1) / 2
    mean = n * m / 2
    groups: dict[float, int] = {}
    for x in (*a, *b):
        groups[x] = groups.get(x, 0) + 1
    ties = sum(t**3 - t for t in groups.values())
    nn = n + m
    var = n * m / 12 * ((nn + 1) - ties / (nn * (nn - 1)))
    if var <= 0:
        return 1.0
    z = (u - mean - 0.5) / math.sqrt(var)
    return 0.5 * math.erfc(z / math.sqrt(2))


def fisher_greater(bad_a: int, n_a: int, bad_b: int, n_b: int) -> float:
    """The p-value of Fisher's exact one-sided test that B's rate of bad runs
    (``bad_b`` of ``n_b``) is larger than A's (``bad_a`` of ``n_a``)."""
    if not n_a or not n_b:
        return 1.0
    bad, total = bad_a + bad_b, n_a + n_b
    denominator = math.comb(total, n_b)
    return sum(math.comb(bad, k) * math.comb(total - bad, n_b - k)
               for k in range(bad_b, min(bad, n_b) + 1)) / denominator
