"""Running test cases: every variant and seed through its runner, then judged.

:func:`run_case` executes the runs of one case (one recording each, under
``<out>/recordings/<case id>/``), judges every recording exactly as ``bench score`` does,
and combines them with :func:`~bench.acceptance.judge.judge_case`. :func:`run_suite`
does so for every case file found. A case that does not load is ERROR with the
configuration error as its reason; a run the runner could not execute is ERROR.

A crash is contained where it happens: an exception while loading one case file, or
running, scoring or judging one run, makes that case (or run) ERROR with a one-line
reason (its traceback appended to ``<out>/bench-error.log``) and the suite goes on.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from bench.acceptance.case import TestCase, is_case_file, load_case
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
    log_dir = Path(options.out_dir)
    try:
        out = _run_case(case, options, reporter, runs)
    except Exception as exc:
        reason = crash_reason(f"the case {case.id} crashed", exc, log_dir)
        out = CaseResult(case.id, case.title, case.file_name, case.requirements, Verdict.ERROR, runs=runs,
                         errors=[reason], case=case)
    out.elapsed_s = time.perf_counter() - started
    _notify(reporter and reporter.case_finished, out, out_dir=log_dir)
    return out


def _run_case(
    case: TestCase, options: SuiteOptions, reporter: SuiteReporter | None, runs: list[RunResult]
) -> CaseResult:
    case = prepare_case(case, options)
    log_dir = Path(options.out_dir)
    out_dir = log_dir / "recordings" / case.id
    out_dir.mkdir(parents=True, exist_ok=True)
    variants = case.variants()
    _notify(reporter and reporter.case_started, case, len(variants) * len(case.run.seeds), out_dir=log_dir)
    errors: list[str] = []
    for v in variants:
        cv = case.for_variant(v)
        for seed in cv.run.seeds:
            progress = _quiet_progress(_notify(reporter and reporter.run_started, cv, seed, out_dir=log_dir), log_dir)

            def failed(reason: str, cv: TestCase = cv, seed: int = seed, v: str | None = v) -> RunResult:
                return RunResult(str(out_dir / recording_name(cv, seed)), case.id, v, seed, Verdict.ERROR, [reason])

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
                which = f"seed {seed}" + (f" of variant {v}" if v else "")
                result = failed(crash_reason(f"the run of {which} crashed", exc, log_dir))
            runs.append(result)
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
    ERROR, the others still run."""
    results: list[CaseResult] = []
    log_dir = Path(options.out_dir)
    for path in collect_cases(paths):
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
            continue
        _notify(reporter and reporter.case_finished, results[-1], out_dir=log_dir)
    return results
