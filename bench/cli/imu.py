"""``bench imu allan FILE``: IEEE noise terms of a static IMU log by Allan deviation.

Exit codes: 0 the report was written (its warnings say how far the figures go), 2 the
file is not an IMU log (named with what was found) or an option is wrong, 3 the bench
could not read a recording.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``imu`` subcommand group."""
    p = sub.add_parser("imu", help="IMU tools: Allan deviation of a static log or recording")
    s = p.add_subparsers(dest="imu_command", metavar="IMU_COMMAND")
    a = s.add_parser(
        "allan",
        help="Allan deviation and IEEE noise terms of a static IMU log",
        description="Read a static IMU log (PSINS .imu text, KF-GINS imu.txt, gnss-ins-sim output, a "
        "TOML-declared text log, an ICD byte log, or an MCAP recording's IMU topic), "
        "compute the overlapping Allan deviation of each axis, fit quantization, random walk, "
        "bias instability, rate random walk and rate ramp over the averaging times where each "
        "dominates, print the fit residual, and warn when the log is not static. Unresolved terms "
        "are given as upper bounds.",
    )
    a.add_argument("file", help="IMU log (PSINS .imu, KF-GINS imu.txt, gnss-ins-sim output, a TOML-declared text "
                   "log, an ICD byte log of the imu line) or MCAP recording")
    a.add_argument("--format", "--imu-format", dest="format",
                   choices=("icd", "psins", "kfgins", "gnss-ins-sim", "declared"),
                   help="format of a log (default: recognised by its content; docs/exchange.md)")
    a.add_argument("--topic", default="/imu", help="IMU topic of an MCAP recording (default /imu)")
    a.add_argument("--plot", help="write the Allan deviation plot to this PNG file")
    a.set_defaults(handler=_allan)
    p.set_defaults(handler=lambda _a: (p.print_help(), 2)[1])


def _from_recording(path: Path, topic: str) -> Any:
    import numpy as np

    from bench.errors import BenchError, ConfigError
    from bench.record.mcap_io import RecordingReader
    from bench.sensors.imu.logs import ImuLog, check_log

    try:
        reader = RecordingReader(path)
        topics = reader.topics()
        if topic not in topics:
            found = ", ".join(sorted(topics)) or "no topics"
            raise ConfigError(f"no topic {topic!r} in the recording (found {found}); choose one with --topic",
                              file=str(path))
        rec = reader.read_columnar(topic)
    except BenchError:
        raise
    except Exception as exc:  # the MCAP library's own errors on a file that only starts like one
        raise ConfigError(f"not a readable MCAP recording: {type(exc).__name__}: {exc}", file=str(path)) from None
    names = rec.dtype.names or ()
    if not {"t_ns", "dtheta", "dvel"} <= set(names):
        raise ConfigError(f"topic {topic} holds {', '.join(names) or 'no fields'}, not IMU samples "
                          "(t_ns, dtheta, dvel)", file=str(path))
    t = rec["t_ns"].astype(np.int64)
    steps = np.diff(t)
    if len(steps) and np.any(steps <= 0):
        k = int(np.argmax(steps <= 0)) + 1
        raise ConfigError(f"topic {topic}: sample {k} is not later than the one before (t_ns {t[k]} after "
                          f"{t[k - 1]})", file=str(path))
    dt = float(np.median(steps)) * 1e-9 if len(steps) else 0.0
    irregular = int(np.sum(np.abs(steps * 1e-9 - dt) > 0.01 * dt)) if len(steps) else 0
    log = ImuLog(rec["dtheta"].astype(float), rec["dvel"].astype(float), dt, None, f"{path}:{topic}",
                 irregular=irregular)
    check_log(log)
    return log


def sniff_any(path: Path) -> str:
    """``mcap``, ``text``, or ``log`` for binary data holding ICD IMU frames (else the refusal of
    :func:`~bench.sensors.imu.logs.sniff`)."""
    import numpy as np

    from bench.errors import ConfigError
    from bench.sensors.imu.logs import sniff
    from bench.wire.imu_stream import accept_frames

    try:
        return sniff(path)
    except ConfigError:
        if not path.is_file():  # a FIFO or device is never opened
            raise
        try:
            with path.open("rb") as fh:
                head = fh.read(1 << 16)
        except OSError:
            raise
        if accept_frames(np.frombuffer(head, np.uint8))[0].size:
            return "log"
        raise


def _allan(args: argparse.Namespace) -> int:
    from bench.errors import ConfigError
    from bench.exchange.field_logs import imu_log_for_allan
    from bench.sensors.imu.analysis import analyse
    path = Path(args.file)
    kind = "log" if (path.is_dir() and (path / "time.csv").is_file()) or args.format else sniff_any(path)
    if kind == "mcap":
        log = _from_recording(path, args.topic)
    elif path.suffix == ".mcap":
        raise ConfigError("named .mcap but does not start with the MCAP magic; it is text, not a recording",
                          file=str(path))
    else:
        log = imu_log_for_allan(path, args.format)
    report = analyse(log)
    print(report.text())
    if args.plot:
        from bench.report.plots import allan_plot

        allan_plot(report, args.plot)
        print(f"plot: {args.plot}")
    return 0
