"""Runs whose worker died: who ran them, and the ERROR record that names it.

A worker process can die under a run (a DUT's native library crashing in process, the
kernel's out-of-memory killer, a node lost): no exception reaches the campaign from that
run, only a broken pool (local processes) or Dask's ``KilledWorker``. So that the run is
told apart and named, each run leaves a marker while it executes
(``<dir>/runs/<key>.running``: the worker's host and process id, when it started), removed
when it ends however it ends, except by the death of its process.

:func:`guarded_run` is what the executors call; :func:`death_record` is the ERROR record the
campaign writes for a run that killed its worker (see :mod:`bench.campaign.campaign` for
when a death is blamed on a run).
"""

from __future__ import annotations

import datetime as _dt
import os
import socket
from pathlib import Path
from typing import Any

from bench.campaign.plan import PlannedRun
from bench.campaign.work import RECORD_VERSION, execute_run, read_json, record_path, write_atomic

__all__ = ["guarded_run", "marker_path", "read_marker", "death_record", "DEATH"]

#: The start of the reason of a run whose worker died.
DEATH = "the worker process died while running it"


def marker_path(out_dir: str | Path, key: str) -> Path:
    """The marker of the run ``key`` while it executes."""
    return Path(out_dir) / "runs" / f"{key}.running"


def read_marker(out_dir: str | Path, key: str) -> dict[str, Any] | None:
    """The marker of run ``key`` (None: not started, or ended)."""
    return read_json(marker_path(out_dir, key))


def guarded_run(run: PlannedRun, out_dir: str) -> dict[str, Any]:
    """:func:`bench.campaign.work.execute_run` with the run's marker around it."""
    marker = marker_path(out_dir, run.key)
    write_atomic(marker, {"key": run.key, "host": socket.gethostname(), "pid": os.getpid(),
                          "started_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")})
    try:
        return execute_run(run, out_dir)
    finally:
        marker.unlink(missing_ok=True)


def death_record(run: PlannedRun, out_dir: str | Path, detail: str) -> dict[str, Any]:
    """Write and return the ERROR record of ``run``, whose worker died under it; ``detail``
    says how the death was seen. The marker names the worker."""
    m = read_marker(out_dir, run.key) or {}
    who = f"process {m['pid']} on {m['host']}, started {m['started_utc']}" if m else "worker unknown"
    record = {
        "version": RECORD_VERSION, "key": run.key, "case_id": run.case_id, "case_file": run.case_file,
        "variant": run.variant, "seed": run.seed, "sweep": [list(kv) for kv in run.point], "criteria": {},
        "verdict": "ERROR", "bench_issues": [f"{DEATH} ({who}): {detail}"], "dut_issues": [],
        "worker": m or None, "complete": True,
    }
    write_atomic(record_path(out_dir, run.key), record)
    marker_path(out_dir, run.key).unlink(missing_ok=True)
    return record
