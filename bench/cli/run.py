"""``bench run CASE``: run one test case through the run engine and judge it.

Runs every variant and seed of the case (or those chosen), writes the recordings and the
results under the output folder (``reports/runs/<case id>`` by default) and prints the
verdicts. Exit codes: 0 PASS or MARGINAL, 1 the DUT failed, 2 usage or configuration
error, 3 bench error (the run could not be judged). Recordings of an earlier run in the
output folder are not overwritten without ``--force`` (as ``bench accept``).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import shlex
import sys
import time
from pathlib import Path

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


def _reproduction(args: argparse.Namespace) -> str:
    """The ``bench run`` command line that reruns this case."""
    parts = ["bench", "run", str(args.case)]
    if args.out:
        parts += ["-o", str(args.out)]
    for s in args.seed or []:
        parts += ["--seed", str(s)]
    for flag, value in (("--variant", args.variant), ("--clock", args.clock), ("--speed", args.speed)):
        if value is not None:
            parts += [flag, f"{value:g}" if isinstance(value, float) else str(value)]
    return shlex.join(parts)


def _run(args: argparse.Namespace) -> int:
    from bench.acceptance.case import load_case
    from bench.acceptance.suite import SuiteOptions, refuse_impossible_faults, run_case
    from bench.cli.accept import _Reporter, clear_recordings, exit_code
    from bench.errors import ConfigError
    from bench.paths import reports_dir
    from bench.record.lock import preflight_folder
    from bench.report.outputs import write_reports
    from bench.report.table import text_table

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
    result = run_case(case, options, _Reporter(1, args.quiet))
    elapsed = time.perf_counter() - started
    written = write_reports([result], out, {"started_utc": when, "elapsed_s": round(elapsed, 3),
                                            "paths": [str(args.case)], "command": _reproduction(args)},
                            plots=not args.no_plots)
    print(text_table([result]))
    for run in result.runs:
        print(f"  recording: {run.recording}", file=sys.stderr)
    print(f"\n{case.id} in {elapsed:.1f} s; results: {written['json']}")
    return exit_code([result])
