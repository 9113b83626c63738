"""``bench synth SCENARIO -o run.mcap``: truth and sensor streams into one recording.

The output is checked before anything is built: an existing file is not overwritten
without ``--force``, and a file another bench is writing is never touched (exit 2). A
recording that cannot be written part way (a full disk) ends with exit 3, the file
holding what was written.
"""

from __future__ import annotations

import argparse
import sys

from bench.cli.progress import progress_bar

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``synth`` subcommand."""
    p = sub.add_parser(
        "synth",
        help="synthesize truth and sensor streams of a scenario into an MCAP file",
        description="Synthesize the truth trajectory and the sensor streams of a scenario "
        "(motion script or track) and write them to one MCAP recording.",
    )
    p.add_argument("scenario", help="scenario id (e.g. S000) or path to a scenario TOML file")
    p.add_argument("-o", "--output", required=True, help="output MCAP file")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--seed", type=int, default=0, help="run seed (default 0)")
    p.add_argument("--imu-rate", type=float, help="IMU rate in Hz (default: the scenario's, else 200)")
    p.add_argument("--imu-grade", help="IMU grade name in models/imu/ or a TOML path (default: the scenario's)")
    p.add_argument("--truth-rate", type=float, default=100.0, help="rate of the /truth topic, Hz (default 100)")
    p.add_argument("--no-ideal", action="store_true", help="do not write the error-free IMU increments")
    p.add_argument(
        "--faults",
        action="append",
        default=[],
        metavar="FILE",
        help="fault schedule file ([[fault]] tables) added to the scenario's own; may be repeated",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from bench.record.lock import preflight
    from bench.scenario.loader import load_scenario
    from bench.scenario.track import SampledTrajectory
    from bench.sensors.suite import fault_schedule
    from bench.synth import SynthOptions, synthesize

    scenario = load_scenario(args.scenario)
    fault_schedule(scenario.doc, file=str(scenario.path), extra=tuple(args.faults))  # bad input first
    preflight(args.output, force=args.force)  # then the output, before the trajectory is built
    options = SynthOptions(
        seed=args.seed,
        imu_rate_hz=args.imu_rate,
        imu_grade=args.imu_grade,
        truth_rate_hz=args.truth_rate,
        write_ideal=not args.no_ideal,
        fault_files=tuple(args.faults),
    )
    if not args.quiet:
        print(f"bench synth: building the {scenario.id} trajectory ...", file=sys.stderr)
    traj = scenario.trajectory()
    if "track" in scenario.doc and isinstance(traj, SampledTrajectory):
        for line in traj.fit_report.lines():  # how the recorded track was fitted
            print(line)
    with progress_bar(f"synth {scenario.id}", traj.duration_s, enabled=not args.quiet) as bar:
        summary = synthesize(scenario, args.output, options, trajectory=traj, progress=bar, overwrite=args.force)
    print(
        f"{summary.path}: {summary.scenario}, {summary.duration_s:.1f} s, {summary.distance_m / 1000:.3f} km, "
        f"top speed {summary.max_speed:.2f} m/s, in {summary.elapsed_s:.1f} s"
    )
    for topic, n in summary.counts.items():
        print(f"  {topic:<24} {n:>10} samples")
    return 0
