"""``bench replay RECORDING``: re-emit a recorded run's traffic into a DUT.

The DUT comes from a test case (``--case``: its DUT, links and clock) or from the
options. Without ``--faults`` the recorded frames go out frame for frame; with a fault
file the recorded samples are re-encoded with those wire faults instead. ``--start S``
seeks: the replay is a run of its own whose bench time starts at 0 at bench time S of the
recording. The new recording carries the original truth, so it is judged like the
original (``bench score``); a replay of an unfinished or damaged recording is ERROR
unless ``--accept-damaged-source``. Instead of a recording, field logs of a drive (``--can-log`` ASC/BLF,
``--imu-log``, ``--gnss-log``; ``--truth`` to score it) are re-emitted the same way, with
``--faults`` adding wire faults (docs/run_engine.md, "Replaying field logs"); IMU and GNSS
logs in other formats (PSINS, KF-GINS, gnss-ins-sim, a TOML-declared log) are converted to
the lines' streams first (docs/exchange.md, "Field logs in other formats").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``replay`` subcommand."""
    p = sub.add_parser("replay", help="re-emit a recording's traffic into a DUT (lockstep, 1x or scaled)",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("recording", nargs="?", help="MCAP recording of an earlier run (or give field logs)")
    p.add_argument("-o", "--out", required=True, help="recording of the replay")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--accept-damaged-source", action="store_true",
                   help="judge the replay of an unfinished, damaged or ended-early recording anyway (recorded in "
                   "the replay's metadata and its results); without it such a replay is ERROR")
    p.add_argument("--case", help="test case whose DUT, links and clock to use")
    p.add_argument("--estimator", help="in-process estimator name (instead of --case)")
    p.add_argument("--dut-command", help="external DUT command line with ICD placeholders (instead of --case); its "
                   "CAN is udp_multicast on the loopback ({can_interface}, {can_channel}, {can_port})")
    p.add_argument("--dut-config", help="JSON or TOML file of the DUT configuration")
    p.add_argument("--faults", help="fault file ([[fault]] tables, wire layer): re-encode with these faults")
    p.add_argument("--clock", choices=("lockstep", "realtime"), default=None, help="clock mode (default lockstep)")
    p.add_argument("--speed", type=float, default=1.0, help="real-time speed factor")
    p.add_argument("--start", type=float, default=0.0,
                   help="seek: replay from this bench time of the recording, s (a whole number of steps); the "
                   "replay's bench time starts at 0 there (field logs: the DUT's first BENCH_TIME is this time)")
    p.add_argument("--step", type=float, default=10.0, help="scheduler step, ms (default 10)")
    p.add_argument("--imu-rate", help="the rate the IMU stream was recorded at ('100 Hz'): the replay is refused "
                   "when the stream runs at another (docs/run_engine.md, 'The IMU rate of a replay')")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _field_log_options(p)
    p.set_defaults(handler=_run)


def _field_log_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("field logs (instead of a recording; times as '80 ms' or seconds)")
    g.add_argument("--can-log", help="python-can log of the vehicle bus (.asc, .blf)")
    g.add_argument("--imu-log", help="IMU log: the imu line's bytes (ICD 3 frames), a PSINS .imu, a KF-GINS imu.txt, "
                   "gnss-ins-sim output, or a text/CSV log declared by a TOML beside it (docs/exchange.md)")
    g.add_argument("--imu-format", choices=("icd", "psins", "kfgins", "gnss-ins-sim", "declared"),
                   help="format of --imu-log (default: recognised by its content)")
    g.add_argument("--gnss-log", help="GNSS log: the gnss line's bytes (NMEA) or a KF-GINS gnss.pos")
    g.add_argument("--gnss-format", choices=("nmea", "kfgins"),
                   help="format of --gnss-log (default: recognised by its content)")
    g.add_argument("--epoch", help="UTC of bench time zero, ISO 8601 (when the logs do not carry it)")
    g.add_argument("--gps-week", type=int,
                   help="GPS week of logs stamped in GPS seconds of week (KF-GINS); default: a truth.nav's week")
    g.add_argument("--can-offset", help="bench time of the CAN log's first frame (logs without BENCH_TIME; default 0)")
    g.add_argument("--can-ids", choices=("icd", "all"), default="icd",
                   help="re-emit the ICD's bench-to-DUT messages only (default) or every classic frame")
    g.add_argument("--can-channel", type=int, help="use this channel of the log only (1, 2, ...)")
    g.add_argument("--imu-shift", default="0", help="added to the IMU frames' times of validity (re-stamped)")
    g.add_argument("--gnss-latency", default="0", help="NMEA epoch's UTC time to its sentences on the line")
    g.add_argument("--truth", help="ground-truth track of the drive, written as /truth so the replay can be scored")
    g.add_argument("--truth-format", choices=("smartloc", "csv", "kfgins"), default="smartloc",
                   help="truth file format (kfgins: a KF-GINS/OB_GINS .nav, e.g. truth.nav, in GPS week and sow)")
    g.add_argument("--truth-time", choices=("bench", "utc"), default="bench",
                   help="the truth's time column is bench time (default) or UTC seconds since 1970")
    g.add_argument("--truth-offset", default="0", help="added to the truth's times")
    g.add_argument("--truth-smoothing", default="0", help="1-sigma position noise of the truth track, m")
    g.add_argument("--seed", type=int, default=1, help="seed of the wire faults (field logs)")


def _dut_config(path: str | None) -> dict:
    from bench.config.files import read_json, read_toml
    from bench.errors import ConfigError

    if path is None:
        return {}
    what = "DUT configuration file"  # bounded, nested <= 64 levels, every number finite; or ConfigError
    doc = read_json(path, what=what) if path.endswith(".json") else read_toml(path, what=what)
    if not isinstance(doc, dict):
        raise ConfigError(f"expected a table, found {type(doc).__name__}", file=path, key="--dut-config")
    return doc


def _run(args: argparse.Namespace) -> int:
    import math

    from bench.cli.progress import progress_bar
    from bench.errors import ConfigError
    from bench.faults.schedule import FaultSchedule
    from bench.record.lock import preflight
    from bench.run.engine import execute
    from bench.run.imu_rate import check_replay
    from bench.run.replay import RecordingReplay
    from bench.run.spec import ClockSpec, DutSpec, LinkSpec
    from bench.scoring.integrity import DUT_STATUSES
    from bench.sensors.suite import fault_schedule
    from bench.textsafe import for_terminal

    for name in ("speed", "step"):
        value = getattr(args, name)
        if not math.isfinite(value) or value <= 0 or value > 1e6:
            raise ConfigError(f"expected a positive number, found {value:g}", key=f"--{name}")
    links = LinkSpec()
    case = None
    clock = ClockSpec(mode=args.clock or "lockstep", step_ns=round(args.step * 1e6), speed=args.speed)
    attachments = None
    logs = args.can_log or args.imu_log or args.gnss_log
    if args.case:
        from bench.acceptance.case import load_case
        from bench.run.case_runner import _links

        case = load_case(args.case, check_files=not logs)  # a field-log replay uses no scenario file
        if case.dut.kind not in ("in_process", "external", "hardware"):
            raise ConfigError(f"a replay needs an in_process, external or hardware DUT, the case has "
                              f"{case.dut.kind!r}",
                              file=case.file, key="dut.kind")
        dut = DutSpec(kind=case.dut.kind, name=case.dut.name, command=case.dut.command, config=dict(case.dut.config),
                      startup_timeout_s=case.dut.startup_timeout_s, shutdown_timeout_s=case.dut.shutdown_timeout_s)
        links = _links({k: dict(v) for k, v in case.dut.links.items()})
        clock = ClockSpec(mode=args.clock or case.clock.mode, step_ns=case.clock.step_ns,
                          timeout_s=case.clock.timeout_ns / 1e9, speed=args.speed)
        # a field-log replay is judged against the case given (a recording's replay carries its own)
        attachments = [(f"case/{case.file_name}", case.text.encode(), "application/toml")]
    elif args.estimator:
        dut = DutSpec(kind="in_process", name=args.estimator, config=_dut_config(args.dut_config))
    elif args.dut_command:
        dut = DutSpec(kind="external", command=args.dut_command, config=_dut_config(args.dut_config))
        # another process: not python-can's virtual bus (the bench's process only) but
        # udp_multicast on this machine's loopback, a free port per run ({can_port})
        links = LinkSpec(can={"interface": "udp_multicast"})
    else:
        raise ConfigError("give the DUT: --case, --estimator or --dut-command", key="--case")
    faults: FaultSchedule | None = None
    if args.faults:
        faults = fault_schedule({}, extra=[args.faults])
    if bool(args.recording) == bool(logs):
        raise ConfigError("give either a recording or field logs (--can-log, --imu-log, --gnss-log)", key="recording")
    if not math.isfinite(args.start) or args.start < 0 or args.start > 1e7:
        raise ConfigError(f"expected a bench time from 0 s on, found {args.start:g}", key="--start")
    start_ns = round(args.start * 1e9)
    if start_ns % clock.step_ns:
        raise ConfigError(f"the start {args.start:g} s must be a whole number of scheduler steps "
                          f"({clock.step_ns / 1e6:g} ms)", key="--start")
    for src in (args.recording, args.can_log, args.imu_log, args.gnss_log, args.truth):
        if src and Path(src).exists() and Path(args.out).exists() and Path(src).samefile(args.out):
            raise ConfigError(f"is the input {src} itself: a replay cannot overwrite what it reads", file=args.out,
                              key="-o")
    if logs:
        if args.accept_damaged_source:
            raise ConfigError("--accept-damaged-source is for recordings; field logs have no such check",
                              key="--accept-damaged-source")
        provider = _log_replay(args, clock.lockstep, faults)
    else:
        provider = RecordingReplay(args.recording, lockstep=clock.lockstep, faults=faults, start_ns=start_ns,
                                   accept_damaged_source=args.accept_damaged_source)
    check_replay(provider, args.imu_rate, case)  # the stream at the declared rate (bench.run.imu_rate)
    preflight(args.out, force=args.force)  # the inputs first, then the output
    if not logs:
        _say_source(provider, args.quiet)
    with progress_bar("replay", (provider.duration_ns - provider.start_ns) * 1e-9, enabled=not args.quiet) as bar:
        result = execute(provider, dut, links, clock, Path(args.out), progress=bar, overwrite=args.force,
                         attachments=attachments if logs else None)
    print(for_terminal(f"{result.path}: {result.status}" + (f" ({result.reason})" if result.reason else "")
                       + f", {result.bench_s:.1f} s of bench time in {result.elapsed_s:.1f} s"))
    if result.timing is not None:
        print(f"  timing: {result.timing.text()}", file=sys.stderr)
    if logs and not args.case and not args.quiet:
        print(f"bench replay: judge it against a test case's criteria: bench score {result.path} --case CASE.toml",
              file=sys.stderr)
    if result.status in DUT_STATUSES:
        return 1  # the DUT failed (docs/scoring.md, "Verdicts")
    if not result.ok:
        return 3
    source = getattr(provider, "provenance", {})
    if source.get("source_complete") == "false" and source.get("accept_damaged_source") != "true":
        print(f"bench replay: ERROR: {result.path} replays a source that cannot be trusted (see above); "
              "bench score judges it ERROR", file=sys.stderr)
        return 3
    return 0


def _say_source(provider, quiet: bool) -> None:
    """Tell what the replay starts from: a seek, and a source that cannot be trusted."""
    import json

    from bench.record.provenance import ACCEPT_FLAG

    if provider.seek_ns and not quiet:
        print(f"bench replay: from bench time {provider.seek_ns / 1e9:g} s of the recording, which is bench time 0 "
              f"of the replay ({provider.duration_ns / 1e9:g} s)", file=sys.stderr)
    problems = json.loads(provider.provenance["source_problems"])
    if problems:
        verdict = ("judged anyway, as asked" if provider.provenance["accept_damaged_source"] == "true"
                   else f"the replay will be judged ERROR (pass {ACCEPT_FLAG} to judge it anyway)")
        print(f"bench replay: the source cannot be trusted: {'; '.join(problems)}; {verdict}", file=sys.stderr)


def _log_replay(args: argparse.Namespace, lockstep: bool, faults):
    from bench.exchange.fieldopen import FieldLogOptions, open_field_logs
    from bench.textsafe import for_terminal

    def path(value: str | None) -> Path | None:
        return Path(value) if value else None

    opts = FieldLogOptions(
        can_log=path(args.can_log), imu_log=path(args.imu_log), imu_format=args.imu_format,
        gnss_log=path(args.gnss_log), gnss_format=args.gnss_format, epoch=args.epoch, gps_week=args.gps_week,
        can_offset=args.can_offset, can_ids=args.can_ids, can_channel=args.can_channel, imu_shift=args.imu_shift,
        gnss_latency=args.gnss_latency, truth=path(args.truth), truth_format=args.truth_format,
        truth_time=args.truth_time, truth_offset=args.truth_offset, truth_smoothing=args.truth_smoothing,
        seed=args.seed, start_s=args.start)
    return open_field_logs(opts, lockstep=lockstep, faults=faults, quiet=args.quiet,
                           say=lambda text: print(for_terminal(f"bench replay: {text}"), file=sys.stderr))
