"""Running test cases: every variant and seed through its runner, then judged.

:func:`run_case` executes the runs of one case (one recording each, under
``<out>/recordings/<case id>/``), judges every recording exactly as ``bench score`` does,
and combines them with :func:`~bench.acceptance.judge.judge_case`. :func:`run_suite`
does so for every case file found. A case that does not load is ERROR with the
configuration error as its reason; a run the runner could not execute is ERROR.

A crash is contained where it happens: an exception while loading one case file, or
running, scoring or judging one run, makes that case (or run) ERROR with a one-line
reason (its traceback appended to ``<out>/bench-error.log``) and the suite goes on.

An interrupt (Ctrl-C, or SIGTERM, which ``bench`` turns into :class:`KeyboardInterrupt`)
ends the suite, but what finished is kept: :func:`run_case` raises
:class:`CaseInterrupted` carrying the case's result (judged, if it had finished; else
ERROR "did not finish" with the runs that had finished), and :func:`run_suite` raises
:class:`SuiteInterrupted` carrying every case's result -- those that finished as judged,
the one in progress and those not run as ERROR -- and an :class:`Interruption` naming
them, from which the reports are written marked incomplete (``bench accept``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from bench.acceptance.case import TestCase, is_case_file, load_case
from bench.acceptance.interrupted import Interruption, signal_name
from bench.acceptance.judge import CaseResult, RunResult, judge_case, score_recording
from bench.acceptance.runner import Progress, recording_name, runner_for
from bench.acceptance.verdict import Verdict
from bench.crashlog import one_line, write_traceback
from bench.errors import BenchError, ConfigError

__all__ = [
    "SuiteOptions",
    "SuiteReporter",
    "collect_cases",
    "prepare_case",
    "run_case",
    "run_suite",
    "load_error",
    "refuse_impossible_faults",
    "crash_reason",
    "Interruption",
    "CaseInterrupted",
    "SuiteInterrupted",
]


@dataclass
class SuiteOptions:
    """Where results go and what the command line overrides (None: the case's own)."""

    out_dir: Path
    seeds: tuple[int, ...] | None = None
    runs: int | None = None
    clock: str | None = None


class SuiteReporter(Protocol):
    """Progress callbacks of a suite (all optional to act on)."""

    def case_started(self, case: TestCase, runs: int) -> None: ...

    def run_started(self, case: TestCase, seed: int) -> Progress | None: ...

    def run_finished(self, case: TestCase, result: RunResult) -> None: ...

    def case_finished(self, result: CaseResult) -> None: ...


class CaseInterrupted(KeyboardInterrupt):
    """:func:`run_case` interrupted: ``result`` is the case judged (``finished``) if the
    interrupt came after it was, else ERROR with the runs that had finished."""

    def __init__(self, by: str, result: CaseResult, finished: bool):
        super().__init__(by)
        self.by, self.result, self.finished = by, result, finished


class SuiteInterrupted(KeyboardInterrupt):
    """:func:`run_suite` interrupted: ``results`` holds one result per case file found, in
    order (finished: judged; unfinished and not run: ERROR), ``interruption`` names them."""

    def __init__(self, interruption: Interruption, results: list[CaseResult]):
        super().__init__(interruption.by)
        self.interruption, self.results = interruption, results


def collect_cases(paths: Iterable[str | Path]) -> list[Path]:
    """Case files among ``paths``: files as given, folders' ``*.toml`` with a ``[case]``
    table (not recursive, so ``test_cases/scenarios/`` is not searched)."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            out.extend(f for f in sorted(p.glob("*.toml")) if is_case_file(f))
        elif p.exists():
            out.append(p)
        else:
            raise ConfigError("no such file or folder", file=str(p))
    return out


def prepare_case(case: TestCase, options: SuiteOptions) -> TestCase:
    """Apply the command-line overrides (clock mode, seeds, Monte Carlo count)."""
    if options.clock:
        case = case.with_clock(options.clock)
    if options.seeds:
        case = case.with_seeds(tuple(options.seeds))
    elif options.runs:
        first = case.run.seeds[0]
        case = case.with_seeds(tuple(range(first, first + options.runs)))
    return case


def refuse_impossible_faults(case: TestCase, options: SuiteOptions) -> None:
    """Refuse (ConfigError, before anything runs) wire faults on the bench's own lockstep
    frame when the case runs in lockstep (:func:`bench.faults.lockstep.refuse_lockstep_faults`)."""
    from bench.faults.lockstep import refuse_lockstep_faults

    if (options.clock or case.clock.mode) == "lockstep":
        refuse_lockstep_faults(case.faults)


def load_error(path: Path, exc: Exception) -> CaseResult:
    """The result of a case file that could not be loaded."""
    return CaseResult(path.stem, "(not loaded)", str(path), (), Verdict.ERROR, errors=[f"configuration error: {exc}"])


def crash_reason(what: str, exc: BaseException, out_dir: Path | None) -> str:
    """``<what>: ZeroDivisionError: ... (traceback in <out_dir>/bench-error.log)``, the
    traceback appended to that log (:mod:`bench.crashlog`)."""
    log = write_traceback(exc, out_dir, context=what)
    return f"{what}: {one_line(exc)}" + (f" (traceback in {log})" if log else "")


def _notify(fn: Callable[..., Any] | None, *args: Any, out_dir: Path | None = None) -> Any:
    """A reporter callback whose failure (a progress display) does not touch the verdicts."""
    if fn is None:
        return None
    try:
        return fn(*args)
    except Exception as exc:
        write_traceback(exc, out_dir, context=f"the progress reporter failed in {getattr(fn, '__name__', fn)}")
        return None


def _quiet_progress(progress: Progress | None, log_dir: Path) -> Progress | None:
    """``progress`` that stops drawing, rather than failing the run, when it raises."""
    if progress is None:
        return None
    broken: list[bool] = []

    def draw(done: float, total: float) -> None:
        if not broken:
            try:
                progress(done, total)
            except Exception as exc:
                broken.append(True)
                write_traceback(exc, log_dir, context="the progress display failed")

    return draw


def run_case(case: TestCase, options: SuiteOptions, reporter: SuiteReporter | None = None) -> CaseResult:
    """Run and judge every variant and seed of ``case``.

    Never raises but for an interrupt: an exception while preparing, running, scoring or
    judging makes that run (or, outside a run, the case) ERROR with the reason, and its
    traceback goes to ``bench-error.log`` in the output folder."""
    started = time.perf_counter()
    runs: list[RunResult] = []
    progress = _CaseProgress()
    log_dir = Path(options.out_dir)
    out: CaseResult | None = None
    try:
        try:
            out = _run_case(case, options, reporter, runs, progress)
        except Exception as exc:
            reason = crash_reason(f"the case {case.id} crashed", exc, log_dir)
            out = CaseResult(case.id, case.title, case.file_name, case.requirements, Verdict.ERROR, runs=runs,
                             errors=[reason], case=case)
        out.elapsed_s = time.perf_counter() - started
        _notify(reporter and reporter.case_finished, out, out_dir=log_dir)
    except KeyboardInterrupt as exc:
        by = signal_name(exc)
        if out is None:
            out = CaseResult(case.id, case.title, case.file_name, case.requirements, Verdict.ERROR, runs=list(runs),
                             errors=[progress.unfinished(by, len(runs))], case=case)
            out.elapsed_s = time.perf_counter() - started
            raise CaseInterrupted(by, out, finished=False) from exc
        raise CaseInterrupted(by, out, finished=True) from exc
    return out


@dataclass
class _CaseProgress:
    """How far a case got: the runs it plans and the one running (for an interrupt's reason)."""

    planned: int | None = None
    running: tuple[str, Path] | None = None  # ("seed 2 of variant fast", its recording)

    def unfinished(self, by: str, done: int) -> str:
        of = f" of {self.planned}" if self.planned is not None else ""
        now = ""
        if self.running is not None:
            which, path = self.running
            now = f"; the run of {which} was interrupted" + (f", its recording {path} finished as far as it got"
                                                             if path.exists() else "")
        return f"interrupted by {by}: the case did not finish ({done}{of} run(s) finished{now}); not judged"


def _run_case(
    case: TestCase, options: SuiteOptions, reporter: SuiteReporter | None, runs: list[RunResult],
    state: _CaseProgress,
) -> CaseResult:
    case = prepare_case(case, options)
    log_dir = Path(options.out_dir)
    out_dir = log_dir / "recordings" / case.id
    out_dir.mkdir(parents=True, exist_ok=True)
    variants = case.variants()
    state.planned = len(variants) * len(case.run.seeds)
    _notify(reporter and reporter.case_started, case, state.planned, out_dir=log_dir)
    errors: list[str] = []
    for v in variants:
        cv = case.for_variant(v)
        for seed in cv.run.seeds:
            progress = _quiet_progress(_notify(reporter and reporter.run_started, cv, seed, out_dir=log_dir), log_dir)

            def failed(reason: str, cv: TestCase = cv, seed: int = seed, v: str | None = v) -> RunResult:
                return RunResult(str(out_dir / recording_name(cv, seed)), case.id, v, seed, Verdict.ERROR, [reason])

            which = f"seed {seed}" + (f" of variant {v}" if v else "")
            state.running = (which, out_dir / recording_name(cv, seed))
            try:
                runner = runner_for(cv)
                path = runner.run(cv, seed, out_dir, progress=progress)
                _, result = score_recording(path, case)
            except ConfigError as exc:
                errors.append(f"configuration error: {exc}")
                result = failed(str(exc))
            except BenchError as exc:
                result = failed(f"the run could not be executed: {type(exc).__name__}: {exc}")
            except Exception as exc:  # a crash of the runner, the scoring or the environment (disk full)
                result = failed(crash_reason(f"the run of {which} crashed", exc, log_dir))
            runs.append(result)
            state.running = None
            _notify(reporter and reporter.run_finished, cv, result, out_dir=log_dir)
            if errors:
                break
        if errors:
            break
    return judge_case(case, runs, errors)


def run_suite(
    paths: Iterable[str | Path], options: SuiteOptions, reporter: SuiteReporter | None = None
) -> list[CaseResult]:
    """Load, run and judge every case found in ``paths``; one case's crash is that case's
    ERROR, the others still run. An interrupt raises :class:`SuiteInterrupted` with every
    case's result (see the module docstring)."""
    results: list[CaseResult] = []
    log_dir = Path(options.out_dir)
    files = collect_cases(paths)
    finished: list[str] = []
    for path in files:
        try:
            _run_one(path, options, reporter, results, log_dir)
            finished.append(results[-1].case_id)
        except CaseInterrupted as exc:
            results.append(exc.result)
            raise _suite_interrupted(exc.by, results, files, finished + [exc.result.case_id] * exc.finished,
                                     [] if exc.finished else [exc.result.case_id]) from exc
        except KeyboardInterrupt as exc:  # while loading a case file or reporting progress
            finished += [r.case_id for r in results[len(finished):]]
            raise _suite_interrupted(signal_name(exc), results, files, finished, []) from exc
    return results


def _run_one(path: Path, options: SuiteOptions, reporter: SuiteReporter | None, results: list[CaseResult],
             log_dir: Path) -> None:
    """Load, run and judge the case file ``path``; its result appended to ``results``."""
    try:
        case = load_case(path)
        refuse_impossible_faults(case, options)
    except ConfigError as exc:
        results.append(load_error(path, exc))
    except OSError as exc:  # a case file that cannot be read is malformed input
        results.append(load_error(path, ConfigError(exc.strerror or str(exc), file=str(path))))
    except Exception as exc:
        reason = crash_reason(f"the case file {path} could not be loaded", exc, log_dir)
        results.append(CaseResult(path.stem, "(not loaded)", str(path), (), Verdict.ERROR, errors=[reason]))
    else:
        results.append(run_case(case, options, reporter))
        return
    _notify(reporter and reporter.case_finished, results[-1], out_dir=log_dir)


def _suite_interrupted(by: str, results: list[CaseResult], files: list[Path], finished: list[str],
                       unfinished: list[str]) -> SuiteInterrupted:
    """The interrupt of a suite: the case files without a result are ERROR "not run"."""
    not_run = [_not_run(path, by) for path in files[len(results):]]
    results.extend(not_run)
    return SuiteInterrupted(Interruption(by, tuple(finished), tuple(unfinished), tuple(c.case_id for c in not_run)),
                            results)


def _not_run(path: Path, by: str) -> CaseResult:
    """The result of a case the interrupt came before: ERROR, its id and title if it loads."""
    reason = f"interrupted by {by}: not run"
    try:
        case = load_case(path)
    except Exception:  # loaded only to name it: a broken file is still just "not run"
        return CaseResult(path.stem, "(not run)", str(path), (), Verdict.ERROR, errors=[reason])
    return CaseResult(case.id, case.title, case.file_name, case.requirements, Verdict.ERROR, errors=[reason],
                      case=case)
