"""``bench imu allan FILE``: noise terms of a static IMU log by Allan deviation."""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``imu`` subcommand group."""
    p = sub.add_parser("imu", help="IMU tools: Allan deviation of a static log or recording")
    s = p.add_subparsers(dest="imu_command", metavar="IMU_COMMAND")
    a = s.add_parser(
        "allan",
        help="Allan deviation and noise terms of a static IMU log",
        description="Read a static IMU log (PSINS .imu text, or an MCAP recording's IMU topic), "
        "compute the overlapping Allan deviation of each axis, fit angle/velocity random walk "
        "and bias instability, and optionally plot the curves.",
    )
    a.add_argument("file", help="PSINS .imu file or MCAP recording")
    a.add_argument("--topic", default="/imu", help="IMU topic of an MCAP recording (default /imu)")
    a.add_argument("--plot", help="write the Allan deviation plot to this PNG file")
    a.set_defaults(handler=_allan)


def _allan(args: argparse.Namespace) -> int:
    from bench.sensors.imu.analysis import ImuLog, analyse, read_psins_imu

    path = Path(args.file)
    if path.suffix == ".mcap":
        import numpy as np

        from bench.record.mcap_io import RecordingReader

        rec = RecordingReader(path).read_columnar(args.topic)
        dt = float(np.median(np.diff(rec["t_ns"]))) * 1e-9
        log = ImuLog(rec["dtheta"].astype(float), rec["dvel"].astype(float), dt, None, f"{path}:{args.topic}")
    else:
        log = read_psins_imu(path)
    report = analyse(log)
    print(report.text())
    if args.plot:
        from bench.report.plots import allan_plot

        allan_plot(report, args.plot)
        print(f"plot: {args.plot}")
    return 0
