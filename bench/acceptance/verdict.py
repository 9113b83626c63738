"""Verdicts: PASS, MARGINAL, FAIL, ERROR, and N/A.

* PASS -- the DUT met the criterion with room to spare;
* MARGINAL -- it met it, but inside the criterion's marginal band next to the limit;
* FAIL -- the DUT missed it (its measured performance, or its own failure: a crash, an
  invalid solution, bad frames);
* ERROR -- the bench could not judge (timing budget missed, link lost, FMU error, data
  missing from the recording, too few Monte Carlo runs for the statistic asked);
* N/A -- the criterion does not apply to the run: the DUT's output latency in a lockstep
  run (the bench waits for each answer, so arrival minus time of validity measures the
  protocol, not the DUT).

Combining verdicts takes the worst, ERROR > FAIL > MARGINAL > PASS > N/A: a judgement the
bench could not complete is never reported as a pass or a fail, and N/A neither passes
nor fails anything (it is what a combination gives only when every part is N/A; a case
whose criteria are all N/A is an ERROR, see :func:`bench.acceptance.judge.judge_case`).
"""

from __future__ import annotations

import enum
from collections.abc import Iterable

__all__ = ["Verdict", "worst"]


class Verdict(enum.Enum):
    """The outcome of a criterion, a run, a case or a suite."""

    PASS = "PASS"
    MARGINAL = "MARGINAL"
    FAIL = "FAIL"
    ERROR = "ERROR"
    NA = "N/A"

    @property
    def rank(self) -> int:
        return _RANK[self]

    @property
    def passed(self) -> bool:
        """PASS or MARGINAL."""
        return self in (Verdict.PASS, Verdict.MARGINAL)

    def __str__(self) -> str:
        return self.value


_RANK = {Verdict.NA: -1, Verdict.PASS: 0, Verdict.MARGINAL: 1, Verdict.FAIL: 2, Verdict.ERROR: 3}


def worst(verdicts: Iterable[Verdict], default: Verdict = Verdict.PASS) -> Verdict:
    """The worst of ``verdicts`` (``default`` when there are none)."""
    out = None
    for v in verdicts:
        if out is None or v.rank > out.rank:
            out = v
    return default if out is None else out
