"""Running test cases: every variant and seed through its runner, then judged.

:func:`run_case` executes the runs of one case (one recording each, under
``<out>/recordings/<case id>/``), judges every recording exactly as ``bench score`` does,
and combines them with :func:`~bench.acceptance.judge.judge_case`. :func:`run_suite`
does so for every case file found. A case that does not load is ERROR with the
configuration error as its reason; a run the runner could not execute is ERROR.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from bench.acceptance.case import TestCase, is_case_file, load_case
from bench.acceptance.judge import CaseResult, RunResult, judge_case, score_recording
from bench.acceptance.runner import Progress, recording_name, runner_for
from bench.acceptance.verdict import Verdict
from bench.errors import BenchError, ConfigError

__all__ = ["SuiteOptions", "SuiteReporter", "collect_cases", "prepare_case", "run_case", "run_suite", "load_error"]


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


def load_error(path: Path, exc: Exception) -> CaseResult:
    """The result of a case file that could not be loaded."""
    return CaseResult(path.stem, "(not loaded)", str(path), (), Verdict.ERROR, errors=[f"configuration error: {exc}"])


def run_case(case: TestCase, options: SuiteOptions, reporter: SuiteReporter | None = None) -> CaseResult:
    """Run and judge every variant and seed of ``case``."""
    started = time.perf_counter()
    case = prepare_case(case, options)
    out_dir = Path(options.out_dir) / "recordings" / case.id
    out_dir.mkdir(parents=True, exist_ok=True)
    variants = case.variants()
    if reporter:
        reporter.case_started(case, len(variants) * len(case.run.seeds))
    runs: list[RunResult] = []
    errors: list[str] = []
    for v in variants:
        cv = case.for_variant(v)
        for seed in cv.run.seeds:
            progress = reporter.run_started(cv, seed) if reporter else None
            try:
                runner = runner_for(cv)
                path = runner.run(cv, seed, out_dir, progress=progress)
                _, result = score_recording(path, case)
            except ConfigError as exc:
                errors.append(f"configuration error: {exc}")
                result = RunResult(str(out_dir / recording_name(cv, seed)), case.id, v, seed, Verdict.ERROR, [str(exc)])
            except (BenchError, OSError) as exc:
                result = RunResult(
                    str(out_dir / recording_name(cv, seed)),
                    case.id,
                    v,
                    seed,
                    Verdict.ERROR,
                    [f"the run could not be executed: {type(exc).__name__}: {exc}"],
                )
            runs.append(result)
            if reporter:
                reporter.run_finished(cv, result)
            if errors:
                break
        if errors:
            break
    out = judge_case(case, runs, errors)
    out.elapsed_s = time.perf_counter() - started
    if reporter:
        reporter.case_finished(out)
    return out


def run_suite(
    paths: Iterable[str | Path], options: SuiteOptions, reporter: SuiteReporter | None = None
) -> list[CaseResult]:
    """Load, run and judge every case found in ``paths``."""
    results: list[CaseResult] = []
    for path in collect_cases(paths):
        try:
            case = load_case(path)
        except ConfigError as exc:
            results.append(load_error(path, exc))
            if reporter:
                reporter.case_finished(results[-1])
            continue
        results.append(run_case(case, options, reporter))
    return results
