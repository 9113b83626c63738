"""``bench export`` and ``bench import-nav``: runs in and out of the i2Nav text formats.

``bench export RUN.mcap --format i2nav -o DIR [--imu measured|ideal] [--dut]`` writes the
run's sensor streams, truth and KF-GINS configuration (and with ``--dut`` its DUT
solution as ``dut.nav`` and ``dut_std.txt``); ``bench import-nav RESULT.nav --run RUN.mcap
[--std STD.txt] [-o OUT.mcap] [--force]`` writes a recording of the run whose DUT output is
the result, for ``bench score``. ``docs/exchange.md`` has the formats.

A recording that is unfinished, damaged or made from such a one (:mod:`bench.record.provenance`)
is a source that cannot be trusted. ``import-nav`` onto it writes the copy with that state
in its ``run_start`` (judged ERROR) and exits 3 naming it; ``export`` of it writes nothing
and exits 3 (text files cannot carry the state). With ``--accept-damaged-source`` both
write what can be read, say so (the copy's ``run_start``; ``export.json`` and
``SOURCE_PROBLEMS.txt``), and exit 0.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping
from pathlib import Path

from bench.textsafe import for_terminal

__all__ = ["register", "say_source"]

_ACCEPT_HELP = "{what} (recorded in {where}); without it {without}"


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``export`` and ``import-nav`` subcommands."""
    p = sub.add_parser("export", help="export a run's sensor streams and truth as text files (i2Nav formats)",
                       description="Write a recording's IMU, BDS, odometer and Doppler samples, its truth (and its "
                       "DUT solution) in the text formats of the i2Nav estimators (KF-GINS, OB_GINS), with a "
                       "KF-GINS configuration file (docs/exchange.md).")
    p.add_argument("recording", help="a run's (or bench synth's) MCAP recording")
    p.add_argument("--format", choices=("i2nav",), default="i2nav", help="the file formats (default i2nav)")
    p.add_argument("-o", "--out", required=True, help="output folder (created; its files are replaced)")
    p.add_argument("--imu", choices=("measured", "ideal"), default="measured",
                   help="the IMU samples as sent (/imu, default) or error-free (/imu/ideal, bench synth only)")
    p.add_argument("--dut", action="store_true", help="also write the DUT's solution (dut.nav, dut_std.txt)")
    p.add_argument("--accept-damaged-source", action="store_true", help=_ACCEPT_HELP.format(
        what="export an unfinished or damaged recording as far as it can be read",
        where="export.json and SOURCE_PROBLEMS.txt", without="nothing is exported (exit 3)"))
    p.set_defaults(handler=_export)

    q = sub.add_parser("import-nav", help="make a .nav result the DUT output of a run's recording",
                       description="Read a .nav result (KF-GINS columns) and write a recording holding the run's "
                       "content with the result as its DUT output, judged by bench score like any run.")
    q.add_argument("nav", help="the .nav result")
    q.add_argument("--run", required=True, help="the run's recording the result belongs to")
    q.add_argument("--std", help="the result's state-STD file (KF-GINS columns; gives NAV_QUALITY)")
    q.add_argument("-o", "--output", help="output MCAP file (default: RESULT.mcap beside the result)")
    q.add_argument("--force", action="store_true", help="overwrite an existing output file")
    q.add_argument("--accept-damaged-source", action="store_true", help=_ACCEPT_HELP.format(
        what="judge the import onto an unfinished or damaged recording anyway",
        where="the output's metadata and its results", without="it is judged ERROR (exit 3)"))
    q.set_defaults(handler=_import)


def _export(args: argparse.Namespace) -> int:
    from bench.exchange.i2nav_export import export_i2nav
    from bench.record.lock import preflight_folder

    preflight_folder(args.out)
    s = export_i2nav(args.recording, args.out, imu=args.imu, dut=args.dut,
                     accept_damaged_source=args.accept_damaged_source)
    print(f"{s.folder}: GPS week {s.week} (GPS - UTC {s.leap_s} s), IMU from {s.imu_topic}")
    for name, n in s.lines.items():
        print(f"  {name:<14} {n:>10} lines")
    if s.problems:
        print(for_terminal(f"bench export: the source cannot be trusted: {'; '.join(s.problems)}; exported as far "
                           "as it could be read, as asked (export.json and SOURCE_PROBLEMS.txt say so)"),
              file=sys.stderr)
    return 0


def _import(args: argparse.Namespace) -> int:
    from bench.exchange.nav_import import import_nav
    from bench.record.lock import preflight
    from bench.record.mcap_io import RecordingReader

    out = Path(args.output) if args.output else Path(args.nav).with_suffix(".mcap")
    preflight(out, force=args.force)
    counts = import_nav(args.nav, args.run, out, std=args.std, overwrite=args.force,
                        accept_damaged_source=args.accept_damaged_source)
    extra = ", ".join(f"{k} {v}" for k, v in counts.items() if k not in ("solutions", "qualities"))
    print(for_terminal(f"{out}: {counts['solutions']} solutions, {counts['qualities']} qualities imported"
                       + (f"; rejected by the receiver: {extra}" if extra else "")))
    with RecordingReader(out) as written:
        source = written.metadata().get("run_start", {})
    return say_source("bench import-nav", out, source)


def say_source(command: str, out: str | Path, source: Mapping[str, str]) -> int:
    """Tell what ``command`` wrote to ``out`` from a source that cannot be trusted (its
    ``run_start`` fields ``source``, :mod:`bench.record.provenance`); the exit code: 3 when
    the output will be judged ERROR for it, else 0."""
    from bench.cli.app import EXIT_ERROR, EXIT_OK
    from bench.record.provenance import ACCEPT_FLAG

    try:
        problems = [str(p) for p in json.loads(source.get("source_problems", "[]"))]
    except (TypeError, ValueError):
        problems = ["its source_problems metadata does not parse"]
    if source.get("source_complete") == "false" and not problems:
        problems = ["its own source was not complete"]
    if not problems:
        return EXIT_OK
    what = "; ".join(problems)
    if source.get("accept_damaged_source") == "true":
        print(for_terminal(f"{command}: the source cannot be trusted: {what}; {out} is judged anyway, as asked "
                           "(its metadata and its results say so)"), file=sys.stderr)
        return EXIT_OK
    print(for_terminal(f"{command}: ERROR: the source cannot be trusted: {what}; {out} carries this and is judged "
                       f"ERROR (pass {ACCEPT_FLAG} to judge it anyway)"), file=sys.stderr)
    return EXIT_ERROR
