"""Wire faults and the bench's own lockstep protocol (the rule is in docs/wire.md).

Kept apart from :mod:`bench.faults.wire` (no codecs) so that case loading can check it.
"""

from __future__ import annotations

from collections.abc import Iterable

from bench.errors import ConfigError
from bench.faults.schedule import FaultWindow

__all__ = ["LOCKSTEP_TARGET", "refuse_lockstep_faults"]

#: The bench's own lockstep frame (BENCH_TIME(T), answered by DUT_READY(T), ICD 6).
LOCKSTEP_TARGET = "can:BENCH_TIME"


def refuse_lockstep_faults(windows: Iterable[FaultWindow]) -> None:
    """Refuse wire windows that would make the lockstep protocol impossible.

    In lockstep the bench sends BENCH_TIME(T) and waits for the DUT's DUT_READY(T): a fault
    on it (dropped, delayed, a broken CRC, a wrong counter or length...) would leave the DUT
    nothing to answer, and the run would end blaming the DUT. A window aimed at
    ``can:BENCH_TIME`` is therefore a bad case (:class:`ConfigError`, naming the file and
    the window); ``can:*`` and ``can`` windows leave BENCH_TIME alone in lockstep
    (:class:`WireFaultInjector` with ``lockstep=True``). Real time has no such limit.
    """
    for w in windows:
        if w.layer == "wire" and w.target == LOCKSTEP_TARGET:
            file, key = w.origin or (None, f"fault {w.id}")
            raise ConfigError(
                f"a {w.kind} fault on {w.target} cannot run in lockstep: BENCH_TIME is the bench's own lockstep "
                "frame, which the DUT answers with DUT_READY; run this case in real time ([clock] mode = "
                "\"realtime\") or aim the fault at another message (can:* faults leave BENCH_TIME alone in lockstep)",
                file=file,
                key=f"{key}.target",
            )
