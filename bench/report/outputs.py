"""Everything an acceptance run leaves under its output folder.

``write_reports(cases, out_dir)`` writes:

* ``results.json`` -- :mod:`bench.report.results`;
* ``junit.xml`` -- :mod:`bench.report.junit`;
* ``summary.txt`` and ``summary.md`` -- :mod:`bench.report.table`;
* ``plots/<recording>.png`` -- the DUT's errors against time per run (optional).

The recordings themselves are under ``recordings/<case id>/`` (written by the runners).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.acceptance.judge import CaseResult
from bench.report.junit import write_junit
from bench.report.results import results_json, write_json
from bench.report.table import markdown_table, text_table

__all__ = ["write_reports", "plot_run"]


def plot_run(recording: str | Path, out: str | Path, title: str = "") -> Path | None:
    """Error curves of one recording (None when it holds no truth or DUT output)."""
    from bench.report.plots import error_curves
    from bench.scoring.align import nav_errors
    from bench.scoring.data import load_run

    run = load_run(recording)
    if run.truth is None or run.nav is None or len(run.nav) == 0:
        return None
    e = nav_errors(run.truth, run.nav)
    u = e.usable
    t = e.t_ns[u] * 1e-9
    spans = [(w.start_ns * 1e-9, w.end_ns * 1e-9, f"{w.kind} {w.target}") for w in run.faults]
    spans += [(s["start_s"], s["end_s"], "GNSS blocked") for s in run.segments if s.get("gnss") == "blocked"]
    frames = run.nav["frame"][e.index][u]
    marks = [(float(x), "frame switch") for x in t[1:][np.diff(frames.astype(int)) != 0]]
    error_curves(
        t,
        np.hypot(e.pos[u, 0], e.pos[u, 1]),
        e.pos[u, 2],
        np.degrees(e.att[u, 0]) * 60.0,
        out,
        title=title or Path(recording).stem,
        spans=spans,
        marks=marks,
    )
    return Path(out)


def write_reports(
    cases: Sequence[CaseResult], out_dir: str | Path, run_info: dict[str, Any] | None = None, *, plots: bool = True
) -> dict[str, Path]:
    """Write the result files of ``cases`` into ``out_dir``; returns them by kind."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {
        "json": write_json(results_json(cases, run_info), out / "results.json"),
        "junit": write_junit(cases, out / "junit.xml"),
    }
    (out / "summary.txt").write_text(text_table(cases) + "\n", encoding="utf-8")
    (out / "summary.md").write_text(markdown_table(cases), encoding="utf-8")
    files["summary"] = out / "summary.txt"
    files["markdown"] = out / "summary.md"
    if plots:
        for cr in cases:
            for r in cr.runs:
                rec = Path(r.recording)
                if rec.exists():
                    try:
                        plot_run(rec, out / "plots" / f"{rec.stem}.png", f"{cr.case_id}: {rec.stem} ({r.verdict})")
                    except Exception as exc:  # a plot never hides results
                        (out / "plots").mkdir(exist_ok=True)
                        (out / "plots" / f"{rec.stem}.txt").write_text(f"no plot: {exc}\n")
        files["plots"] = out / "plots"
    return files
