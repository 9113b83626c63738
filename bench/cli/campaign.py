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
and the case verdicts of the run records ``DIR/campaign.json`` plans (those recorded since included), as
``bench campaign`` would compute them.

Each case (at each sweep point) is judged over all its runs as ``bench accept`` judges it
(:mod:`bench.campaign.verdicts`: Monte Carlo modes, comparisons, negative controls).
A campaign holds DIR while it runs (``DIR/campaign.lock``, :mod:`bench.campaign.lock`):
a second ``bench campaign`` on DIR is refused at once, naming the holder's host, pid and
start; a lock left by a killed campaign is taken over, said on stderr.
``bench campaign-report`` of a DIR a campaign holds writes the report of what is recorded
and says that the campaign is still running (on stderr and in the report).

Exit codes of ``bench campaign``: 0 every case PASS or MARGINAL; 1 a case FAILed; 2 a
malformed case, bad usage, or DIR held by another campaign; 3 a case was ERROR: a run
ERROR, or not run (the campaign is then incomplete). A report that cannot be written is
said on stderr and changes none of them. Of ``bench campaign-report``: 0 written; 2 no
readable ``DIR/campaign.json``, or it or a run record it names is malformed (a number that
is not finite, not JSON, larger than 256 MiB, nested deeper than 64 levels: the file and
the field named); 3 the report could not be written. ``bench campaign`` runs again a run
whose record is malformed, and says so.
"""

from __future__ import annotations

import argparse
import shlex
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
    p.add_argument("--retry-errors", action="store_true", help="run again the runs recorded ERROR")
    p.add_argument("--prune", action="store_true",
                   help="delete the records and recordings of runs the campaign no longer has")
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
    from bench.campaign.sweep import point_label

    def show(state) -> None:
        if quiet:
            return
        last = state.last
        if last is not None:
            point = point_label(tuple(tuple(kv) for kv in last.get("sweep") or ()))
            variant = f"[{last['variant']}]" if last.get("variant") else ""
            label = f"{last['case_id']}{variant}{point} seed {last['seed']}"
            print(for_terminal(f"  {label}: {last.get('verdict')}"), file=sys.stderr)
            state.last = None
        eta = state.eta_s
        eta_text = f", ETA {eta:.0f} s" if eta is not None else ""
        lost = f", {len(state.lost)} lost" if state.lost else ""
        print(f"campaign: {state.done}/{state.total} runs done, {state.failing} failing{lost}{eta_text}",
              file=sys.stderr)

    return show


def _notice(message: str) -> None:
    print(for_terminal(message), file=sys.stderr, flush=True)


def _run(args: argparse.Namespace) -> int:
    from bench.campaign.campaign import CampaignOptions, run_campaign
    from bench.campaign.lock import CampaignHeldError

    if (args.runs is not None and args.runs < 1) or args.workers < 1:
        print("bench campaign: --runs and --workers must be at least 1", file=sys.stderr)
        return EXIT_USAGE
    options = CampaignOptions(list(args.paths), Path(args.out), args.runs, tuple(args.seed) if args.seed else None,
                              args.clock, args.workers, args.scheduler, retry_errors=args.retry_errors,
                              prune=args.prune)
    try:
        result = run_campaign(options, _progress(args.quiet), _notice, command=shlex.join(["bench", *sys.argv[1:]]))
    except CampaignHeldError as exc:
        _notice(f"bench campaign: {exc}")
        return EXIT_USAGE
    agg = result["aggregate"]
    for label, case in agg["cases"].items():
        lo, hi = case["pass_rate_interval"]
        print(f"{label}: {case['runs']} run(s), pass rate {case['pass_rate']:.3f} [{lo:.3f}, {hi:.3f}]")
    inv = result["invocation"]
    print(f"{agg['runs']}/{result['campaign']['planned']} run(s) recorded ({inv['executed']} run now, "
          f"{inv['reused']} reused); {Path(args.out) / 'campaign.json'}")
    for note in inv.get("malformed", []):
        print(for_terminal(f"bench campaign: a run record cannot be used, its run runs again: {note}"),
              file=sys.stderr)
    for note in inv["lost"]:
        print(for_terminal(f"bench campaign: not run: {note}"), file=sys.stderr)
    if stale := result["campaign"]["stale"]:
        print(f"bench campaign: {len(stale)} record(s) under {Path(args.out) / 'runs'} belong to no run of this "
              "campaign (--prune deletes them)", file=sys.stderr)
    judged = result["verdicts"]
    for label, case in judged.items():
        print(for_terminal(f"{label}: {case['verdict']} over {case['runs']} run(s)"
                           + "".join(f"; {e}" for e in case["errors"])))
    if not args.no_report:
        _write_report(result, Path(args.out), pdf=not args.no_pdf, workers=args.workers)
    verdicts = {case["verdict"] for case in judged.values()}
    if not result["campaign"]["complete"] or "ERROR" in verdicts or not judged:
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
    names (recorded or missing), its ``missing`` and ``complete`` updated. A malformed record
    (a number that is not finite...) is a ConfigError naming it: never judged as if fine."""
    from bench.campaign.aggregate import aggregate
    from bench.campaign.work import load_record

    camp = dict(campaign.get("campaign") or {})
    keys = list((campaign.get("aggregate") or {}).get("keys") or []) + list(camp.get("missing") or [])
    records, missing = [], []
    for key in dict.fromkeys(keys):
        rec = load_record(out, key, strict=True)
        if rec is None:
            missing.append(key)
        else:
            records.append(rec)
    camp.update(missing=missing, complete=not missing)
    return {**campaign, "campaign": camp, "aggregate": aggregate(records),
            "verdicts": _rejudged(campaign, camp, {r["key"]: r for r in records}, set(keys))}


def _rejudged(campaign: dict, camp: dict, records: dict, keys: set[str]) -> dict:
    """The case verdicts judged again from the records, when the campaign's cases still plan
    exactly the runs ``campaign.json`` names; else its verdicts as written, each noting it."""
    from bench.campaign.plan import plan_campaign
    from bench.campaign.verdicts import judge_groups

    opts = camp.get("options") or {}
    try:
        plan = plan_campaign(camp.get("paths") or [], opts.get("runs"),
                             tuple(opts["seeds"]) if opts.get("seeds") else None, opts.get("clock"))
    except Exception:  # the case files moved or no longer load
        plan = None
    if plan is not None and {r.key for r in plan} == keys:
        return judge_groups(plan, records)
    why = "verdicts as of the campaign's last invocation: its case files now plan other runs"
    old = campaign.get("verdicts") or {}
    return {label: {**v, "errors": [*v.get("errors", []), why]} for label, v in old.items()}


def _running(out: Path) -> dict | None:
    """Say on stderr whether a campaign holds ``out`` (or may: a lock left that names a
    host whose locks this one cannot see); the holder when one does."""
    from bench.campaign.lock import describe, lock_state, this_kernel

    state, who = lock_state(out)
    if state == "held":
        _notice(f"bench campaign-report: a campaign is still running in {out} ({describe(who)}): "
                "this report is of the runs recorded so far")
        return who or {"pid": "?", "host": "?", "started_utc": "?"}
    if state == "stale" and who is not None:
        if who.get("host") == this_kernel()["host"]:
            _notice(f"bench campaign-report: the last campaign in {out} ended without finishing ({describe(who)}): "
                    "killed, or its machine lost; start it again to complete it")
        else:
            _notice(f"bench campaign-report: a campaign on {who.get('host')} may still be running in {out} "
                    f"({describe(who)}; its lock cannot be checked from this host)")
    return None


def _report_only(args: argparse.Namespace) -> int:
    from bench.campaign.campaign import read_campaign
    from bench.errors import ConfigError

    out = Path(args.out)
    if args.workers < 1:
        print("bench campaign-report: --workers must be at least 1", file=sys.stderr)
        return EXIT_USAGE
    running = _running(out)
    try:  # campaign.json and the run records it names, each read bounded and checked
        campaign = reaggregated(read_campaign(out), out)
    except ConfigError as exc:
        later = "; the campaign running there writes it when it ends" if running is not None else ""
        print(for_terminal(f"bench campaign-report: {exc}{later}"), file=sys.stderr)
        return EXIT_USAGE
    if running is not None:
        campaign = {**campaign, "running": running}
    ok = _write_report(campaign, out, pdf=not args.no_pdf, workers=args.workers)
    return EXIT_OK if ok else EXIT_ERROR
