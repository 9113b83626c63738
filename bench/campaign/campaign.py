"""Run a campaign: plan its runs, skip those already recorded, execute the rest, aggregate.

``<dir>/runs/<key>.json`` holds one record per run (:mod:`bench.campaign.work`),
``<dir>/recordings/`` the recordings, ``<dir>/campaign.json`` the aggregate
(:mod:`bench.campaign.aggregate`) with what this invocation did. A run whose key already
has a complete record is not run again, so an interrupted campaign continues where it
stopped, and ``aggregate`` is the same whichever executor ran it.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.campaign.aggregate import aggregate
from bench.campaign.executors import completed, open_executor
from bench.campaign.plan import PlannedRun, plan_campaign
from bench.campaign.work import execute_run, load_record, write_atomic

__all__ = ["CampaignOptions", "CampaignProgress", "run_campaign", "read_campaign"]


@dataclass
class CampaignProgress:
    """The state of a campaign, passed to the progress callback after every run."""

    total: int
    done: int = 0
    failing: int = 0
    executed: int = 0
    to_run: int = 0
    lost: list[str] = field(default_factory=list)
    started: float = field(default_factory=time.monotonic)
    last: dict[str, Any] | None = None

    @property
    def eta_s(self) -> float | None:
        """Seconds left at the pace of this invocation's runs (None before the first)."""
        if not self.executed:
            return None
        return (time.monotonic() - self.started) / self.executed * (self.to_run - self.executed - len(self.lost))


@dataclass
class CampaignOptions:
    """What to run and where."""

    paths: list[str]
    out_dir: Path
    runs: int | None = None
    seeds: tuple[int, ...] | None = None
    clock: str | None = None
    workers: int = 1
    scheduler: str | None = None  # None: local processes; "local": a Dask LocalCluster; else an address
    env: dict[str, str] = field(default_factory=dict)


def _failing(rec: dict[str, Any]) -> bool:
    return rec.get("verdict") not in ("PASS", "MARGINAL", "N/A")


def run_campaign(
    options: CampaignOptions, progress: Callable[[CampaignProgress], None] | None = None
) -> dict[str, Any]:
    """Run what is missing of the campaign and write ``campaign.json``; returns its content."""
    out = Path(options.out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    plan = plan_campaign(options.paths, options.runs, options.seeds, options.clock)
    records: dict[str, dict[str, Any]] = {}
    todo: list[PlannedRun] = []
    for run in plan:
        rec = load_record(out, run.key)
        if rec is None:
            todo.append(run)
        else:
            records[run.key] = rec
    state = CampaignProgress(total=len(plan), done=len(records), to_run=len(todo),
                             failing=sum(map(_failing, records.values())))
    if progress:
        progress(state)
    env = {k: v for k, v in os.environ.items() if k == "PYTHONPATH"} | options.env
    try:
        if todo:
            with open_executor(options.scheduler, max(1, options.workers), env) as ex:
                futures = [ex.submit(execute_run, run, str(out)) for run in todo]
                by_future = dict(zip(map(id, futures), todo, strict=True))
                for fut in completed(futures):
                    run = by_future[id(fut)]
                    try:
                        rec = fut.result()
                    except Exception as exc:  # a worker died or could not write: the run stays missing
                        state.lost.append(f"{run.label}: {type(exc).__name__}: {exc}")
                    else:
                        records[run.key] = rec
                        state.done += 1
                        state.executed += 1
                        state.failing += _failing(rec)
                        state.last = rec
                    if progress:
                        progress(state)
    finally:  # also when interrupted: every run recorded so far (a worker may have finished one unseen)
        for run in plan:
            if run.key not in records and (rec := load_record(out, run.key)) is not None:
                records[run.key] = rec
        missing = [r.key for r in plan if r.key not in records]
        result = {
            "campaign": {"paths": [str(p) for p in options.paths], "planned": len(plan), "complete": not missing,
                         "missing": missing},
            "aggregate": aggregate(records.values()),
            "invocation": {"executed": state.executed, "reused": len(plan) - len(todo), "lost": state.lost,
                           "workers": options.workers, "scheduler": options.scheduler or "processes"},
        }
        write_atomic(out / "campaign.json", result)
    return result


def read_campaign(out_dir: str | Path) -> dict[str, Any]:
    """The ``campaign.json`` of a campaign folder."""
    return json.loads((Path(out_dir) / "campaign.json").read_text(encoding="utf-8"))

