"""Report figures: seconds per recording and PNG sizes (``bench.report.figures``).

For each case of a suite's output folder (default ``/work/demo-reports``: its
``results.json`` and ``recordings/<case>/``), draws every figure of the first recording of
each variant (``--all-variants``) or of the case (default), and prints per recording: the
wall-clock and CPU seconds (the first recording also pays the imports; they are timed
apart), the figures and their PNG sizes, and the totals. The report's budget is 30 s for
the reference suite on 2 cores; the figures' share aims at under 1.5 s per recording.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_report_figures.py [SUITE_DIR] [--all-variants] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path


def representatives(suite: Path, all_variants: bool) -> list[tuple[str, Path, list[dict]]]:
    """``(case id, recording, criteria)`` of one recording per case (or per variant)."""
    res = json.loads((suite / "results.json").read_text())
    out = []
    for case in res["cases"]:
        seen: set[str | None] = set()
        for run in case["runs"]:
            key = run.get("variant") if all_variants else None
            rec = suite / "recordings" / case["id"] / Path(run["recording"]).name
            if key in seen or not rec.exists():
                continue
            seen.add(key)
            out.append((case["id"], rec, case["criteria"]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("suite", nargs="?", default="/work/demo-reports", type=Path)
    ap.add_argument("--all-variants", action="store_true", help="one recording per case variant")
    ap.add_argument("--out", type=Path, help="write the PNGs here")
    args = ap.parse_args()
    t0 = time.perf_counter()
    import bench.acceptance.judge  # noqa: F401  (the case parser, as the report has it loaded)
    from bench.report.figures import case_figures
    from bench.report.figures_events import fault_figure  # noqa: F401

    print(f"imports: {time.perf_counter() - t0:.2f} s")
    total_wall = total_cpu = 0.0
    total_bytes = 0
    largest = 0
    rows = representatives(args.suite, args.all_variants)
    for case_id, rec, criteria in rows:
        w0, c0 = time.perf_counter(), time.process_time()
        figs = case_figures(rec, criteria, title=f"{case_id}: {rec.stem}")
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        total_wall += wall
        total_cpu += cpu
        sizes = ", ".join(f"{f.key} {len(f.png) / 1024:.0f}" for f in figs)
        total_bytes += sum(len(f.png) for f in figs)
        largest = max([largest, *(len(f.png) for f in figs)])
        mb = rec.stat().st_size / 1e6
        print(f"{rec.name:42s} {mb:6.1f} MB  wall {wall:5.2f} s  cpu {cpu:5.2f} s  PNG kB: {sizes}")
        if args.out:
            args.out.mkdir(parents=True, exist_ok=True)
            for f in figs:
                (args.out / f"{rec.stem}-{f.key}.png").write_bytes(f.png)
    n = max(1, len(rows))
    print(f"{len(rows)} recordings: wall {total_wall:.2f} s ({total_wall / n:.2f} s each), "
          f"cpu {total_cpu:.2f} s ({total_cpu / n:.2f} s each); PNG total {total_bytes / 1e6:.2f} MB, "
          f"largest {largest / 1024:.0f} kB")


if __name__ == "__main__":
    main()
