"""``bench views RECORDING -o OUT``: a copy of a recording with its Foxglove views.

Recordings made before the protobuf views (or whose views should be made again, at another
display rate) get them here: every record of the recording is copied as it was (the
columnar topics, JSON events, metadata, attachments and the ``run_end`` record), its old
views (``/foxglove/...`` and the JSON ``foxglove.LocationFix``/``PoseInFrame`` topics of
older recordings) are left out, and fresh views are derived from the copy's sources
(``docs/recording.md``, "Foxglove views"). The copy scores exactly as the original. An
unfinished or damaged recording (a killed run has no views: they are written at its end)
is copied as far as it can be read, and the copy carries the source's state
(:mod:`bench.record.provenance`): it scores ERROR, and the command exits 3 naming the
damage, unless ``--accept-damaged-source`` (exit 0; the copy is judged, its results say
so). An existing output is refused without ``--force``.
"""

from __future__ import annotations

import argparse

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``views`` subcommand."""
    p = sub.add_parser("views", help="write a copy of a recording with its Foxglove views",
                       description="Copy a recording record for record and add the Foxglove views "
                       "(map, poses, transforms, log, plots at the display rate, events) derived from it.")
    p.add_argument("recording", help="MCAP recording of a run")
    p.add_argument("-o", "--output", required=True, help="output MCAP file")
    p.add_argument("--rate", type=float, default=10.0, help="display rate of the plot and map topics, Hz "
                   "(10..50, default 10)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--accept-damaged-source", action="store_true",
                   help="a copy of an unfinished or damaged recording is judged anyway (recorded in the copy and its "
                   "results); without it the copy is judged ERROR and the command exits 3")
    p.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from bench.cli.exchange import say_source
    from bench.record.lock import preflight
    from bench.scoring.views import check_rate
    from bench.scoring.viewwrite import copy_with_views
    from bench.textsafe import for_terminal

    check_rate(args.rate)
    preflight(args.output, force=args.force)
    n, source = copy_with_views(args.recording, args.output, rate_hz=args.rate, overwrite=args.force,
                                accept_damaged_source=args.accept_damaged_source)
    print(for_terminal(f"{args.output}: {n} view messages"))
    return say_source("bench views", args.output, source)
