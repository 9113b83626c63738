"""``bench replay RECORDING``: re-emit a recorded run's traffic into a DUT.

The DUT comes from a test case (``--case``: its DUT, links and clock) or from the
options. Without ``--faults`` the recorded frames go out frame for frame; with a fault
file the recorded samples are re-encoded with those wire faults instead. ``--start``
seeks. The new recording carries the original truth, so it is judged like the original
(``bench score``).
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
    p.add_argument("recording", help="MCAP recording of an earlier run")
    p.add_argument("-o", "--out", required=True, help="recording of the replay")
    p.add_argument("--case", help="test case whose DUT, links and clock to use")
    p.add_argument("--estimator", help="in-process estimator name (instead of --case)")
    p.add_argument("--dut-command", help="external DUT command line with ICD placeholders (instead of --case)")
    p.add_argument("--dut-config", help="JSON or TOML file of the DUT configuration")
    p.add_argument("--faults", help="fault file ([[fault]] tables, wire layer): re-encode with these faults")
    p.add_argument("--clock", choices=("lockstep", "realtime"), default=None, help="clock mode (default lockstep)")
    p.add_argument("--speed", type=float, default=1.0, help="real-time speed factor")
    p.add_argument("--start", type=float, default=0.0, help="seek: start at this bench time, s")
    p.add_argument("--step", type=float, default=10.0, help="scheduler step, ms (default 10)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(handler=_run)


def _dut_config(path: str | None) -> dict:
    import json
    import tomllib

    if path is None:
        return {}
    text = Path(path).read_text()
    return json.loads(text) if path.endswith(".json") else tomllib.loads(text)


def _run(args: argparse.Namespace) -> int:
    from bench.cli.progress import progress_bar
    from bench.errors import ConfigError
    from bench.faults.schedule import FaultSchedule
    from bench.run.engine import execute
    from bench.run.replay import RecordingReplay
    from bench.run.spec import ClockSpec, DutSpec, LinkSpec
    from bench.sensors.suite import fault_schedule

    links = LinkSpec()
    clock = ClockSpec(mode=args.clock or "lockstep", step_ns=round(args.step * 1e6), speed=args.speed)
    if args.case:
        from bench.acceptance.case import load_case
        from bench.run.case_runner import _links

        case = load_case(args.case)
        if case.dut.kind not in ("in_process", "external"):
            raise ConfigError(f"a replay needs an in_process or external DUT, the case has {case.dut.kind!r}",
                              file=case.file, key="dut.kind")
        dut = DutSpec(kind=case.dut.kind, name=case.dut.name, command=case.dut.command, config=dict(case.dut.config),
                      startup_timeout_s=case.dut.startup_timeout_s, shutdown_timeout_s=case.dut.shutdown_timeout_s)
        links = _links({k: dict(v) for k, v in case.dut.links.items()})
        clock = ClockSpec(mode=args.clock or case.clock.mode, step_ns=case.clock.step_ns,
                          timeout_s=case.clock.timeout_ns / 1e9, speed=args.speed)
    elif args.estimator:
        dut = DutSpec(kind="in_process", name=args.estimator, config=_dut_config(args.dut_config))
    elif args.dut_command:
        dut = DutSpec(kind="external", command=args.dut_command, config=_dut_config(args.dut_config))
    else:
        raise ConfigError("give the DUT: --case, --estimator or --dut-command", key="--case")
    faults: FaultSchedule | None = None
    if args.faults:
        faults = fault_schedule({}, extra=[args.faults])
    provider = RecordingReplay(args.recording, lockstep=clock.lockstep, faults=faults,
                               start_ns=round(args.start * 1e9))
    with progress_bar("replay", (provider.duration_ns - provider.start_ns) * 1e-9, enabled=not args.quiet) as bar:
        result = execute(provider, dut, links, clock, Path(args.out), progress=bar)
    print(f"{result.path}: {result.status}" + (f" ({result.reason})" if result.reason else "")
          + f", {result.bench_s:.1f} s of bench time in {result.elapsed_s:.1f} s")
    if result.timing is not None:
        print(f"  timing: {result.timing.text()}", file=sys.stderr)
    return 0 if result.ok else 3
