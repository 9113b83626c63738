"""``bench run CASE``: run one test case through the run engine and judge it.

Runs every variant and seed of the case (or those chosen), writes the recordings and the
results under the output folder (``reports/runs/<case id>`` by default) and prints the
verdicts. Exit codes: 0 PASS or MARGINAL, 1 the DUT failed, 2 usage or configuration
error, 3 bench error (the run could not be judged, a report could not be written, or the
case was interrupted). Recordings of an earlier run in the output folder are not
overwritten without ``--force`` (as ``bench accept``).

The reports are written as ``bench accept`` writes them (:func:`bench.cli.accept.write_suite_reports`):
each whole or not at all, a message listing exactly what was and was not written when one
could not be, and, when the case is interrupted (Ctrl-C, SIGTERM), the reports of the runs
that had finished, marked incomplete.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import os
import sys
import time
from pathlib import Path

from bench.textsafe import for_terminal

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``run`` subcommand."""
    p = sub.add_parser("run", help="run one test case (its DUT on its links) and judge it",
                       description="Run a test case through the run engine: its scenario, sensors and faults on "
                       "the ICD links to its DUT (in process, external process, or hardware), lockstep or real "
                       "time, one MCAP recording per run, then judge the recordings.")
    p.add_argument("case", help="test case file")
    p.add_argument("-o", "--out", help="output folder (default: reports/runs/<case id>)")
    p.add_argument("--seed", type=int, action="append", help="run only this seed (repeatable)")
    p.add_argument("--variant", help="run only this DUT variant")
    p.add_argument("--clock", choices=("lockstep", "realtime"), help="override the case's clock mode")
    p.add_argument("--speed", type=float, help="real-time speed factor (0.5 half speed, 2 twice as fast)")
    p.add_argument("--force", action="store_true", help="overwrite earlier recordings in the output folder")
    p.add_argument("--no-plots", action="store_true", help="do not draw error plots")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    p.set_defaults(handler=_run)


def _reproduction(args: argparse.Namespace, out: Path, started_utc: str) -> str:
    """The ``bench run`` command line that reruns this case, from the folder it was run in,
    into a fresh output folder (:func:`bench.cli.accept.rerun_folder`)."""
    from bench.cli.accept import in_folder, rerun_folder

    parts = ["bench", "run", str(args.case), "-o", str(rerun_folder(out, started_utc))]
    for s in args.seed or []:
        parts += ["--seed", str(s)]
    for flag, value in (("--variant", args.variant), ("--clock", args.clock), ("--speed", args.speed)):
        if value is not None:
            parts += [flag, f"{value:g}" if isinstance(value, float) else str(value)]
    return in_folder(os.getcwd(), parts)


def _run(args: argparse.Namespace) -> int:
    from bench.acceptance.case import load_case
    from bench.acceptance.interrupted import Interruption
    from bench.acceptance.suite import CaseInterrupted, SuiteOptions, refuse_impossible_faults, run_case
    from bench.cli.accept import _Reporter, clear_recordings, exit_code, write_suite_reports
    from bench.cli.app import EXIT_ERROR, EXIT_FAIL, EXIT_OK
    from bench.cli.progress import end_line
    from bench.errors import ConfigError
    from bench.paths import reports_dir
    from bench.record.lock import preflight_folder

    case = load_case(args.case)
    if args.variant is not None:
        if args.variant not in case.dut.variants:
            raise ConfigError(f"no variant {args.variant!r}; the case has {', '.join(case.dut.variants) or 'none'}",
                              file=case.file, key="dut.variants")
        case = dataclasses.replace(case, dut=dataclasses.replace(
            case.dut, variants={args.variant: case.dut.variants[args.variant]}))
    if args.speed is not None:
        if args.speed <= 0:
            raise ConfigError(f"expected a positive speed, found {args.speed}", key="--speed")
        case = dataclasses.replace(case, clock=dataclasses.replace(case.clock, speed=args.speed))
    out = Path(args.out) if args.out else reports_dir() / "runs" / case.id
    options = SuiteOptions(out, tuple(args.seed) if args.seed else None, None, args.clock)
    refuse_impossible_faults(case, options)
    preflight_folder(out)
    clear_recordings([case], options, args.force)
    started = time.perf_counter()
    when = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    interruption = None
    try:
        result = run_case(case, options, _Reporter(1, args.quiet))
    except CaseInterrupted as exc:  # the reports of the runs that finished are still written
        end_line()  # a bar the interrupt cut ends where it stood: what follows starts on its own line
        result = exc.result
        interruption = Interruption(exc.by, (result.case_id,) if exc.finished else (),
                                    () if exc.finished else (result.case_id,))
    elapsed = time.perf_counter() - started
    run_info = {"started_utc": when, "elapsed_s": round(elapsed, 3), "paths": [str(args.case)],
                "command": _reproduction(args, out, when)}
    written, failures, cut = write_suite_reports("bench run", [result], out, run_info, interruption=interruption,
                                                 plots=not args.no_plots, report=False, quiet=args.quiet)
    for run in result.runs:  # only recordings that exist: a DUT that failed to load wrote none
        if Path(run.recording).is_file():
            print(for_terminal(f"  recording: {run.recording}"), file=sys.stderr)
        else:
            which = f"seed {run.seed}" + (f" of variant {run.variant}" if run.variant else "")
            print(for_terminal(f"  {which}: no recording was written (the summary says why)"), file=sys.stderr)
    print(f"\n{case.id} in {elapsed:.1f} s; results: {written.get('json') or 'none written'}")
    if interruption is not None or cut:
        return EXIT_ERROR
    code = exit_code([result])
    return EXIT_ERROR if failures and code in (EXIT_OK, EXIT_FAIL) else code
