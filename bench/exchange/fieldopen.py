"""Field logs opened for a replay: the options a user gives (``bench replay --imu-log ...``
or a test case's ``[scenario] log`` table) turned into a :class:`~bench.run.logreplay.LogReplay`.

One function for both, so that a case built on a real log and a replay of the same log on
the command line read, convert and place it the same way: logs in other formats
(:mod:`bench.exchange.field_logs`) are converted to the lines' bytes at their own rate, the
epoch is found as docs/exchange.md says, a truth track is read, and every warning of the
conversion and the replay reaches ``say``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bench.faults.schedule import FaultSchedule
from bench.run.logreplay import FieldLogs, LogReplay, TruthTrack
from bench.runinfo import parse_epoch
from bench.units import quantity

__all__ = ["FieldLogOptions", "open_field_logs"]


@dataclass
class FieldLogOptions:
    """What a user says of a drive's logs (the ``bench replay`` options of the same names;
    times as text, ``"80 ms"`` or seconds)."""

    can_log: Path | None = None
    imu_log: Path | None = None
    imu_format: str | None = None
    gnss_log: Path | None = None
    gnss_format: str | None = None
    epoch: str | None = None
    gps_week: int | None = None
    can_offset: str | None = None
    can_ids: str = "icd"
    can_channel: int | None = None
    imu_shift: str = "0"
    gnss_latency: str = "0"
    truth: Path | None = None
    truth_format: str = "smartloc"
    truth_time: str = "bench"
    truth_offset: str = "0"
    truth_smoothing: str = "0"
    seed: int = 1
    start_s: float = 0.0
    #: where the options come from, for messages: ``"--"`` (the command line) or ``"scenario.log."``
    key_prefix: str = "--"


def open_field_logs(opts: FieldLogOptions, *, lockstep: bool, faults: FaultSchedule | None,
                    say: Callable[[str], None] | None = None, quiet: bool = False) -> LogReplay:
    """The replay of the logs ``opts`` names; conversion notes and warnings go to ``say``
    (warnings always, notes unless ``quiet``).

    Raises
    ------
    ConfigError
        A log that cannot be read or placed, named with the file and the line or field.
    """
    from bench.exchange.field_logs import convert_field_logs

    def key(name: str) -> str:
        return opts.key_prefix + (name.replace("_", "-") if opts.key_prefix == "--" else name)

    def ns(text: str | None, name: str) -> int | None:
        return None if text is None else round(quantity(text, "time", "s", key=key(name)) * 1e9)

    tell = say or (lambda _text: None)
    given_epoch = parse_epoch(opts.epoch, key=key("epoch")) if opts.epoch else None
    conv = convert_field_logs(opts.imu_log, opts.gnss_log, imu_format=opts.imu_format, gnss_format=opts.gnss_format,
                              epoch_ns=given_epoch, gps_week=opts.gps_week, truth=opts.truth,
                              truth_format=opts.truth_format)
    for what, fmt in (("IMU", conv.imu_format), ("GNSS", conv.gnss_format)):
        if fmt and fmt not in ("icd", "nmea") and not quiet:
            tell(f"the {what} log is read as {fmt} and converted to the line's bytes")
    for w in conv.warnings:
        tell(f"WARNING: {w}")
    logs = FieldLogs(
        can=opts.can_log,
        imu=opts.imu_log,
        gnss=opts.gnss_log,
        epoch_ns=conv.epoch_ns if conv.epoch_ns is not None else given_epoch,
        can_offset_ns=ns(opts.can_offset, "can_offset"),
        can_ids=opts.can_ids,
        can_channel=opts.can_channel,
        imu_shift_ns=ns(opts.imu_shift, "imu_shift") or 0,
        gnss_latency_ns=ns(opts.gnss_latency, "gnss_latency") or 0,
        imu_data=conv.imu_data,
        gnss_data=conv.gnss_data,
        imu_format=conv.imu_format or "icd",
        gnss_format=conv.gnss_format or "nmea",
        epoch_rule=conv.epoch_rule,
        figures=conv.figures,
    )
    truth = None
    if opts.truth is not None:
        truth = TruthTrack(opts.truth, format=opts.truth_format, time=opts.truth_time,
                           offset_ns=ns(opts.truth_offset, "truth_offset") or 0,
                           smoothing=quantity(opts.truth_smoothing, "length", "m", key=key("truth_smoothing")),
                           samples=conv.truth)
        if conv.truth is not None:
            truth.time = "bench"
    replay = LogReplay(logs, lockstep=lockstep, truth=truth, faults=faults, seed=opts.seed,
                       start_ns=round(opts.start_s * 1e9))
    for w in replay.warnings:
        tell(f"WARNING: {w}")
    return replay
