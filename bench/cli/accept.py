"""``bench accept [PATHS]``: run an acceptance suite and judge it.

Every test case found (``test_cases/`` by default) is run for each variant and seed
through its runner, every recording is judged as ``bench score`` would judge it, and
the results go under the output folder (``reports/`` by default): recordings,
``results.json``, ``junit.xml``, ``summary.txt``/``summary.md``, error plots, and the
certification report ``report.html`` and ``report.pdf`` (:mod:`bench.cli.report`;
``--no-report`` leaves it out).

Exit codes: 0 every case PASS or MARGINAL; 1 a case FAILed; 2 a case file is malformed
(or bad usage); 3 a case could not be judged (ERROR), a report could not be written, or
the suite was interrupted. A case that crashes is that case's ERROR
(:mod:`bench.acceptance.suite`); the suite goes on and every report is still written (a
report that fails does not stop the others).

Every report is written whole or not at all (:mod:`bench.atomic`); when one could not be
written (a full disk), stderr names it with the reason and one line lists exactly the
files written and those not written (:func:`write_suite_reports`). An interrupted suite
(Ctrl-C, SIGTERM) still writes the reports of the cases that finished, marked incomplete
(the record's ``interrupted`` block, the summaries' first line, a JUnit error, the
report's banner), and exits 3.

Recordings are evidence: before anything runs, the recordings the suite would write are
looked for, and an existing one is not overwritten without ``--force`` (nor, even with
it, one another bench is writing); the reports (``results.json``...) are rewritten.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import shlex
import sys
import time
from collections.abc import Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bench.acceptance.interrupted import Interruption, signal_name
from bench.cli.app import EXIT_ERROR, EXIT_FAIL, EXIT_OK, EXIT_USAGE
from bench.cli.progress import end_line, progress_bar
from bench.textsafe import for_terminal

if TYPE_CHECKING:
    from bench.acceptance.judge import CaseResult
    from bench.report.outputs import Ledger

__all__ = [
    "register", "exit_code", "recording_targets", "clear_recordings", "reproduction", "rerun_folder", "in_folder",
    "write_suite_reports",
]


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


def rerun_folder(out: Path, started_utc: str) -> Path:
    """A fresh output folder for rerunning a suite whose output went to ``out``: beside it,
    named after it and the start time (``reports`` -> ``reports-rerun-20261206T110416Z``), so
    the rerun neither meets the first run's recordings (not overwritten without ``--force``)
    nor overwrites them."""
    if out.name in ("", ".", ".."):
        out = Path(os.path.abspath(out))
    stamp = "".join(ch for ch in started_utc.split("+")[0] if ch.isalnum())
    return out.with_name(f"{out.name}-rerun-{stamp}Z")


def in_folder(cwd: str, parts: Sequence[str]) -> str:
    """``cd CWD && COMMAND``: the command line as run, from where it was run (relative
    paths stay as the user gave them)."""
    return f"cd {shlex.quote(cwd)} && {shlex.join(parts)}"


def reproduction(args: argparse.Namespace, out: Path | None = None, started_utc: str = "") -> str:
    """The ``bench accept`` command line that reruns this suite: from the folder it was run
    in, the paths as given, a fresh output folder (:func:`rerun_folder`; the output folder
    as given when ``out`` is None), and the options that change what runs, not how it is
    shown."""
    parts = ["bench", "accept", *(args.paths or [])]
    if out is not None:
        parts += ["-o", str(rerun_folder(out, started_utc))]
    elif args.out:
        parts += ["-o", str(args.out)]
    for s in args.seed or []:
        parts += ["--seed", str(s)]
    if args.runs is not None:
        parts += ["--runs", str(args.runs)]
    if args.clock:
        parts += ["--clock", args.clock]
    return in_folder(os.getcwd(), parts)


def _report(record: Path, out: Path, ledger: Ledger, *, figures: bool, quiet: bool) -> dict[str, Path]:
    """report.html and report.pdf of the suite just judged (figures from its recordings),
    each entered in ``ledger`` as written or not (a failure is noted there, an interrupt
    goes on once it is)."""
    from bench.report.build import build_report, commands_for, folder_locator
    from bench.report.outputs import crash_reason

    meant = [out / "report.html", out / "report.pdf"]
    done: list[Path] = []
    try:
        results = json.loads(record.read_text(encoding="utf-8"))
        command, rescore = commands_for(results, out=out)
        with progress_bar("report: figures", 1, unit="recordings", enabled=figures and not quiet) as bar:
            files = build_report(results, out, locate=folder_locator(out), figures=figures, command=command,
                                 rescore_command=rescore, progress=bar, written=done.append)
    except Exception as exc:  # the record is written: the run's verdict stands, the exit code says ERROR
        why = crash_reason("report.html/report.pdf", exc, out)
        _enter(ledger, meant, done, why)
        return {}
    except KeyboardInterrupt as exc:
        _enter(ledger, meant, done, f"interrupted by {signal_name(exc)}")
        raise
    for p in done:
        ledger.wrote(p)
    for note in files.figure_notes:
        print(for_terminal(f"bench accept: report: {note}"), file=sys.stderr)
    return {"html": files.html, **({"pdf": files.pdf} if files.pdf is not None else {})}


def _enter(ledger: Ledger, meant: list[Path], done: list[Path], why: str) -> None:
    for p in meant:
        if p in done:
            ledger.wrote(p)
        else:
            ledger.missed(p, why)


def write_suite_reports(
    command: str,
    results: Sequence[CaseResult],
    out: Path,
    run_info: dict[str, Any],
    *,
    interruption: Interruption | None,
    plots: bool,
    report: bool,
    quiet: bool,
) -> tuple[dict[str, Path], list[str], bool]:
    """Write the reports of a suite (``bench accept``; ``bench run``, one case) and say on
    stderr what could not be written; returns the files written by kind, the failures that
    make the exit code 3, and whether an interrupt cut the writing.

    Each file is written whole or not at all; when one was not written, or the suite was
    interrupted, one line lists exactly the files written and those not written
    (``bench accept: reports in OUT: written: ...; not written: ...``)."""
    from bench.cli.summary import terminal_summary
    from bench.report.outputs import Ledger, crash_note, write_reports

    ledger = Ledger(out)
    written: dict[str, Path] = {}
    cut: KeyboardInterrupt | None = None
    failures: list[str] = []
    try:
        written = write_reports(results, out, run_info, plots=plots, ledger=ledger, interrupted=interruption)
        if report:
            if "json" in written:
                written.update(_report(written["json"], out, ledger, figures=plots, quiet=quiet))
            else:
                for name in ("report.html", "report.pdf"):
                    ledger.missed(out / name, "not attempted: results.json was not written")
    except KeyboardInterrupt as exc:  # a third signal, or one held while the records were written
        cut = exc
    try:
        print(terminal_summary(results, interrupted=interruption, written=written))
    except Exception as exc:  # the reports are written: say so rather than lose the exit code
        failures.append(crash_note("the summary table", exc, out))
    for note in ledger.notes:
        print(for_terminal(f"{command}: could not write {note}"), file=sys.stderr)
    for note in failures:
        print(for_terminal(f"{command}: could not print {note}"), file=sys.stderr)
    if ledger.not_written or interruption is not None or cut is not None:
        print(for_terminal(f"{command}: {ledger.line()}"), file=sys.stderr)
    if interruption is not None:
        print(for_terminal(f"{command}: the reports are of what finished, marked incomplete "
                           f"({interruption.cases()})"), file=sys.stderr)
    if cut is not None:
        print(for_terminal(f"bench: interrupted by {signal_name(cut)} (while writing the reports)"), file=sys.stderr)
    elif interruption is not None:
        print(for_terminal(f"bench: interrupted by {interruption.by}"), file=sys.stderr)
    return written, ledger.failures + failures, cut is not None


def _run(args: argparse.Namespace) -> int:
    from bench.acceptance.suite import SuiteInterrupted, SuiteOptions, collect_cases, run_suite
    from bench.paths import reports_dir, test_cases_dir
    from bench.record.lock import preflight_folder

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
    interruption = None
    try:
        results = run_suite(files, options, _Reporter(len(files), args.quiet))
    except SuiteInterrupted as exc:  # the reports of what finished are still written, marked incomplete
        end_line()  # a bar the interrupt cut ends where it stood: what follows starts on its own line
        results, interruption = exc.results, exc.interruption
    elapsed = time.perf_counter() - started
    run_info = {"started_utc": when, "elapsed_s": round(elapsed, 3), "paths": [str(p) for p in files],
                "command": reproduction(args, out, when)}
    written, failures, cut = write_suite_reports("bench accept", results, out, run_info, interruption=interruption,
                                                 plots=not args.no_plots, report=not args.no_report,
                                                 quiet=args.quiet)
    names = ", ".join(str(written[k]) for k in ("json", "junit", "summary", "html", "pdf") if k in written)
    names = names or "none written"
    print(f"\n{len(results)} case(s) in {elapsed:.1f} s; results: {names}")
    if interruption is not None or cut:
        return EXIT_ERROR
    code = exit_code(results)
    return EXIT_ERROR if failures and code in (EXIT_OK, EXIT_FAIL) else code
