"""``bench report RESULTS.json|RECORDINGS... -o DIR``: the certification report.

* From recordings (``.mcap`` files or folders holding them): each is re-judged against the
  test case attached to it (as ``bench score`` does), then the results record
  (``results.json``) and the report (``report.html``, ``report.pdf``) are written to DIR.
  Nothing but the recordings is read.
* From a results record (``results.json`` or the folder of a ``bench accept`` run): the
  record as it is, its figures drawn from the recordings beside it
  (``recordings/<case>/<file>``); with ``--rescore`` those recordings are re-judged first,
  exactly as from recordings. Without it, a recording found beside the record that is now
  unfinished or damaged makes its run, its case and the report ERROR with the damage named
  (:mod:`bench.report.evidence`), never the record's last verdict silently.

Exit codes as every command's: the report's verdict, 0 PASS (or MARGINAL), 1 FAIL, 3
ERROR; 2 usage (a missing or malformed input, named); 3 also when the report could not be
written. The report is written whatever the verdict.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path
from typing import Any

__all__ = ["register", "load_results", "report_from_recordings"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``report`` subcommand."""
    p = sub.add_parser(
        "report",
        help="write the certification report (HTML and PDF) of a run or suite",
        description="Build report.html and report.pdf from a results record or from recordings alone "
        "(re-judged against their attached test cases).",
    )
    p.add_argument("inputs", nargs="+", help="results.json (or a bench accept output folder), or MCAP recordings "
                   "and folders of them")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--rescore", action="store_true", help="re-judge the recordings a results record names")
    p.add_argument("--no-pdf", action="store_true", help="write the HTML page only")
    p.add_argument("--no-figures", action="store_true", help="no figures (no recording is read for them)")
    p.add_argument("--title", default="Acceptance report", help="the report's title")
    p.add_argument("--all-variants", action="store_true",
                   help="figures of every variant's worst run (default: of the case's worst run only)")
    p.add_argument("--workers", type=int, help="processes drawing figures (default: the CPU count)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    p.set_defaults(handler=_run)


def load_results(path: Path) -> dict[str, Any]:
    """A results record from ``path`` (a file, or a folder holding ``results.json``): read
    bounded and checked (:func:`bench.config.files.read_json`: every number finite, an
    infinite measurement the string ``"inf"``), then against its schema."""
    from bench.config.files import read_json
    from bench.errors import ConfigError

    file = path / "results.json" if path.is_dir() else path
    obj = read_json(file, what="results record")
    if not isinstance(obj, dict) or not isinstance(obj.get("cases"), list):
        raise ConfigError(f"{file}: not a results record (no 'cases' list)")
    if "schema_version" in obj:  # a record of the published schema (older ones predate it)
        from bench.report.results import schema_errors

        errors = schema_errors(obj)
        if errors:
            raise ConfigError(f"{file}: not a valid results record: " + "; ".join(errors))
    return obj


def _recordings(inputs: list[Path]) -> list[Path]:
    from bench.errors import ConfigError

    out: list[Path] = []
    for p in inputs:
        if p.is_dir():
            found = sorted(p.rglob("*.mcap"))
            if not found:
                raise ConfigError(f"{p}: no results.json and no .mcap recordings in it")
            out += found
        elif p.suffix == ".mcap" and p.is_file():
            out.append(p)
        else:
            raise ConfigError(f"{p}: not a recording (.mcap), a results.json or a folder of them")
    return out


def report_from_recordings(recordings: list[Path]) -> dict[str, Any]:
    """The results record of ``recordings`` re-judged (as ``bench score`` does)."""
    from bench.cli.score import score_files
    from bench.report.results import results_json

    return results_json(score_files(list(recordings)), {"paths": [str(p) for p in recordings]})


def _is_record(p: Path) -> bool:
    return (p.is_dir() and (p / "results.json").is_file()) or (p.is_file() and p.suffix == ".json")


def _run(args: argparse.Namespace) -> int:
    from bench.cli.app import EXIT_ERROR, EXIT_FAIL, EXIT_OK
    from bench.cli.progress import progress_bar
    from bench.errors import ConfigError
    from bench.report.build import build_report, commands_for, folder_locator
    from bench.report.results import write_json

    inputs = [Path(x) for x in args.inputs]
    out = Path(args.out)
    records = [p for p in inputs if _is_record(p)]
    if records and len(inputs) > 1:
        raise ConfigError("give one results record, or recordings only (not both)")
    if records:
        base = records[0] if records[0].is_dir() else records[0].parent
        results = load_results(records[0])
        locate = folder_locator(base)
        if args.rescore:
            names = [(c["id"], r["recording"]) for c in results["cases"] for r in c.get("runs", [])
                     if r.get("recording")]
            paths = [locate(cid, n) for cid, n in names]
            missing = [n for (_, n), p in zip(names, paths, strict=True) if p is None]
            if missing:
                raise ConfigError(f"{records[0]}: recordings not found beside it: {', '.join(missing[:5])}")
            results = report_from_recordings([p for p in paths if p is not None])
        else:  # the record's verdicts, unless a recording behind one is now damaged or unfinished
            from bench.report.evidence import distrust_damaged

            results, distrusted = distrust_damaged(results, locate)
            for line in distrusted:
                print(f"bench report: ERROR: {line}", file=sys.stderr)
    else:
        recs = _recordings(inputs)
        by_name = {p.name: p for p in recs}
        results = report_from_recordings(recs)

        def locate(case_id: str, name: str) -> Path | None:
            return by_name.get(name)  # recording names are unique across cases (case id in the name)

    out.mkdir(parents=True, exist_ok=True)
    if not records or args.rescore:
        write_json(results, out / "results.json")
    command, rescore = commands_for(results, out=base if records else None)
    argv = "bench report " + " ".join(shlex.quote(a) for a in args.inputs)
    def stage(text: str) -> None:
        if not args.quiet:
            print(f"report: {text}", file=sys.stderr, flush=True)

    with progress_bar("report: figures", 1, unit="recordings", enabled=not (args.quiet or args.no_figures)) as bar:
        files = build_report(
            results, out, locate=locate, pdf=not args.no_pdf, figures=not args.no_figures, workers=args.workers,
            per_variant=args.all_variants,
            command=command, rescore_command=rescore if records else argv, title=args.title, progress=bar,
            stage=stage,
        )
    for note in files.figure_notes:
        print(f"bench report: {note}", file=sys.stderr)
    written = ", ".join(str(p) for p in (files.html, files.pdf) if p is not None)
    print(f"report ({results.get('verdict', '?')}): {written}")
    return {"PASS": EXIT_OK, "MARGINAL": EXIT_OK, "FAIL": EXIT_FAIL}.get(str(results.get("verdict")), EXIT_ERROR)
