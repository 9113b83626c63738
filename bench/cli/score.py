"""``bench score RECORDING... [--case CASE]``: judge recordings offline.

Each recording is judged against the test case attached to it (``case/<file>``) or the
one given with ``--case``; recordings of the same case (its variants and Monte Carlo
seeds) are combined into one case verdict, exactly as ``bench accept`` combined them.
The numbers are those of the live run, bit for bit: the live verdict came from the same
functions applied to the same file.

Exit codes as ``bench accept``: 0 pass, 1 FAIL, 2 usage or malformed case, 3 ERROR.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

__all__ = ["register", "score_files"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``score`` subcommand."""
    p = sub.add_parser(
        "score",
        help="judge recordings offline against their test case",
        description="Re-judge one or more recordings from the recordings alone: the test case attached to "
        "each recording (or --case), every criterion, the case verdict.",
    )
    p.add_argument("recordings", nargs="+", help="MCAP recordings of runs")
    p.add_argument("--case", help="judge against this test case file instead of the attached one")
    p.add_argument("--json", help="write the results JSON here")
    p.add_argument("--junit", help="write JUnit XML here")
    p.add_argument("-v", "--verbose", action="store_true", help="print each run's overview figures")
    p.set_defaults(handler=_run)


def score_files(recordings: list[str | Path], case_file: str | Path | None = None):
    """Judge recordings; returns the case results (grouped by case id, in first-seen order)."""
    from bench.acceptance.case import load_case
    from bench.acceptance.judge import judge_case, score_recording

    case = load_case(case_file, check_files=False) if case_file else None
    groups: dict[str, tuple] = {}
    for rec in recordings:
        c, result = score_recording(rec, case)
        if c.id not in groups:
            groups[c.id] = (c, [])
        groups[c.id][1].append(result)
    return [judge_case(c, runs) for c, runs in groups.values()]


def _need_cases(recordings: list[str]) -> None:
    """Refuse (exit 2, saying how to judge it) a recording that carries no test case: a
    replay with ``--estimator`` or ``--dut-command`` has no criteria of its own."""
    from bench.errors import ConfigError
    from bench.record.mcap_io import RecordingReader

    for rec in recordings:
        try:
            with RecordingReader(rec) as r:
                names = list(r.attachments())
                start = r.metadata().get("run_start", {})
        except Exception:  # an unreadable recording: the scoring below names what is wrong with it
            continue
        if any(n.startswith("case/") for n in names):
            continue
        what = ("a replay of field logs" if start.get("replay_mode") == "field logs"
                else "a replay" if start.get("replay_mode") else "a recording")
        raise ConfigError(
            f"{what} without a test case (made with --estimator or --dut-command): there are no criteria to judge it "
            f"by. Give them: bench score {rec} --case CASE.toml (the case's criteria and scoring; its DUT, scenario "
            "and sensors are not used), or replay with --case CASE.toml, which attaches the case", file=rec)


def _run(args: argparse.Namespace) -> int:
    from bench.cli.accept import exit_code
    from bench.report.junit import write_junit
    from bench.report.results import results_json, write_json
    from bench.report.table import text_table
    from bench.textsafe import for_terminal

    if args.case is None:
        _need_cases(args.recordings)
    results = score_files(args.recordings, args.case)
    print(text_table(results))
    if args.verbose:
        for cr in results:
            for r in cr.runs:
                print(for_terminal(f"\n{Path(r.recording).name}: {r.verdict}", keep="\n"))
                for label, block in r.overview.items():
                    if isinstance(block, dict):
                        for k, v in block.items():
                            print(for_terminal(f"  {label:<10} {k:<28} {v}"))
    if args.json:
        command = ["bench", "score", *args.recordings, *(["--case", args.case] if args.case else [])]
        write_json(results_json(results, command=shlex.join(command)), args.json)
    if args.junit:
        write_junit(results, args.junit)
    return exit_code(results)
