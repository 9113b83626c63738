"""``bench accept [PATHS]``: run an acceptance suite and judge it.

Every test case found (``test_cases/`` by default) is run for each variant and seed
through its runner, every recording is judged as ``bench score`` would judge it, and
the results go under the output folder (``reports/`` by default): recordings,
``results.json``, ``junit.xml``, ``summary.txt``/``summary.md``, error plots, and the
certification report ``report.html`` and ``report.pdf`` (:mod:`bench.cli.report`;
``--no-report`` leaves it out).

Exit codes: 0 every case PASS or MARGINAL; 1 a case FAILed; 2 a case file is malformed
(or bad usage); 3 a case could not be judged (ERROR), or a report could not be written.
A case that crashes is that case's ERROR (:mod:`bench.acceptance.suite`); the suite goes
on and every report is still written (a report that fails does not stop the others).

Recordings are evidence: before anything runs, the recordings the suite would write are
looked for, and an existing one is not overwritten without ``--force`` (nor, even with
it, one another bench is writing); the reports (``results.json``...) are rewritten.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import shlex
import sys
import time
from contextlib import ExitStack
from pathlib import Path

from bench.cli.app import EXIT_ERROR, EXIT_FAIL, EXIT_OK, EXIT_USAGE
from bench.cli.progress import progress_bar
from bench.textsafe import for_terminal

__all__ = ["register", "exit_code", "recording_targets", "clear_recordings", "reproduction"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``accept`` subcommand."""
    p = sub.add_parser(
        "accept",
        help="run and judge acceptance test cases (the reference suite by default)",
        description="Run every test case under PATHS (default test_cases/) for each variant and seed, judge "
        "the recordings and write results.json, junit.xml, summary tables and plots to the output folder.",
    )
    p.add_argument("paths", nargs="*", help="case files or folders (default: test_cases/)")
    p.add_argument("-o", "--out", help="output folder (default: reports/)")
    p.add_argument("--seed", type=int, action="append", help="run only this seed (repeatable)")
    p.add_argument("--runs", type=int, help="Monte Carlo runs per case and variant (seeds from the case's first)")
    p.add_argument("--clock", choices=("lockstep", "realtime"), help="override the cases' clock mode")
    p.add_argument("--force", action="store_true", help="overwrite earlier recordings in the output folder")
    p.add_argument("--no-plots", action="store_true", help="do not draw error plots (nor the report's figures)")
    p.add_argument("--no-report", action="store_true", help="do not write report.html and report.pdf")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    p.set_defaults(handler=_run)


class _Reporter:
    """Progress on stderr: a line per case, a bar per run, the verdicts."""

    def __init__(self, total: int, quiet: bool):
        self.total = total
        self.index = 0
        self.quiet = quiet
        self._stack = ExitStack()

    def case_started(self, case, runs: int) -> None:
        self.index += 1
        if not self.quiet:
            line = f"[{self.index}/{self.total}] {case.id}: {case.title} -- {runs} run(s)"
            print(for_terminal(line), file=sys.stderr)

    def run_started(self, case, seed: int):
        if self.quiet:
            return None
        label = for_terminal(f"  {case.label} seed {seed}")
        state: dict = {}

        def progress(done: float, total: float) -> None:
            if "bar" not in state:
                state["bar"] = self._stack.enter_context(progress_bar(label, total))
            state["bar"](done, total)

        return progress

    def run_finished(self, case, result) -> None:
        self._stack.close()
        if not self.quiet:
            print(for_terminal(f"  {case.label} seed {result.seed}: {result.verdict}"), file=sys.stderr)

    def case_finished(self, result) -> None:
        if not self.quiet:
            print(for_terminal(f"  => {result.case_id}: {result.verdict} ({result.elapsed_s:.1f} s)"), file=sys.stderr)


def recording_targets(cases, options) -> list[Path]:
    """The recordings a suite with ``options`` would write for ``cases`` (loaded cases)."""
    from bench.acceptance.runner import recording_name
    from bench.acceptance.suite import prepare_case

    out: list[Path] = []
    for case in cases:
        case = prepare_case(case, options)
        folder = Path(options.out_dir) / "recordings" / case.id
        for v in case.variants():
            cv = case.for_variant(v)
            out += [folder / recording_name(cv, seed) for seed in cv.run.seeds]
    return out


def clear_recordings(cases, options, force: bool) -> None:
    """Refuse (ConfigError) when a recording the suite would write exists and ``force`` is
    not given, or another bench is writing one; with ``force`` remove the old ones."""
    from bench.record.lock import clear_outputs

    clear_outputs(recording_targets(cases, options), force=force)


def _loadable(files) -> list:
    from bench.acceptance.case import load_case
    from bench.errors import ConfigError

    cases = []
    for f in files:
        try:
            cases.append(load_case(f))
        except ConfigError:  # the suite reports it as the case's error
            continue
    return cases


def exit_code(cases) -> int:
    """0 all passed, 1 a FAIL, 2 a malformed case, 3 an ERROR (a malformed case first)."""
    from bench.acceptance.verdict import Verdict

    if any(any(e.startswith("configuration error") for e in c.errors) for c in cases):
        return EXIT_USAGE
    if not cases or any(c.verdict is Verdict.ERROR for c in cases):
        return EXIT_ERROR
    if any(c.verdict is Verdict.FAIL for c in cases):
        return EXIT_FAIL
    return EXIT_OK


def reproduction(args: argparse.Namespace) -> str:
    """The ``bench accept`` command line that reruns this suite (paths and output folder
    as given; the options that change what runs, not how it is shown)."""
    parts = ["bench", "accept", *(args.paths or [])]
    if args.out:
        parts += ["-o", str(args.out)]
    for s in args.seed or []:
        parts += ["--seed", str(s)]
    if args.runs is not None:
        parts += ["--runs", str(args.runs)]
    if args.clock:
        parts += ["--clock", args.clock]
    return shlex.join(parts)


def _report(record: Path, out: Path, *, figures: bool, quiet: bool) -> dict[str, Path]:
    """report.html and report.pdf of the suite just judged (figures from its recordings)."""
    from bench.report.build import build_report, commands_for, folder_locator

    results = json.loads(record.read_text(encoding="utf-8"))
    command, rescore = commands_for(results)
    with progress_bar("report: figures", 1, unit="recordings", enabled=figures and not quiet) as bar:
        files = build_report(results, out, locate=folder_locator(out), figures=figures, command=command,
                             rescore_command=rescore, progress=bar)
    for note in files.figure_notes:
        print(for_terminal(f"bench accept: report: {note}"), file=sys.stderr)
    return {"html": files.html, **({"pdf": files.pdf} if files.pdf is not None else {})}


def _run(args: argparse.Namespace) -> int:
    from bench.acceptance.suite import SuiteOptions, collect_cases, run_suite
    from bench.paths import reports_dir, test_cases_dir
    from bench.record.lock import preflight_folder
    from bench.report.outputs import crash_note, write_reports
    from bench.report.table import text_table

    paths = args.paths or [str(test_cases_dir())]
    out = Path(args.out) if args.out else reports_dir()
    files = collect_cases(paths)
    if not files:
        print(f"bench accept: no test case files in {', '.join(paths)}", file=sys.stderr)
        return EXIT_USAGE
    options = SuiteOptions(out, tuple(args.seed) if args.seed else None, args.runs, args.clock)
    preflight_folder(out)
    clear_recordings(_loadable(files), options, args.force)
    started = time.perf_counter()
    when = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    results = run_suite(files, options, _Reporter(len(files), args.quiet))
    elapsed = time.perf_counter() - started
    run_info = {"started_utc": when, "elapsed_s": round(elapsed, 3), "paths": [str(p) for p in files],
                "command": reproduction(args)}
    failures: list[str] = []
    written = write_reports(results, out, run_info, plots=not args.no_plots, failures=failures)
    if not args.no_report and "json" in written:
        try:
            written.update(_report(written["json"], out, figures=not args.no_plots, quiet=args.quiet))
        except Exception as exc:  # the record is written: the run's verdict stands, the exit code says ERROR
            failures.append(crash_note("report.html/report.pdf", exc, out))
    try:
        print(text_table(results))
    except Exception as exc:  # the reports are written: say so rather than lose the exit code
        failures.append(crash_note("the summary table", exc, out))
    for note in failures:
        print(for_terminal(f"bench accept: could not write {note}"), file=sys.stderr)
    names = ", ".join(str(written[k]) for k in ("json", "junit", "summary", "html", "pdf") if k in written)
    names = names or "none written"
    print(f"\n{len(results)} case(s) in {elapsed:.1f} s; results: {names}")
    code = exit_code(results)
    return EXIT_ERROR if failures and code in (EXIT_OK, EXIT_FAIL) else code
