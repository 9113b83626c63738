"""Run a campaign: plan its runs, skip those already recorded, execute the rest, aggregate.

``<dir>/runs/<key>.json`` holds one record per run (:mod:`bench.campaign.work`),
``<dir>/recordings/`` the recordings, ``<dir>/campaign.json`` the aggregate
(:mod:`bench.campaign.aggregate`) with what this invocation did. A run whose key already
has a complete record is not run again, so an interrupted campaign continues where it
stopped, and ``aggregate`` is the same whichever executor ran it. One campaign at a time
holds ``<dir>`` (``<dir>/campaign.lock``, :mod:`bench.campaign.lock`).
"""

from __future__ import annotations

import datetime as _dt
import os
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench import __version__
from bench.campaign.aggregate import aggregate
from bench.campaign.executors import completed, open_executor, pool_broken, worker_killed
from bench.campaign.guard import death_record, guarded_run, marker_path, read_marker
from bench.campaign.lock import CampaignLock, acquire
from bench.campaign.plan import PlannedRun, plan_campaign
from bench.campaign.verdicts import judge_groups
from bench.campaign.work import (
    RunBusyError,
    check_json,
    load_record,
    read_json,
    record_path,
    record_problem,
    write_atomic,
)
from bench.crashlog import one_line
from bench.record.lock import holder

__all__ = ["CampaignOptions", "CampaignProgress", "run_campaign", "read_campaign"]


@dataclass
class CampaignProgress:
    """The state of a campaign, passed to the progress callback after every run."""

    total: int
    done: int = 0
    failing: int = 0
    executed: int = 0
    reused: int = 0
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
    retry_errors: bool = False  # run again the runs recorded ERROR
    prune: bool = False  # delete records (and recordings) no run of the campaign has


def _failing(rec: dict[str, Any]) -> bool:
    return rec.get("verdict") not in ("PASS", "MARGINAL", "N/A")


def _stale(out: Path, plan: list[PlannedRun]) -> list[str]:
    """Keys of the records under ``out/runs`` that no run of the plan has (a case edited, a
    seed dropped, another bench version)."""
    keys = {r.key for r in plan}
    return sorted(p.stem for p in (out / "runs").glob("*.json") if p.stem not in keys)


def _prune(out: Path, keys: list[str]) -> None:
    """Delete stale records and their recordings' folders."""
    for key in keys:
        rec = record_path(out, key)
        where = (read_json(rec) or {}).get("recording")
        folder = (out / where).parent if isinstance(where, str) and where else None
        if folder is not None and folder.resolve().is_relative_to((out / "recordings").resolve()):
            shutil.rmtree(folder, ignore_errors=True)
        rec.unlink(missing_ok=True)


class _Execution:
    """This invocation's runs on an executor, with the death of a worker told apart: a
    broken local pool, or Dask giving up on runs whose workers died (``KilledWorker``: also
    a run only queued on a worker that another run killed), puts those runs back; those that
    had started are run again one at a time, and one whose worker dies alone is recorded
    ERROR naming it. A run whose recording another process is still writing (a worker of a
    killed campaign that went on: a remote Dask worker) is waited for: its record is then
    taken, or the run run again if it left none."""

    def __init__(self, options: CampaignOptions, out: Path, env: dict[str, str], state: CampaignProgress,
                 records: dict[str, dict[str, Any]], progress: Callable[[CampaignProgress], None] | None,
                 notice: Callable[[str], None]):
        self.options, self.out, self.env, self.state, self.records = options, out, env, state, records
        self.progress, self.notice = progress, notice
        self.busy: list[tuple[PlannedRun, RunBusyError]] = []

    def _done(self, run: PlannedRun, rec: dict[str, Any]) -> None:
        self.records[run.key] = rec
        self.state.done += 1
        self.state.executed += 1
        self.state.failing += _failing(rec)
        self.state.last = rec
        if self.progress:
            self.progress(self.state)

    def attempt(self, batch: list[PlannedRun], workers: int) -> list[PlannedRun]:
        """Run ``batch``; the runs left unfinished by a dead worker are returned."""
        unfinished: list[PlannedRun] = []
        with open_executor(self.options.scheduler, workers, self.env) as ex:
            futures = [ex.submit(guarded_run, run, str(self.out)) for run in batch]
            by_future = dict(zip(map(id, futures), batch, strict=True))
            for fut in completed(futures):
                run = by_future[id(fut)]
                try:
                    rec = fut.result()
                except RunBusyError as exc:  # another process is writing this very run
                    self.busy.append((run, exc))
                    continue
                except Exception as exc:
                    if pool_broken(exc) or worker_killed(exc):  # a worker died: this run, or beside it?
                        unfinished.append(run)
                        continue
                    # the run could not be sent or its record written
                    self.state.lost.append(f"{run.label}: {type(exc).__name__}: {one_line(exc)}")
                    if self.progress:
                        self.progress(self.state)
                    continue
                self._done(run, rec)
        return unfinished

    def run(self, todo: list[PlannedRun]) -> None:
        pending = todo
        while pending:
            self._run(pending)
            pending = self._waited_for()

    def _run(self, todo: list[PlannedRun]) -> None:
        for run in todo:  # an earlier campaign killed under it (a run still being written is told by its lock)
            marker_path(self.out, run.key).unlink(missing_ok=True)
        pending = todo
        workers = max(1, self.options.workers)
        while pending:
            unfinished = self.attempt(pending, workers)
            suspects = [r for r in unfinished if read_marker(self.out, r.key) is not None]
            if unfinished and not suspects:  # the pool broke before any run started
                self.state.lost += [f"{r.label}: the worker processes died before it started" for r in unfinished]
                return
            pending = [r for r in unfinished if r not in suspects]
            for run in suspects:  # each alone: a death now is the run's own
                marker_path(self.out, run.key).unlink(missing_ok=True)
                if self.attempt([run], 1):
                    self._done(run, death_record(run, self.out, "it died again when the run was retried alone"))

    def _waited_for(self) -> list[PlannedRun]:
        """Wait until the runs found being written by another process are no longer; those
        it recorded are taken (``reused``), the others returned to be run."""
        again: list[PlannedRun] = []
        busy, self.busy = self.busy, []
        for run, exc in busy:
            self.notice(f"bench campaign: {run.label}: {exc}; waiting for it to end")
            while holder(exc.path) is not None:
                time.sleep(0.5)
            rec = load_record(self.out, run.key)
            if rec is None:
                again.append(run)
                continue
            self.records[run.key] = rec
            self.state.done += 1
            self.state.reused += 1
            self.state.failing += _failing(rec)
            self.state.last = rec
            if self.progress:
                self.progress(self.state)
        return again


def run_campaign(
    options: CampaignOptions, progress: Callable[[CampaignProgress], None] | None = None,
    notice: Callable[[str], None] | None = None, command: str | None = None,
) -> dict[str, Any]:
    """Run what is missing of the campaign and write ``campaign.json``; returns its content.

    The folder is held for the whole campaign (:mod:`bench.campaign.lock`): while another
    campaign holds it, :class:`~bench.campaign.lock.CampaignHeldError` is raised before
    anything is read or written. ``notice`` is told what the user should know that is no
    run's outcome (a stale lock taken over, a run still being written by another process);
    default: stderr. ``command`` is what the lock says the holder is (default: this
    process's command line)."""
    out = Path(options.out_dir).resolve()
    notice = notice or _stderr
    with acquire(out, command, notice=notice) as held:
        return _run_held(options, out, held, progress, notice)


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _run_held(options: CampaignOptions, out: Path, held: CampaignLock,
              progress: Callable[[CampaignProgress], None] | None, notice: Callable[[str], None]) -> dict[str, Any]:
    plan = plan_campaign(options.paths, options.runs, options.seeds, options.clock)
    stale = _stale(out, plan)
    if options.prune and stale:
        _prune(out, stale)
        stale = []
    records: dict[str, dict[str, Any]] = {}
    todo: list[PlannedRun] = []
    malformed: list[str] = []  # records on disk that cannot be used: their runs run again
    for run in plan:
        rec = load_record(out, run.key)
        if rec is None and (why := record_problem(out, run.key)) is not None:
            malformed.append(why)
        if rec is None or (options.retry_errors and rec.get("verdict") == "ERROR"):
            todo.append(run)
        else:
            records[run.key] = rec
    state = CampaignProgress(total=len(plan), done=len(records), to_run=len(todo),
                             failing=sum(map(_failing, records.values())), reused=len(plan) - len(todo))
    env = {k: v for k, v in os.environ.items() if k == "PYTHONPATH"} | options.env
    try:
        if progress:
            progress(state)
        if todo:
            _Execution(options, out, env, state, records, progress, notice).run(todo)
    finally:  # also when interrupted: every run recorded so far (a worker may have finished one unseen)
        for run in plan:
            if run.key not in records and (rec := load_record(out, run.key)) is not None:
                records[run.key] = rec
        missing = [r.key for r in plan if r.key not in records]
        # a run recorded as its worker's death may have been retried by the scheduler once
        # more after the record (Dask retries a task its worker died under), and that
        # attempt died too, leaving its marker: the executors are shut down here, so the
        # marker of a recorded run names nobody
        for key in records:
            marker_path(out, key).unlink(missing_ok=True)
        try:
            verdicts, failed = judge_groups(plan, records), None
        except Exception as exc:  # a bench bug: still write what the runs gave, then raise it
            verdicts, failed = {}, exc
        lock = {k: held.info.get(k) for k in ("host", "pid", "started_utc")}
        result = {
            "campaign": {"paths": [str(p) for p in options.paths], "planned": len(plan), "complete": not missing,
                         "missing": missing, "stale": stale, "bench_version": __version__,
                         "finished_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
                         "options": {"runs": options.runs, "seeds": list(options.seeds) if options.seeds else None,
                                     "clock": options.clock}},
            "aggregate": aggregate(records.values()),
            "verdicts": verdicts,
            "invocation": {"executed": state.executed, "reused": state.reused, "lost": state.lost,
                           "malformed": malformed,
                           "workers": options.workers, "scheduler": options.scheduler or "processes",
                           "lock": lock, "took_over": held.took_over},
        }
        write_atomic(out / "campaign.json", result)
        if failed is not None:
            raise failed
    return result


def read_campaign(out_dir: str | Path) -> dict[str, Any]:
    """The ``campaign.json`` of a campaign folder (:func:`~bench.campaign.work.check_json`:
    a malformed one is a :class:`~bench.errors.ConfigError` naming the file and the field)."""
    return check_json(Path(out_dir) / "campaign.json")

