"""``bench export`` and ``bench import-nav``: runs in and out of the i2Nav text formats.

``bench export RUN.mcap --format i2nav -o DIR [--imu measured|ideal] [--dut]`` writes the
run's sensor streams, truth and KF-GINS configuration (and with ``--dut`` its DUT
solution as ``dut.nav`` and ``dut_std.txt``); ``bench import-nav RESULT.nav --run RUN.mcap
[--std STD.txt] [-o OUT.mcap] [--force]`` writes a recording of the run whose DUT output is
the result, for ``bench score``. ``docs/exchange.md`` has the formats.
"""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["register"]


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
    p.set_defaults(handler=_export)

    q = sub.add_parser("import-nav", help="make a .nav result the DUT output of a run's recording",
                       description="Read a .nav result (KF-GINS columns) and write a recording holding the run's "
                       "content with the result as its DUT output, judged by bench score like any run.")
    q.add_argument("nav", help="the .nav result")
    q.add_argument("--run", required=True, help="the run's recording the result belongs to")
    q.add_argument("--std", help="the result's state-STD file (KF-GINS columns; gives NAV_QUALITY)")
    q.add_argument("-o", "--output", help="output MCAP file (default: RESULT.mcap beside the result)")
    q.add_argument("--force", action="store_true", help="overwrite an existing output file")
    q.set_defaults(handler=_import)


def _export(args: argparse.Namespace) -> int:
    from bench.exchange.i2nav_export import export_i2nav
    from bench.record.lock import preflight_folder

    preflight_folder(args.out)
    s = export_i2nav(args.recording, args.out, imu=args.imu, dut=args.dut)
    print(f"{s.folder}: GPS week {s.week} (GPS - UTC {s.leap_s} s), IMU from {s.imu_topic}")
    for name, n in s.lines.items():
        print(f"  {name:<14} {n:>10} lines")
    return 0


def _import(args: argparse.Namespace) -> int:
    from bench.exchange.nav_import import import_nav
    from bench.record.lock import preflight

    out = Path(args.output) if args.output else Path(args.nav).with_suffix(".mcap")
    preflight(out, force=args.force)
    counts = import_nav(args.nav, args.run, out, std=args.std, overwrite=args.force)
    extra = ", ".join(f"{k} {v}" for k, v in counts.items() if k not in ("solutions", "qualities"))
    print(f"{out}: {counts['solutions']} solutions, {counts['qualities']} qualities imported"
          + (f"; rejected by the receiver: {extra}" if extra else ""))
    return 0
