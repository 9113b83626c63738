"""What the DUT side fills in an estimator's output, and the one rule it checks.

An estimator returns physics only. Around it (the in-process adapter and the harness
alike) the records of a window's steps are stacked with ``rx_ns`` set to their step time
(:func:`bench.dut.estimator.stack_outputs`), then:

* :func:`first_late` finds the first epoch whose time of validity is later than the step
  that returned it (ICD 6: a DUT sends its epochs up to T before DUT_READY(T); an epoch
  from the future is the estimator's error, :func:`late_message` says which);
* :class:`EpochNumbering` writes the epoch counters: NAV_SOLUTION +1 per epoch modulo 256
  across the whole run, each NAV_QUALITY the counter of the NAV_SOLUTION with its time
  of validity. Whatever an estimator put there is overwritten.
"""

from __future__ import annotations

import numpy as np

from bench.wire.icd import EPOCH_MODULUS

__all__ = ["EpochNumbering", "first_late", "late_message"]


def first_late(*records: np.ndarray | None) -> tuple[int, int] | None:
    """``(t_ns, step_ns)`` of the first record (in step order, over every array given)
    whose time of validity ``t_ns`` is later than its step time ``rx_ns``; None if none is."""
    found: tuple[int, int] | None = None
    for recs in records:
        if recs is None or len(recs) == 0:
            continue
        late = np.flatnonzero(recs["t_ns"] > recs["rx_ns"])
        if late.size:
            k = int(late[0])
            hit = (int(recs["t_ns"][k]), int(recs["rx_ns"][k]))
            if found is None or hit[1] < found[1]:
                found = hit
    return found


def late_message(estimator: str, t_ns: int, step_ns: int) -> str:
    """The reason of a run ended by an epoch from the future."""
    return (
        f"the estimator {estimator!r} returned an epoch with time of validity {t_ns / 1e9:.6f} s at the step "
        f"{step_ns / 1e9:.6f} s: later than the step time (an estimator returns epochs up to the step's time)"
    )


class EpochNumbering:
    """The epoch counters of one run's NAV records (see the module docstring)."""

    def __init__(self) -> None:
        #: The counter of the next NAV_SOLUTION.
        self.next = 0
        # the previous call's solutions (time of validity, counter): a quality may follow
        # its solution one call later
        self._prev_t = np.zeros(0, np.int64)
        self._prev_e = np.zeros(0, np.uint8)

    def number(self, solutions: np.ndarray | None, qualities: np.ndarray | None) -> None:
        """Write the ``epoch`` field of the records (in place, in step order)."""
        sol_t = np.zeros(0, np.int64)
        sol_e = np.zeros(0, np.uint8)
        if solutions is not None and len(solutions):
            n = len(solutions)
            sol_e = ((self.next + np.arange(n)) % EPOCH_MODULUS).astype(np.uint8)
            solutions["epoch"] = sol_e
            sol_t = solutions["t_ns"].astype(np.int64)
            self.next = (self.next + n) % EPOCH_MODULUS
        if qualities is not None and len(qualities):
            keys_t = np.concatenate([self._prev_t, sol_t])
            keys_e = np.concatenate([self._prev_e, sol_e])
            if len(keys_t):
                order = np.argsort(keys_t, kind="stable")
                ts, es = keys_t[order], keys_e[order]
                qt = qualities["t_ns"]
                i = np.searchsorted(ts, qt, side="right") - 1  # the latest solution of that time
                ok = i >= 0
                ok[ok] = ts[i[ok]] == qt[ok]
                qualities["epoch"][ok] = es[i[ok]]
        if len(sol_t):
            self._prev_t, self._prev_e = sol_t, sol_e
