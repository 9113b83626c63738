"""Time to build the certification report of a suite, and its size.

Builds report.html and report.pdf from a ``bench accept`` output folder (the reference
suite: ``make demo`` writes it to ``reports/``) into a temporary folder, as ``bench
accept`` does at its end, and prints the seconds of each stage (figures, the HTML page,
the PDF), the total, the sizes and the page count. The issue's targets: under 30 s in
all, the PDF under 10 MB.

Run: ``.venv/bin/python benchmarks/report_build.py [REPORTS_DIR] [--workers N]``
(default ``reports/``; workers: the CPU count).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import pypdf

from bench.report.build import build_report, commands_for, folder_locator


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("reports", nargs="?", default="reports")
    ap.add_argument("--workers", type=int)
    ap.add_argument("--all-variants", action="store_true", help="figures of every variant (as bench report)")
    args = ap.parse_args()
    root = Path(args.reports)
    results = json.loads((root / "results.json").read_text())
    n_runs = sum(len(c["runs"]) for c in results["cases"])
    marks: list[tuple[str, float]] = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        command, rescore = commands_for(results)
        files = build_report(results, tmp, locate=folder_locator(root), workers=args.workers,
                             per_variant=args.all_variants, command=command,
                             rescore_command=rescore, stage=lambda s: marks.append((s, time.perf_counter())))
        total = time.perf_counter() - t0
        html_s = files.html.stat().st_size
        pdf_s = files.pdf.stat().st_size if files.pdf else 0
        pages = len(pypdf.PdfReader(files.pdf).pages) if files.pdf else 0
    t_fig = next((t for s, t in marks if s.startswith("drew")), t0)
    t_html = next(t for s, t in marks if s.startswith("wrote"))
    which = "one run per case" + (" and variant" if args.all_variants else "")
    print(f"suite {root}: {len(results['cases'])} cases, {n_runs} runs; figures of {which}")
    for note in files.figure_notes:
        print(f"  note: {note}")
    print(f"figures             : {t_fig - t0:6.1f} s   ({next((s for s, _ in marks if s.startswith('drew')), '')})")
    print(f"HTML page           : {t_html - t_fig:6.1f} s")
    print(f"PDF                 : {t0 + total - t_html:6.1f} s")
    print(f"total               : {total:6.1f} s   (target < 30 s)")
    print(f"report.html {html_s / 1e6:.2f} MB, report.pdf {pdf_s / 1e6:.2f} MB (target < 10 MB), {pages} pages")


if __name__ == "__main__":
    main()
