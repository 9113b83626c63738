"""One campaign run, executed where a worker is: run, judge, write the run's record.

:func:`execute_run` is what an executor calls. It loads the case from its file (a
:class:`~bench.campaign.plan.PlannedRun` is small and picklable), runs it through the
case's runner into ``<dir>/recordings/<case id>/<key[:16]>/``, judges the recording as
``bench score`` would, and writes ``<dir>/runs/<key>.json`` atomically
(:mod:`bench.atomic`: a temporary file, fsync, then a rename) only once the recording is
finished. It returns that record, a small dict of numbers and strings, never arrays.

A run interrupted (Ctrl-C, SIGTERM) writes no record, so the next campaign runs it again;
a run that crashed or could not be executed is recorded ERROR with its reason, its
traceback in ``bench-error.log`` beside its recording (``bench campaign --retry-errors``
runs it again). A run whose worker process dies under it is told by the campaign
(:mod:`bench.campaign.guard`). A run whose recording another process is writing (a worker
of a killed campaign that went on) is no error of the run: :class:`RunBusyError`, no
record and no log; the campaign waits for that process.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from bench import atomic
from bench.campaign.plan import PlannedRun
from bench.errors import BenchError

__all__ = [
    "execute_run", "record_path", "load_record", "record_problem", "check_json", "write_atomic", "RunInterruptedError",
    "RunBusyError", "RECORD_VERSION",
]

#: 3: a criterion judged by ANEES over the runs keeps its run's sampled NEES (``series``)
RECORD_VERSION = 3


class RunInterruptedError(BenchError):
    """The run's recording ended ``interrupted``: no record is written (it runs again)."""


class RunBusyError(BenchError):
    """The run's recording (``path``) is being written by another process (``pid``, 0:
    unknown): no record is written."""

    def __init__(self, path: str, pid: int):
        self.path, self.pid = path, pid
        who = f"pid {pid}" if pid else "another process"
        super().__init__(f"its recording {path} is being written by {who} (a worker of an earlier campaign "
                         "still running it?)")

    def __reduce__(self) -> tuple:  # raised in a worker process, seen by the campaign's
        return (type(self), (self.path, self.pid))


def record_path(out_dir: str | Path, key: str) -> Path:
    """Where the record of the run ``key`` is kept."""
    return Path(out_dir) / "runs" / f"{key}.json"


def check_json(path: Path) -> dict[str, Any]:
    """The JSON object of a campaign's file (a run record, a marker, ``campaign.json``), read
    bounded and checked by :func:`bench.config.files.read_json`: a number that is not finite
    is refused (:class:`~bench.errors.ConfigError` naming the file and the field), except
    ``Infinity``, which the campaign writes for an infinite measurement (NaN it writes as
    null, :func:`write_atomic`)."""
    from bench.config.files import read_json as read_checked
    from bench.errors import ConfigError

    data = read_checked(path, what="campaign file", infinity=True)
    if not isinstance(data, dict):
        raise ConfigError(f"expected a JSON object, found {type(data).__name__}", file=str(path))
    return data


def read_json(path: Path) -> dict[str, Any] | None:
    """A JSON object from ``path`` (:func:`check_json`); None when missing or malformed."""
    from bench.errors import ConfigError

    try:
        return check_json(path)
    except ConfigError:
        return None


def record_problem(out_dir: str | Path, key: str) -> str | None:
    """Why the record of run ``key`` on disk is malformed (a number that is not finite, not
    JSON, too large or nested too deep...: the message names the file and the field), or
    None when it is absent or readable."""
    from bench.errors import ConfigError

    path = record_path(out_dir, key)
    if not os.path.lexists(path):
        return None
    try:
        check_json(path)
    except ConfigError as exc:
        return str(exc)
    return None


def load_record(out_dir: str | Path, key: str, *, strict: bool = False) -> dict[str, Any] | None:
    """The complete record of run ``key``, or None (missing, malformed, incomplete or of
    another version). ``strict``: a malformed record is a :class:`~bench.errors.ConfigError`
    naming the file and the field instead."""
    path = record_path(out_dir, key)
    rec = check_json(path) if strict and os.path.lexists(path) else read_json(path)
    if (rec is None or rec.get("key") != key or rec.get("complete") is not True
            or rec.get("version") != RECORD_VERSION):
        return None  # a record of another version lacks what the aggregate reads: the run runs again
    return rec


def _number(x: float) -> float | None:
    return float(x) if math.isfinite(x) else (None if math.isnan(x) else float(x))


def _display(c: Any, x: float | None) -> float | None:
    return None if x is None else _number(c.display(x))


def criterion_fields(c: Any) -> dict[str, Any]:
    """What the campaign report needs of a criterion (:class:`bench.acceptance.criteria.Criterion`),
    besides the run's value: display unit, comparator, limit text and bounds, marginal band
    (all in the display unit), metric, window and requirements."""
    band = c.band()
    return {
        "unit": c.unit, "comparator": c.limit.comparator, "limit_text": c.limit.text(c.unit),
        "limit": {"low": _display(c, c.limit.low), "high": _display(c, c.limit.high)},
        "marginal_band": _display(c, band) if band else None,
        "metric": c.metric, "window": c.window.name, "requirements": list(c.requirements),
        "worse": "lower" if c.limit.comparator == "at_least" else "higher",
    }


def sweep_axes(case_file: str, point: Any) -> list[list[Any]] | None:
    """``[[key, [values as declared]], ...]`` of the sweeps of ``case_file``, so that the
    aggregate orders a sweep's points as written; None without a sweep (or when the
    declaration does not match the point: the aggregate then orders by value)."""
    if not point:
        return None
    from bench.campaign.sweep import sweep_points

    points = sweep_points(case_file)
    axes: list[list[Any]] = []
    for i, (key, _value) in enumerate(point):
        seen: dict[str, Any] = {}
        for p in points:
            if len(p) != len(point) or p[i][0] != key:
                return None
            seen.setdefault(json.dumps(p[i][1], sort_keys=True), p[i][1])
        axes.append([key, list(seen.values())])
    return axes


def _no_nan(x: Any) -> Any:
    """``x`` with every NaN float (in nested dicts and lists) made None: a campaign's files
    hold no NaN, so a NaN read back is a damaged file (:func:`check_json`)."""
    if isinstance(x, float):
        return None if math.isnan(x) else x
    if isinstance(x, dict):
        return {k: _no_nan(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_no_nan(v) for v in x]
    return x


def write_atomic(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as JSON to ``path`` whole or not at all (:mod:`bench.atomic`); NaN is
    written as null, an infinity as ``Infinity``."""
    atomic.write_atomic(path, json.dumps(_no_nan(data), indent=1, sort_keys=True, allow_nan=True))


def execute_run(run: PlannedRun, out_dir: str) -> dict[str, Any]:
    """Run, judge and record ``run`` under ``out_dir`` (see the module docstring)."""
    from bench.acceptance.judge import score_run
    from bench.acceptance.runner import recording_name, runner_for
    from bench.acceptance.verdict import Verdict
    from bench.campaign.sweep import case_at
    from bench.crashlog import one_line, write_traceback
    from bench.record.lock import OutputLockedError, clear_outputs
    from bench.scoring.data import load_run

    base = Path(out_dir)
    folder = base / "recordings" / run.case_id / run.key[:16]
    folder.mkdir(parents=True, exist_ok=True)
    record: dict[str, Any] = {
        "version": RECORD_VERSION, "key": run.key, "case_id": run.case_id, "case_file": run.case_file,
        "variant": run.variant, "seed": run.seed, "sweep_axes": None,
        "sweep": [list(kv) for kv in run.point], "criteria": {}, "bench_issues": [], "dut_issues": [],
    }
    try:
        case = case_at(run.case_file, run.point)
        record["sweep_axes"] = sweep_axes(run.case_file, run.point)
        if run.clock:
            case = case.with_clock(run.clock)
        cv = case.for_variant(run.variant).with_seeds((run.seed,))
        target = folder / recording_name(cv, run.seed)
        clear_outputs([target], force=True)  # the partial recording of an interrupted run
        record["recording"] = str(target.relative_to(base))
        path = runner_for(cv).run(cv, run.seed, folder)
        record["recording"] = str(Path(path).resolve().relative_to(base.resolve()))
        data = load_run(path)
        interrupted = data.run_end.get("status") == "interrupted"
        result = score_run(data, case)
        crits = {c.id: c for c in case.criteria}  # ids are unique in a case
    except OutputLockedError as exc:  # this run, being written by another process: not this run's error
        raise RunBusyError(str(exc.path), exc.pid) from None
    except Exception as exc:  # a run that could not be executed or judged: ERROR, recorded
        write_traceback(exc, folder, context=f"bench campaign: {run.label}")
        record.update(verdict=Verdict.ERROR.value, bench_issues=[f"{type(exc).__name__}: {one_line(exc)}"])
    else:
        if interrupted:
            raise RunInterruptedError(f"{run.label} was interrupted")  # no record: it runs again
        record.update(
            verdict=result.verdict.value,
            bench_issues=list(result.bench_issues),
            dut_issues=list(result.dut_issues),
            criteria={cid: _criterion_record(v, crits.get(cid)) for cid, v in sorted(result.values.items())},
            raw={cid: {"value": _number(v.value), "verdict": v.verdict.value, "reason": v.reason} | _series(v)
                 for cid, v in sorted(result.raw.items())},  # comparisons' and negative controls' values
        )
    record["complete"] = True
    write_atomic(record_path(base, run.key), record)
    return record


def _criterion_record(v: Any, crit: Any) -> dict[str, Any]:
    """One criterion of a run: its value (SI) and, with its criterion, its value in the
    display unit (``display``) and :func:`criterion_fields`."""
    value = _number(v.value)
    out: dict[str, Any] = {"value": value, "verdict": v.verdict.value, "reason": v.reason, "worse": "higher"}
    out.update(_series(v))
    if crit is not None:
        out.update(criterion_fields(crit), display=_display(crit, value))
    return out


def _series(v: Any) -> dict[str, Any]:
    """``{"series": {"dof", "nees_grid"}}`` of a run's value judged by ANEES over the runs
    (its sampled NEES, :mod:`bench.acceptance.anees`; an infinite sample as ``"inf"``),
    else nothing."""
    d = v.details or {}
    if "nees_grid" not in d:
        return {}
    grid = dict(d["nees_grid"])
    grid["values"] = ["inf" if isinstance(x, float) and math.isinf(x) else x for x in grid.get("values", [])]
    return {"series": {"dof": d.get("dof"), "nees_grid": grid}}  # JSON without Infinity
