"""``bench campaign CASES... --runs N [--workers K] [--scheduler ADDRESS|local] -o DIR
[--no-report] [--no-pdf]`` and ``bench campaign-report DIR [--no-pdf]``.

Runs every case x variant x seed in parallel (local processes by default, a Dask
LocalCluster on loopback with ``--scheduler local``, or an existing Dask cluster at
ADDRESS), records each run under DIR and aggregates them into ``DIR/campaign.json``
(:mod:`bench.campaign`; docs/campaigns.md). Starting it again runs only what is missing.
At the end it writes the campaign report, ``DIR/campaign_report.html`` and ``.pdf``
(:mod:`bench.report.campaign_report`; its figures drawn by ``--workers`` processes),
also for an incomplete campaign (a report of what is recorded, saying so);
``--no-report`` skips it, ``--no-pdf`` the PDF.

``bench campaign-report DIR [--no-pdf] [--workers K]`` rebuilds the report without running anything: the aggregate
of the run records ``DIR/campaign.json`` names (those recorded since included), as
``bench campaign`` would compute it.

Exit codes of ``bench campaign``: 0 every run PASS or MARGINAL; 1 a run FAILed; 2 a
malformed case or bad usage; 3 a run was ERROR or could not be run (the campaign is then
incomplete). A report that cannot be written is said on stderr and changes none of them.
Of ``bench campaign-report``: 0 written; 2 no readable ``DIR/campaign.json``; 3 the report
could not be written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bench.cli.app import EXIT_ERROR, EXIT_FAIL, EXIT_OK, EXIT_USAGE
from bench.textsafe import for_terminal

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``campaign`` subcommand."""
    p = sub.add_parser(
        "campaign",
        help="seeded Monte Carlo campaign of test cases, in parallel, resumable",
        description="Run every case x variant x seed in parallel, record each run under DIR and aggregate "
        "pass rates and percentiles into DIR/campaign.json; a second start runs only what is missing.",
    )
    p.add_argument("paths", nargs="+", help="case files or folders")
    p.add_argument("-o", "--out", required=True, help="campaign folder (records, recordings, campaign.json)")
    p.add_argument("--runs", type=int, help="Monte Carlo runs per case and variant (seeds from the case's first)")
    p.add_argument("--seed", type=int, action="append", help="run only this seed (repeatable)")
    p.add_argument("--clock", choices=("lockstep", "realtime"), help="override the cases' clock mode")
    p.add_argument("--workers", type=int, default=1, help="parallel worker processes (default 1)")
    p.add_argument("--scheduler", help="'local' for a Dask LocalCluster on 127.0.0.1, or a Dask scheduler address")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    p.add_argument("--no-report", action="store_true", help="do not write DIR/campaign_report.html and .pdf")
    p.add_argument("--no-pdf", action="store_true", help="write the report's HTML only")
    p.set_defaults(handler=_run)
    r = sub.add_parser(
        "campaign-report",
        help="rebuild a campaign's report from its folder, running nothing",
        description="Write DIR/campaign_report.html and .pdf from DIR/campaign.json and the run records it names.",
    )
    r.add_argument("out", metavar="DIR", help="campaign folder (with campaign.json)")
    r.add_argument("--no-pdf", action="store_true", help="write the report's HTML only")
    r.add_argument("--workers", type=int, default=1, help="processes drawing figures and laying out the PDF")
    r.set_defaults(handler=_report_only)


def _progress(quiet: bool):
    def show(state) -> None:
        if quiet:
            return
        last = state.last
        if last is not None:
            label = f"{last['case_id']}{'[' + last['variant'] + ']' if last.get('variant') else ''} seed {last['seed']}"
            print(for_terminal(f"  {label}: {last.get('verdict')}"), file=sys.stderr)
            state.last = None
        eta = state.eta_s
        eta_text = f", ETA {eta:.0f} s" if eta is not None else ""
        lost = f", {len(state.lost)} lost" if state.lost else ""
        print(f"campaign: {state.done}/{state.total} runs done, {state.failing} failing{lost}{eta_text}",
              file=sys.stderr)

    return show


def _run(args: argparse.Namespace) -> int:
    from bench.campaign.campaign import CampaignOptions, run_campaign

    if (args.runs is not None and args.runs < 1) or args.workers < 1:
        print("bench campaign: --runs and --workers must be at least 1", file=sys.stderr)
        return EXIT_USAGE
    options = CampaignOptions(list(args.paths), Path(args.out), args.runs, tuple(args.seed) if args.seed else None,
                              args.clock, args.workers, args.scheduler)
    result = run_campaign(options, _progress(args.quiet))
    agg = result["aggregate"]
    for label, case in agg["cases"].items():
        lo, hi = case["pass_rate_interval"]
        print(f"{label}: {case['runs']} run(s), pass rate {case['pass_rate']:.3f} [{lo:.3f}, {hi:.3f}]")
    inv = result["invocation"]
    print(f"{agg['runs']}/{result['campaign']['planned']} run(s) recorded ({inv['executed']} run now, "
          f"{inv['reused']} reused); {Path(args.out) / 'campaign.json'}")
    for note in inv["lost"]:
        print(for_terminal(f"bench campaign: not run: {note}"), file=sys.stderr)
    if not args.no_report:
        _write_report(result, Path(args.out), pdf=not args.no_pdf, workers=args.workers)
    verdicts = {v for c in agg["cases"].values() for v in c["verdicts"]}
    if not result["campaign"]["complete"] or "ERROR" in verdicts:
        return EXIT_ERROR
    return EXIT_FAIL if "FAIL" in verdicts else EXIT_OK


def _write_report(campaign: dict, out: Path, *, pdf: bool, workers: int) -> bool:
    """Write the campaign report and print its paths; False (said on stderr) when it fails."""
    from bench.crashlog import one_line
    from bench.report.campaign_report import build_campaign_report

    try:
        files = build_campaign_report(campaign, out, pdf=pdf, workers=workers)
    except Exception as exc:  # a report never hides the campaign's outcome
        print(for_terminal(f"bench campaign: the report could not be written: {type(exc).__name__}: "
                           f"{one_line(exc)}"), file=sys.stderr)
        return False
    print(f"report: {files.html}" + (f", {files.pdf}" if files.pdf else ""))
    return True


def reaggregated(campaign: dict, out: Path) -> dict:
    """``campaign`` with its aggregate computed again from the records on disk of the runs it
    names (recorded or missing), its ``missing`` and ``complete`` updated."""
    from bench.campaign.aggregate import aggregate
    from bench.campaign.work import load_record

    camp = dict(campaign.get("campaign") or {})
    keys = list((campaign.get("aggregate") or {}).get("keys") or []) + list(camp.get("missing") or [])
    records, missing = [], []
    for key in dict.fromkeys(keys):
        rec = load_record(out, key)
        if rec is None:
            missing.append(key)
        else:
            records.append(rec)
    camp.update(missing=missing, complete=not missing)
    return {**campaign, "campaign": camp, "aggregate": aggregate(records)}


def _report_only(args: argparse.Namespace) -> int:
    import json

    out = Path(args.out)
    try:
        campaign = json.loads((out / "campaign.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        print(for_terminal(f"bench campaign-report: cannot read {out / 'campaign.json'}: {exc}"), file=sys.stderr)
        return EXIT_USAGE
    if args.workers < 1:
        print("bench campaign-report: --workers must be at least 1", file=sys.stderr)
        return EXIT_USAGE
    ok = _write_report(reaggregated(campaign, out), out, pdf=not args.no_pdf, workers=args.workers)
    return EXIT_OK if ok else EXIT_ERROR
