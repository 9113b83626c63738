"""Everything an acceptance run leaves under its output folder.

``write_reports(cases, out_dir)`` writes:

* ``results.json`` -- :mod:`bench.report.results`;
* ``junit.xml`` -- :mod:`bench.report.junit`;
* ``summary.txt`` and ``summary.md`` -- :mod:`bench.report.table`;
* ``plots/<recording>.png`` -- the DUT's errors against time per run (optional).

The recordings themselves are under ``recordings/<case id>/`` (written by the runners).
A report that cannot be written does not stop the others (:func:`write_reports`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.acceptance.judge import CaseResult
from bench.crashlog import one_line, write_traceback
from bench.errors import BenchError
from bench.report.junit import write_junit
from bench.report.results import results_json, write_json
from bench.report.table import markdown_table, text_table

__all__ = ["write_reports", "plot_run", "ReportError", "crash_note"]


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


class ReportError(BenchError):
    """One or more reports could not be written (the others were)."""


def write_reports(
    cases: Sequence[CaseResult],
    out_dir: str | Path,
    run_info: dict[str, Any] | None = None,
    *,
    plots: bool = True,
    failures: list[str] | None = None,
) -> dict[str, Path]:
    """Write the result files of ``cases`` into ``out_dir``; returns those written by kind.

    Each report is written on its own: one that fails (a full disk, a crash while
    formatting) does not stop the others, and a plot that fails leaves a
    ``plots/<recording>.txt`` note instead. The failures (``"summary.md: OSError: ..."``)
    are appended to ``failures`` when given; otherwise :class:`ReportError` is raised after
    every report was tried."""
    out = Path(out_dir)
    failed: list[str] = []
    files: dict[str, Path] = {}

    def attempt(kind: str, name: str, write: Callable[[Path], object]) -> None:
        try:
            out.mkdir(parents=True, exist_ok=True)
            write(out / name)
            files[kind] = out / name
        except Exception as exc:
            failed.append(crash_note(name, exc, out))

    attempt("json", "results.json", lambda p: write_json(results_json(cases, run_info), p))
    attempt("junit", "junit.xml", lambda p: write_junit(cases, p))
    attempt("summary", "summary.txt", lambda p: p.write_text(text_table(cases) + "\n", encoding="utf-8"))
    attempt("markdown", "summary.md", lambda p: p.write_text(markdown_table(cases), encoding="utf-8"))
    if plots:
        for cr in cases:
            for r in cr.runs:
                rec = Path(r.recording)
                if rec.exists():
                    try:
                        plot_run(rec, out / "plots" / f"{rec.stem}.png", f"{cr.case_id}: {rec.stem} ({r.verdict})")
                    except Exception as exc:  # a plot never hides results
                        with contextlib.suppress(OSError):
                            (out / "plots").mkdir(parents=True, exist_ok=True)
                            (out / "plots" / f"{rec.stem}.txt").write_text(f"no plot: {one_line(exc)}\n")
        files["plots"] = out / "plots"
    if failures is not None:
        failures.extend(failed)
    elif failed:
        written = ", ".join(p.name for k, p in files.items() if k != "plots") or "none"
        raise ReportError("could not write " + "; ".join(failed) + f" (written: {written})")
    return files


def crash_note(name: str, exc: Exception, out: Path) -> str:
    """``name: OSError: ...`` (the traceback of an unexpected failure into the log)."""
    note = f"{name}: {one_line(exc)}"
    if not isinstance(exc, OSError | BenchError):
        log = write_traceback(exc, out, context=f"writing {name}")
        note += f" (traceback in {log})" if log else ""
    return note
