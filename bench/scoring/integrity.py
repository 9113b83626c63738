"""Can the bench judge this run at all? Bench-side failures, kept apart from the DUT's.

The recording says how the run ended (``run_end`` metadata: ``complete``, ``dut_failed``,
``dut_error``, ``error``, ``interrupted``, ``timing_budget``, ``link_lost``...) and, in
real-time runs, how late the bench was at every step (``/bench/timing``). From these:

* **DUT issues** make it FAIL: ``dut_failed``, the DUT failed (:data:`DUT_STATUSES`): it
  crashed or exited, hung past its timeout, never started, flooded the bus, gave output
  the codec refuses -- in process, external, hardware or batch alike;
* **bench issues** make the run's verdict ERROR: an unfinished recording, a damaged one
  (a stretch of it could not be read), no ``run_end``, an end status other than
  ``complete``/``dut_failed`` -- the bench's own failures, and ``dut_error``, a DUT ending
  the bench cannot pin on the DUT (a SIGKILL it did not send, a ``MemoryError`` in the
  bench's own process; the reason says why) --, steps later than the timing budget, no
  truth, no DUT output at all, a replay of a source recording that was unfinished, damaged,
  ended early or was itself such a replay (:mod:`bench.record.provenance`) unless the
  replay was run with ``--accept-damaged-source`` (then a **note** says so).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.record.provenance import source_issues
from bench.scoring.data import NAV_SOLUTION, TIMING, TRUTH, RunData
from bench.scoring.leftovers import left_running_notes

__all__ = ["Integrity", "check_integrity", "DUT_STATUSES", "OK_STATUSES", "UNCLEAR_STATUS"]

OK_STATUSES = ("complete",)
#: Run endings that are the DUT's failure (FAIL, the reason in the DUT issues): the DUT
#: crashed, exited, hung past its timeout, never started, flooded the bus or gave output
#: the codec refuses (in process, external, hardware), or a batch DUT's command failed,
#: timed out or wrote no or a malformed result -- the bench had done its part.
DUT_STATUSES: tuple[str, ...] = ("dut_failed",)
#: The DUT ended the run in a way the bench cannot pin on it (ERROR, the reason says why).
UNCLEAR_STATUS = "dut_error"


@dataclass
class Integrity:
    """Issues found: ``bench`` ones (-> ERROR) and ``dut`` ones (-> FAIL); ``notes`` for
    the record (a damaged source the user accepted)."""

    bench: list[str] = field(default_factory=list)
    dut: list[str] = field(default_factory=list)
    timing: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def check_integrity(run: RunData, budget_ns: int | None = None) -> Integrity:
    """Bench-side and DUT-side issues of a run (``budget_ns``: real-time lateness budget)."""
    out = Integrity()
    if run.damage:
        more = f" (and {len(run.damage) - 3} more)" if len(run.damage) > 3 else ""
        out.bench.append(f"the recording is damaged, {len(run.damage)} stretch(es) could not be read: "
                         + "; ".join(run.damage[:3]) + more)
    if not run.complete:
        out.bench.append("the recording was never finished (the run was killed or crashed)")
    elif run.run_end is None:
        out.bench.append("the recording has no run_end record")
    else:
        status = run.run_end.get("status", "")
        reason = run.run_end.get("reason", "")
        if status in DUT_STATUSES:
            out.dut.append(f"run ended with {status}" + (f": {reason}" if reason else ""))
        elif status == UNCLEAR_STATUS:
            out.bench.append(f"run ended with status {status!r}, a DUT ending the bench cannot tell from a failure "
                             "of its own" + (f": {reason}" if reason else ""))
        elif status not in OK_STATUSES:
            out.bench.append(f"run ended with status {status!r}" + (f": {reason}" if reason else ""))
    issues, notes = source_issues(run.run_start)
    out.bench += issues
    out.notes += notes
    out.notes += left_running_notes(run.run_start, run.dut_exit)  # noted, not judged
    if run.truth is None or len(run.truth) < 2:
        out.bench.append(f"no truth recorded ({TRUTH})")
    if (run.nav is None or len(run.nav) == 0) and not out.dut:
        out.bench.append(f"no DUT output recorded ({NAV_SOLUTION})")
    if run.timing is not None and len(run.timing):
        late = run.timing["lateness_ns"].astype(np.int64)
        out.timing = {
            "steps": float(len(late)),
            "lateness_max_s": float(np.max(late)) * 1e-9,
            "lateness_p99_s": float(np.percentile(late, 99)) * 1e-9,
        }
        if budget_ns is not None:
            over = int(np.sum(late > budget_ns))
            out.timing["over_budget"] = float(over)
            if over:
                out.bench.append(
                    f"{over} of {len(late)} real-time steps missed the timing budget of {budget_ns * 1e-6:g} ms "
                    f"(worst {float(np.max(late)) * 1e-6:.3f} ms late, {TIMING})"
                )
    return out
