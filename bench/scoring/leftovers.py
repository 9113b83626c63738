"""The processes a DUT left running after its run, as the recording names them.

At the end of a run the bench ends every process the DUT started that is still running
(a daemon, a process group of its own: :mod:`bench.dut.reaper`) and records each -- its
id, command line and how it ended -- in the recording: an external DUT's in the
``dut_exit`` metadata (``left_running``), a batch DUT's in ``run_start``
(``dut_left_running``); both JSON lists of ``{"pid", "command", "ended"}``.

:func:`left_running_notes` makes the run's note of them (results.json ``runs[].notes``,
the summary, the certification report). It is a note, not an issue: the verdict stays
what the DUT's output earns (docs/run_engine.md, "How a run ends").
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

__all__ = ["left_running_notes"]

_SHOWN = 5  # processes named in the note; the rest are counted
_FIELDS = (("dut_exit", "left_running"), ("run_start", "dut_left_running"))


def _describe(p: Any) -> str:
    if not isinstance(p, Mapping):
        return repr(p)[:200]
    return f"pid {p.get('pid')} `{str(p.get('command', ''))[:300]}` ({p.get('ended', 'ended')})"


def left_running_notes(run_start: Mapping[str, str], dut_exit: Mapping[str, str]) -> list[str]:
    """The note naming the processes the DUT left running (none: no note)."""
    notes: list[str] = []
    for (record, key), values in zip(_FIELDS, (dut_exit, run_start), strict=True):
        raw = values.get(key)
        if not raw:
            continue
        try:
            left = json.loads(raw)
        except ValueError:
            notes.append(f"the recording's {record} {key} does not parse: {raw[:200]!r}")
            continue
        if not isinstance(left, list):
            notes.append(f"the recording's {record} {key} is not a list: {raw[:200]!r}")
            continue
        if not left:
            continue
        shown = "; ".join(_describe(p) for p in left[:_SHOWN])
        more = f"; and {len(left) - _SHOWN} more" if len(left) > _SHOWN else ""
        n = f"{len(left)} process" + ("es" if len(left) > 1 else "")
        notes.append(f"the DUT left {n} running when it ended, killed by the bench (SIGTERM, then SIGKILL "
                     f"after the grace): {shown}{more}")
    return notes
